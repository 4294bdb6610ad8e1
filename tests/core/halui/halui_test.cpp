// halui's pin logic (core/halui/halui.cpp) without a controller: poll()
// is given a status block and collects the commands it would send.
#include <gtest/gtest.h>

#include "core/hal/commands.hpp"
#include "core/halui/halui.hpp"
#include "core/ini/ini_file.hpp"

using namespace cnc;
using ipc::CommandType;

namespace {
struct Bench {
  hal::Hal hal;
  hal::ComponentRegistry registry;
  ini::IniFile ini = ini::IniFile::parse(
      "[TRAJ]\nCOORDINATES = X Y Z\n[KINS]\nJOINTS = 3\n[HALUI]\nMDI_COMMAND = G0 X1\nMDI_COMMAND = M3 S100\n",
      "mill.ini");
  hal::CommandInterpreter interp{hal, registry, &ini, nullptr};
  halui::Halui* ui = nullptr;
  std::unique_ptr<ipc::Status> status = std::make_unique<ipc::Status>();
  std::vector<ipc::Command> sent;
  Bench() {
    hal::register_core_components(registry);
    halui::register_components(registry);
    interp.execute("loadrt halui");
    ui = hal.find<halui::Halui>("halui");
    poll();  // the first poll takes the pins as they are
  }
  void poll() {
    ui->poll(*status, [this](const ipc::Command& c) {
      sent.push_back(c);
      return true;
    });
  }
  void set(const std::string& pin, const std::string& v) { hal.set_value(pin, v); }
  std::vector<CommandType> types() const {
    std::vector<CommandType> t;
    for (const auto& c : sent) t.push_back(c.type);
    return t;
  }
};
}  // namespace

TEST(Halui, PinsFollowLinuxCncNamesAndTheIni) {
  Bench b;
  for (const char* p : {"halui.machine.on", "halui.estop.is-activated", "halui.mode.is-mdi", "halui.program.run",
                        "halui.feed-override.counts", "halui.spindle.0.override.value", "halui.axis.z.plus",
                        "halui.axis.jog-speed", "halui.joint.2.home", "halui.home-all", "halui.mdi-command-01"}) {
    EXPECT_TRUE(b.hal.has_pin(p)) << p;
  }
  EXPECT_FALSE(b.hal.has_pin("halui.axis.a.plus")) << "only the INI's axes";
  EXPECT_FALSE(b.hal.has_pin("halui.mdi-command-02"));
}

TEST(Halui, ARisingEdgeSendsOneCommandAndHoldingSendsNoMore) {
  Bench b;
  b.set("halui.machine.on", "1");
  b.poll();
  b.poll();
  ASSERT_EQ(b.sent.size(), 1u);
  EXPECT_EQ(b.sent[0].type, CommandType::TaskSetState);
  b.status->task.state = ipc::TaskState::On;
  b.poll();
  EXPECT_EQ(b.hal.get_value("halui.machine.is-on"), "TRUE");
}

TEST(Halui, MdiCommandWaitsForMdiModeItAskedFor) {
  Bench b;
  b.set("halui.mdi-command-01", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::TaskSetMode}));
  b.poll();
  EXPECT_EQ(b.sent.size(), 1u) << "not sent before the mode is MDI";
  b.status->task.mode = ipc::TaskMode::Mdi;
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::TaskSetMode, CommandType::TaskPlanExecute}));
  EXPECT_EQ(std::string(b.sent[1].text.view()), "M3 S100");
}

TEST(Halui, FeedOverrideFollowsCountsTimesScaleAndTheButtons) {
  Bench b;
  b.status->motion.feed_scale = 1.0;
  b.set("halui.feed-override.scale", "0.05");
  b.set("halui.feed-override.counts", "-4");
  b.poll();
  ASSERT_EQ(b.sent.size(), 1u);
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], 0.8);
  b.status->motion.feed_scale = 0.8;
  b.set("halui.feed-override.increase", "1");
  b.poll();
  ASSERT_EQ(b.sent.size(), 2u);
  EXPECT_DOUBLE_EQ(b.sent[1].d[0], 0.85);
  b.set("halui.feed-override.direct-value", "1");
  b.set("halui.feed-override.counts", "100");
  b.poll();
  ASSERT_EQ(b.sent.size(), 3u);
  EXPECT_DOUBLE_EQ(b.sent[2].d[0], 2.0) << "100 x 0.05 = 5, limited to MAX_FEED_OVERRIDE (2.0)";
  EXPECT_EQ(b.hal.get_value("halui.feed-override.value"), "0.8");
}

TEST(Halui, JogPlusRunsWhileHeldAtJogSpeedPerMinute) {
  Bench b;
  b.set("halui.axis.jog-speed", "600");
  b.set("halui.axis.y.plus", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogCont}));
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], 10.0) << "600 units/min";
  EXPECT_EQ(b.sent[0].i[0], 1) << "Y";
  b.set("halui.axis.y.plus", "0");
  b.poll();
  EXPECT_EQ(b.sent.back().type, CommandType::JogStop);
}
