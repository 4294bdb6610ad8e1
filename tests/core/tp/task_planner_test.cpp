// The real look-ahead planner behind motion, driven by the task controller
// on the ideal mill of tests/core/task/mill: programs run to their end
// point without stalling where the interpreter stops feeding (end of the
// program, synch points, waits for motion to be idle). The task tests use a
// simple exact-stop planner; these are about the hand-over between task,
// motion and tp::LookaheadPlanner.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <memory>
#include <string>

#include "core/daemon/controller.hpp"
#include "core/hal/commands.hpp"
#include "core/io/io_controller.hpp"
#include "core/motion/motion_component.hpp"
#include "core/task/task_controller.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"
#include "kinematics/kinematics.hpp"
#include "tests/support/testing.hpp"

namespace cnc::tp {
namespace {

using ipc::CommandState;
using ipc::CommandType;

class Reporter : public ipc::CommandReporter {
 public:
  void report(const ipc::Command& cmd, CommandState state, std::string_view reason) override {
    last[cmd.serial] = {state, std::string(reason)};
  }
  std::map<uint32_t, std::pair<CommandState, std::string>> last;
};

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The mill of tests/core/task (sim_joint axes) with tp::make_planner behind
// motion, stepped one servo cycle and one task cycle at a time.
class PlannerMill {
 public:
  explicit PlannerMill(PlannerThreading threading) {
    const auto src = testing::source_dir() / "tests/core/task/mill";
    dir_.write("sim.ini", read_file(src / "sim.ini"));
    dir_.write("sim.hal", read_file(src / "sim.hal"));
    dir_.write("tool.tbl", read_file(src / "tool.tbl"));
    std::filesystem::create_directories(dir_ / "nc_files");
    ini_ = ini::IniFile::load(dir_ / "sim.ini");
    hal::register_core_components(registry_);
    kin::register_kinematics_components(registry_);
    motion::register_components(registry_, [threading](const PlannerConfig& c) { return make_planner(c, threading); });
    io::register_components(registry_);
    hal_.add_component(std::make_unique<io::IoController>(hal_, io::IoConfig::from_ini(ini_), &messages_));
    hal::CommandInterpreter interp(hal_, registry_, &ini_, &messages_);
    interp.run_file(dir_ / "sim.hal");
    for (hal::Component* c : hal_.components()) c->on_ready();
    motion_ = hal_.find<motion::MotionComponent>("motmod");
    io_ = hal_.find<io::IoController>("iocontrol");
    task_ = std::make_unique<task::TaskController>(ini_, hal_, *motion_, *io_, messages_);
    thread_ = hal_.find_thread("servo-thread");
    info_.period_ns = info_.actual_period_ns = 1'000'000;
  }

  void step() {
    thread_->run_cycle(info_);
    ++info_.cycle;
    ++cycles_;
    const int64_t now = monotonic_ns();
    io_->update(now);
    task_->update(now);
  }

  std::pair<CommandState, std::string> send(ipc::Command c, int max_cycles = 300000) {
    c.serial = ++serial_;
    if (!task_->handle_command(c, reporter_)) return {CommandState::None, "not handled"};
    for (int i = 0; i < max_cycles; ++i) {
      const auto it = reporter_.last.find(c.serial);
      if (it != reporter_.last.end() &&
          (it->second.first == CommandState::Done || it->second.first == CommandState::Rejected)) {
        return it->second;
      }
      step();
    }
    return reporter_.last[c.serial];
  }
  std::pair<CommandState, std::string> send(CommandType t, int i0 = 0) {
    ipc::Command c;
    c.type = t;
    c.i[0] = i0;
    return send(c);
  }
  void ok(const std::pair<CommandState, std::string>& r, const char* what) {
    ASSERT_EQ(r.first, CommandState::Done) << what << ": " << r.second << "\n" << errors();
  }
  void power_up_home_auto() {
    ok(send(CommandType::TaskSetState, 2), "estop reset");
    ok(send(CommandType::TaskSetState, 4), "machine on");
    ok(send(CommandType::JointHome, -1), "home all");
    ok(send(CommandType::TaskSetMode, 2), "auto");
  }
  // Opens and runs `program`; steps until it ends or `max_cycles` pass.
  // Returns false on a stall (still running after max_cycles).
  bool run(const std::string& program, int max_cycles) {
    const auto p = dir_.write("nc_files/p.ngc", program);
    ipc::Command open;
    open.type = CommandType::TaskPlanOpen;
    open.text.assign(p.string());
    ok(send(open), "open");
    ok(send(CommandType::TaskPlanRun, 0), "run");
    for (int i = 0; i < max_cycles; ++i) {
      if (task_->interp_state() == ipc::InterpState::Idle) return true;
      step();
    }
    return false;
  }
  ipc::Status status() {
    ipc::Status s{};
    for (hal::Component* c : hal_.components()) {
      if (auto* svc = dynamic_cast<ipc::ControllerService*>(c)) svc->contribute_status(s);
    }
    task_->contribute_status(s);
    return s;
  }
  std::string errors() {
    std::string out;
    Message m;
    while (messages_.pop(m)) {
      if (m.kind == MessageKind::Error) out += std::string(m.source.view()) + ": " + std::string(m.text.view()) + "\n";
    }
    return out;
  }
  uint64_t cycles() const { return cycles_; }

