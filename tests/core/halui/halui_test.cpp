// halui's pin logic (core/halui/halui.cpp) without a controller: poll()
// is given a status block and collects the commands it would send.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdio>
#include <regex>
#include <set>
#include <sstream>

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

// The pins LinuxCNC's halui(1) has beyond the first set: coolant and lube,
// spindle speed steps and brake, abort, the tool, joint jogs.
TEST(Halui, CoolantLubeSpindleStepsBrakeAndAbortPinsSendTheirCommands) {
  Bench b;
  const std::vector<std::pair<const char*, CommandType>> presses = {
      {"halui.flood.on", CommandType::CoolantFloodOn},     {"halui.flood.off", CommandType::CoolantFloodOff},
      {"halui.mist.on", CommandType::CoolantMistOn},       {"halui.mist.off", CommandType::CoolantMistOff},
      {"halui.lube.on", CommandType::LubeOn},              {"halui.lube.off", CommandType::LubeOff},
      {"halui.spindle.0.increase", CommandType::SpindleIncrease},
      {"halui.spindle.0.decrease", CommandType::SpindleDecrease},
      {"halui.spindle.0.brake-on", CommandType::SpindleBrakeEngage},
      {"halui.spindle.0.brake-off", CommandType::SpindleBrakeRelease},
      {"halui.abort", CommandType::TaskAbort},
  };
  for (const auto& [pin, type] : presses) {
    b.sent.clear();
    b.set(pin, "1");
    b.poll();
    b.poll();  // held: nothing more
    b.set(pin, "0");
    b.poll();
    ASSERT_EQ(b.types(), std::vector<CommandType>{type}) << pin;
  }
}

TEST(Halui, CoolantLubeSpindleAndToolStatusPinsFollowTheStatus) {
  Bench b;
  b.status->io.flood = true;
  b.status->io.lube = true;
  b.status->io.tool_in_spindle = 7;
  b.status->task.tool_offset[2] = 42.5;
  b.status->spindles[0].enabled = true;
  b.status->spindles[0].direction = -1;
  b.status->spindles[0].brake = false;
  b.poll();
  EXPECT_EQ(b.hal.get_value("halui.flood.is-on"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.mist.is-on"), "FALSE");
  EXPECT_EQ(b.hal.get_value("halui.lube.is-on"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.tool.number"), "7");
  EXPECT_EQ(b.hal.get_value("halui.tool.length-offset.z"), "42.5");
  EXPECT_EQ(b.hal.get_value("halui.tool.length-offset.w"), "0");
  EXPECT_EQ(b.hal.get_value("halui.spindle.0.runs-backward"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.spindle.0.runs-forward"), "FALSE");
  EXPECT_EQ(b.hal.get_value("halui.spindle.0.brake-is-on"), "FALSE");
}

TEST(Halui, JointJogPinsJogJointsAtTheJointJogSpeed) {
  Bench b;
  ASSERT_TRUE(b.hal.has_pin("halui.joint.2.increment-minus"));
  EXPECT_FALSE(b.hal.has_pin("halui.joint.3.plus")) << "[KINS]JOINTS = 3";
  b.set("halui.joint.jog-speed", "120");
  b.set("halui.joint.1.minus", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogCont}));
  EXPECT_EQ(b.sent[0].i[0], 1);
  EXPECT_EQ(b.sent[0].i[1], 1) << "a joint jog";
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], -2.0) << "120 units/min, negative";
  b.set("halui.joint.1.minus", "0");
  b.poll();
  EXPECT_EQ(b.sent.back().type, CommandType::JogStop);
  EXPECT_EQ(b.sent.back().i[1], 1);
  b.sent.clear();
  b.set("halui.joint.0.increment", "0.5");
  b.set("halui.joint.0.increment-plus", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogIncr}));
  EXPECT_DOUBLE_EQ(b.sent[0].d[1], 0.5);
  b.sent.clear();
  b.set("halui.joint.2.analog", "0.5");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogCont}));
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], 1.0) << "half of 2 units/s";
  EXPECT_EQ(b.sent[0].i[0], 2);
}