 private:
  testing::TempDir dir_;
  MessageQueue messages_;
  Reporter reporter_;
  ini::IniFile ini_;
  hal::Hal hal_;
  hal::ComponentRegistry registry_;
  motion::MotionComponent* motion_ = nullptr;
  io::IoController* io_ = nullptr;
  std::unique_ptr<task::TaskController> task_;
  hal::Thread* thread_ = nullptr;
  rt::CycleInfo info_;
  uint32_t serial_ = 0;
  uint64_t cycles_ = 0;
};

// Short blended moves, arcs in two planes, a helix, exact stop and exact
// path, a dwell, a tool change and M66 waits (synch points: the
// interpreter stops feeding until motion is idle) and an end far from the
// last synch point.
std::string mixed_program() {
  std::string p =
      "G21 G90 G17 G54 G64 P0.02\n"
      "G0 X10 Y10 Z-10\n"
      "G1 X20 F1200\n";
  for (int i = 0; i < 200; ++i) {
    p += "G1 X" + std::to_string(20 + 0.05 * (i + 1)) + " Y" + std::to_string(10 + ((i + 1) % 2 ? 0.02 : 0.0)) + "\n";
  }
  p +=
      "G2 X40 Y20 I5 J5\n"
      "G18 G3 X50 Z-10 I5 K0\n"
      "G17 G2 X50 Y20 Z-12 I5 J0 P2\n"
      "G61 G1 X60 Y30\n"
      "G61.1 G1 X70\n"
      "G64 P0.05 G1 X80 Y40\n"
      "G4 P0.05\n"
      "G1 X90 Y45\n"
      "M66 P0 L0\n"
      "G1 X100 Y50 Z-15\n"
      "G1 X110 Y50\n"
      "T2 M6\n"
      "G1 Z-15\n"
      "G1 X120 Y60\n"
      "G1 X121 Y61\n"
      "G1 X122 Y61.5\n"
      "M2\n";
  return p;
}

void expect_final(PlannerMill& m, double x, double y, double z) {
  const ipc::Status s = m.status();
  EXPECT_NEAR(s.motion.position[0], x, 1e-9);
  EXPECT_NEAR(s.motion.position[1], y, 1e-9);
  EXPECT_NEAR(s.motion.position[2], z, 1e-9);
}

TEST(TpWithTask, MixedProgramRunsToItsEndInline) {
  PlannerMill m(PlannerThreading::Inline);
  m.power_up_home_auto();
  ASSERT_TRUE(m.run(mixed_program(), 200000)) << "stalled; " << m.errors();
  EXPECT_EQ(m.errors(), "");
  expect_final(m, 122, 61.5, -15);
}

TEST(TpWithTask, MixedProgramRunsToItsEndOnThePlannerThread) {
  PlannerMill m(PlannerThreading::OwnThread);
  m.power_up_home_auto();
  ASSERT_TRUE(m.run(mixed_program(), 200000)) << "stalled; " << m.errors();
  EXPECT_EQ(m.errors(), "");
  expect_final(m, 122, 61.5, -15);
}

TEST(TpWithTask, ManyShortMovesAfterAWaitDoNotStall) {
  // A program that keeps motion fed, waits (M66: the interpreter stops until
  // motion is idle) with moves still held for corner smoothing, then goes on.
  PlannerMill m(PlannerThreading::OwnThread);
  m.power_up_home_auto();
  std::string p = "G21 G90 G64 P0.01\nG0 X5 Y5 Z-5\nF3000\n";
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < 40; ++i) p += "G1 X" + std::to_string(5 + 0.1 * i) + " Y" + std::to_string(5 + 0.1 * k + (i % 2) * 0.03) + "\n";
    p += "M66 P0 L0\n";
  }
  p += "G1 X50 Y40\nM2\n";
  ASSERT_TRUE(m.run(p, 100000)) << "stalled; " << m.errors();
  EXPECT_EQ(m.errors(), "");
  expect_final(m, 50, 40, -5);
}

}  // namespace
}  // namespace cnc::tp