// Every halui pin has the name, type and direction LinuxCNC's halui(1)
// documents (read from the installed man page; skipped without it): joint
// numbers read as N, axis letters as L, spindle 0 as N, MDI numbers as XX.
TEST(Halui, EveryPinHasTheNameTypeAndDirectionOfLinuxCncsHalui) {
  FILE* f = ::popen("zcat /usr/share/man/man1/halui.1.gz 2>/dev/null", "r");
  ASSERT_NE(f, nullptr);
  std::string man;
  char buf[4096];
  while (const std::size_t n = std::fread(buf, 1, sizeof buf, f)) man.append(buf, n);
  ::pclose(f);
  if (man.empty()) GTEST_SKIP() << "LinuxCNC's halui(1) man page is not installed";
  // ".B halui.abort\fR bit in \fR" -> "halui.abort bit in".
  std::set<std::string> documented;
  std::istringstream lines(man);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(".B halui.", 0) != 0) continue;
    for (const std::string from : {"\\fR", "\\-"}) {
      for (std::size_t at; (at = line.find(from)) != std::string::npos;) line.replace(at, from.size(), from == "\\-" ? "-" : " ");
    }
    std::istringstream words(line.substr(3));
    std::string name, type, dir;
    words >> name >> type >> dir;
    if (type.empty()) {
      // halui.axis.selected.plus, halui.joint.selected.plus: the man page
      // has their type and direction in the next line's text.
      std::string next;
      std::getline(lines, next);
      std::smatch m;
      if (std::regex_search(next, m, std::regex(R"((bit|float|s32|u32) (in|out))"))) {
        type = m[1];
        dir = m[2];
      }
    }
    documented.insert(name + " " + type + " " + dir);
  }
  ASSERT_GT(documented.size(), 100u) << "the man page's pin list was not found";
  Bench b;
  const std::regex joint(R"(^halui\.joint\.\d+\.)"), axis(R"(^halui\.axis\.[xyzabcuvw]\.)"),
      spindle(R"(^halui\.spindle\.0\.)"), mdi(R"(^halui\.mdi-command-\d\d$)");
  int checked = 0;
  std::set<std::string> ours;
  for (const auto& p : b.hal.pins()) {
    if (p.name.rfind("halui.", 0) != 0) continue;
    std::string n = std::regex_replace(p.name, joint, "halui.joint.N.");
    n = std::regex_replace(n, axis, "halui.axis.L.");
    n = std::regex_replace(n, spindle, "halui.spindle.N.");
    n = std::regex_replace(n, mdi, "halui.mdi-command-XX");
    std::string dir = hal::to_string(p.dir);
    for (char& c : dir) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const std::string key = n + " " + hal::to_string(p.type) + " " + dir;
    EXPECT_TRUE(documented.count(key)) << p.name << " as " << key << " is not in halui(1)";
    ours.insert(key);
    ++checked;
  }
  EXPECT_GT(checked, 100);
  // What halui(1) has and this halui does not (docs/hal.md lists them).
  std::string missing;
  for (const auto& d : documented) {
    if (!ours.count(d)) missing += "  " + d + "\n";
  }
  std::printf("halui(1) pins not provided:\n%s", missing.c_str());
}

TEST(Halui, ProgramSwitchesModesUnhomeMaxVelocityAndJointStatusPins) {
  Bench b;
  const std::vector<std::pair<const char*, CommandType>> presses = {
      {"halui.program.optional-stop.on", CommandType::TaskPlanSetOptionalStop},
      {"halui.program.block-delete.off", CommandType::TaskPlanSetBlockDelete},
      {"halui.mode.teleop", CommandType::TrajSetTeleopEnable},
      {"halui.joint.1.unhome", CommandType::JointUnhome},
      {"halui.max-velocity.increase", CommandType::TrajSetMaxVelocity},
  };
  b.status->motion.max_velocity = 20;
  for (const auto& [pin, type] : presses) {
    b.sent.clear();
    b.set(pin, "1");
    b.poll();
    b.set(pin, "0");
    b.poll();
    ASSERT_EQ(b.types(), std::vector<CommandType>{type}) << pin;
  }
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], 20.1) << "scale 0.1 per press, units/s";
  EXPECT_FALSE(b.hal.has_pin("halui.max-velocity.reset")) << "LinuxCNC's max-velocity has none";
  b.status->task.optional_stop = true;
  b.status->motion.teleop_enabled = true;
  b.status->motion.linear_units = 1.0 / 25.4;
  b.status->joints[2].max_soft_limit = true;
  b.status->joints[0].fault = true;
  b.poll();
  EXPECT_EQ(b.hal.get_value("halui.program.optional-stop.is-on"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.mode.is-teleop"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.mode.is-joint"), "FALSE");
  EXPECT_EQ(b.hal.get_value("halui.joint.2.on-soft-max-limit"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.joint.0.has-fault"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.joint.1.has-fault"), "FALSE");
  EXPECT_NEAR(std::stod(b.hal.get_value("halui.machine.units-per-mm")), 1.0 / 25.4, 1e-6);  // as formatted
}

// Selection (LinuxCNC's halui): the last axis or joint whose select pin
// rose is the selected one (the first before any); the selected pins jog,
// home and show that one.
TEST(Halui, SelectPinsChooseTheAxisAndJointTheSelectedPinsActOn) {
  Bench b;
  EXPECT_EQ(b.hal.get_value("halui.axis.selected"), "0");
  EXPECT_EQ(b.hal.get_value("halui.axis.x.is-selected"), "TRUE");
  b.set("halui.axis.z.select", "1");
  b.set("halui.joint.1.select", "1");
  b.status->task.mode = ipc::TaskMode::Manual;
  b.status->joints[1].homed = true;
  b.status->joints[1].max_soft_limit = true;
  b.poll();
  EXPECT_EQ(b.hal.get_value("halui.axis.selected"), "2");
  EXPECT_EQ(b.hal.get_value("halui.axis.z.is-selected"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.axis.x.is-selected"), "FALSE");
  EXPECT_EQ(b.hal.get_value("halui.joint.selected"), "1");
  EXPECT_EQ(b.hal.get_value("halui.joint.1.is-selected"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.joint.selected.is-homed"), "TRUE");
  EXPECT_EQ(b.hal.get_value("halui.joint.selected.on-soft-max-limit"), "TRUE");
  // Jog the selected axis (Z) while held; an increment of the selected joint.
  b.set("halui.axis.jog-speed", "120");
  b.set("halui.axis.selected.plus", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogCont}));
  EXPECT_EQ(b.sent[0].i[0], 2);
  EXPECT_DOUBLE_EQ(b.sent[0].d[0], 2.0);
  // Selecting Y while Z jogs: Z is stopped, not left running.
  b.sent.clear();
  b.set("halui.axis.y.select", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JogStop}));
  EXPECT_EQ(b.sent[0].i[0], 2);
  b.set("halui.axis.selected.plus", "0");
  b.poll();
  b.sent.clear();
  b.set("halui.joint.jog-speed", "60");
  b.set("halui.joint.selected.increment", "0.5");
  b.set("halui.joint.selected.increment-minus", "1");
  b.set("halui.joint.selected.home", "1");
  b.poll();
  ASSERT_EQ(b.types(), (std::vector<CommandType>{CommandType::JointHome, CommandType::JogIncr}));
  EXPECT_EQ(b.sent[0].i[0], 1);
  EXPECT_EQ(b.sent[1].i[0], 1);
  EXPECT_DOUBLE_EQ(b.sent[1].d[1], -0.5);
}

TEST(Halui, PosRelativeIsTheCommandLessTheOffsetsAndToolDiameterIsTheSpindlesTool) {
  Bench b;
  b.status->motion.position[0] = 100;
  b.status->task.g5x_offset[0] = 30;
  b.status->task.g92_offset[0] = 5;
  b.status->task.tool_offset[0] = 0.25;
  b.status->io.tool_diameter = 6.35;
  b.poll();
  EXPECT_DOUBLE_EQ(std::stod(b.hal.get_value("halui.axis.x.pos-relative")), 64.75);
  EXPECT_DOUBLE_EQ(std::stod(b.hal.get_value("halui.tool.diameter")), 6.35);
}

TEST(Halui, EverySpindleOfTheIniHasItsPins) {
  hal::Hal hal;
  hal::ComponentRegistry registry;
  const ini::IniFile ini = ini::IniFile::parse("[TRAJ]\nCOORDINATES = X Y Z\nSPINDLES = 2\n[KINS]\nJOINTS = 3\n", "two.ini");
  hal::CommandInterpreter interp{hal, registry, &ini, nullptr};
  hal::register_core_components(registry);
  halui::register_components(registry);
  interp.execute("loadrt halui");
  auto* ui = hal.find<halui::Halui>("halui");
  auto status = std::make_unique<ipc::Status>();
  std::vector<ipc::Command> sent;
  const auto poll = [&] { ui->poll(*status, [&](const ipc::Command& c) { sent.push_back(c); return true; }); };
  poll();
  EXPECT_TRUE(hal.has_pin("halui.spindle.1.start"));
  EXPECT_TRUE(hal.has_pin("halui.spindle.1.override.value"));
  EXPECT_FALSE(hal.has_pin("halui.spindle.2.start"));
  status->spindles[1].enabled = true;
  status->spindles[1].direction = -1;
  status->spindles[1].speed = -800;
  hal.set_value("halui.spindle.1.increase", "1");
  hal.set_value("halui.spindle.1.start", "1");
  hal.set_value("halui.spindle.1.override.increase", "1");
  poll();
  EXPECT_EQ(hal.get_value("halui.spindle.1.runs-backward"), "TRUE");
  EXPECT_EQ(hal.get_value("halui.spindle.0.is-on"), "FALSE");
  ASSERT_EQ(sent.size(), 3u);
  for (const auto& c : sent) EXPECT_EQ(c.i[0], 1) << ipc::to_string(c.type);  // spindle 1 in every command
  EXPECT_EQ(sent[0].type, CommandType::SpindleOn);
  EXPECT_DOUBLE_EQ(sent[0].d[0], -800);  // reverse, at its speed
}
