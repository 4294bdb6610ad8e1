// Run-time parameter changes through the task (`cnc set`), as an operator
// makes them on the in-process mill: they reach the planner for the next
// move, the status shows them, values beyond the INI are refused; the
// spindle's [SPINDLE_n] limits hold at the HAL pin whatever the command and
// the override, and the operator is told when a command is held at a limit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/tp/lookahead_planner.hpp"
#include "tests/core/task/fixture.hpp"

using namespace cnc;
using cnc::testing::TaskMachine;
using ipc::CommandState;
using ipc::CommandType;

namespace {

motion::PlannerFactory real_planner() {
  return [](const tp::PlannerConfig& c) { return tp::make_planner(c, tp::PlannerThreading::Inline); };
}

std::pair<CommandState, std::string> set(TaskMachine& m, const char* name, int index, double value) {
  ipc::Command c;
  c.type = CommandType::SetParameter;
  c.text.assign(name);
  c.i[0] = index;
  c.d[0] = value;
  return m.send(c);
}

double pin(TaskMachine& m, const std::string& name) { return std::stod(m.hal().get_value(name)); }

// Runs an MDI line to its end, recording the largest |joint.N.vel-cmd|.
double peak_velocity_of_mdi(TaskMachine& m, const std::string& line, int joint) {
  ipc::Command c;
  c.type = CommandType::TaskPlanExecute;
  c.i[0] = -1;
  c.text.assign(line);
  double peak = 0;
  const std::string name = "joint." + std::to_string(joint) + ".vel-cmd";
  c.serial = 900000;
  EXPECT_TRUE(m.task().handle_command(c, m.reporter));
  for (int i = 0; i < 100000; ++i) {
    m.step();
    peak = std::max(peak, std::fabs(pin(m, name)));
    const auto it = m.reporter.last.find(c.serial);
    if (it != m.reporter.last.end() &&
        (it->second.first == CommandState::Done || it->second.first == CommandState::Rejected)) {
      EXPECT_EQ(it->second.first, CommandState::Done) << it->second.second;
      break;
    }
  }
  return peak;
}

bool log_has(TaskMachine& m, const std::string& text) {
  m.errors();  // drains the queue into m.log
  return m.log.find(text) != std::string::npos;
}

}  // namespace

TEST(TaskLimits, SetAxisAndPathVelocityThenG0RunsWithinThem) {
  // The report: both answered set=0, and the next G0 ran X at 99.9 mm/s.
  TaskMachine m({}, "", "", "", real_planner());
  m.power_up_and_home();
  m.ok(set(m, "axis.max-velocity", 0, 10), "set axis.max-velocity");
  m.ok(m.send(CommandType::TaskSetMode, 3), "mdi mode");
  double peak = peak_velocity_of_mdi(m, "G53 G0 X100", 0);
  EXPECT_LE(peak, 10 * 1.0001) << "joint.0.vel-cmd";
  EXPECT_GT(peak, 9.5);
  m.ok(m.send(CommandType::TaskSetMode, 1), "manual mode");
  m.ok(set(m, "traj.max-velocity", 0, 5), "set traj.max-velocity");
  m.ok(m.send(CommandType::TaskSetMode, 3), "mdi mode");
  peak = peak_velocity_of_mdi(m, "G53 G0 X150", 0);
  EXPECT_LE(peak, 5 * 1.0001);
  const ipc::Status s = m.status();
  EXPECT_EQ(s.axes[0].max_velocity, 10) << "the status shows the limits in force";
  EXPECT_EQ(s.motion.max_linear_velocity, 5);
}

TEST(TaskLimits, SetBeyondTheIniIsRefusedWithTheKey) {
  TaskMachine m;
  const auto r = set(m, "axis.max-velocity", 0, 500);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("above [AXIS_X]MAX_VELOCITY = 100"), std::string::npos) << r.second;
  EXPECT_EQ(m.status().axes[0].max_velocity, 100);
}

TEST(TaskLimits, SpindleCommandAboveMaxForwardIsClampedAtThePinAndSaid) {
  TaskMachine m({}, "", "", "[SPINDLE_0]\nMAX_FORWARD_VELOCITY = 10000\n");
  m.power_up_and_home();
  ipc::Command ov;
  ov.type = CommandType::SpindleOverride;
  ov.d[0] = 1.1;
  m.ok(m.send(ov), "spindle override 110 %");
  ipc::Command on;
  on.type = CommandType::SpindleOn;
  on.d[0] = 50000;
  m.ok(m.send(on), "spindle 50000");
  m.step(3);
  EXPECT_DOUBLE_EQ(pin(m, "spindle.0.speed-out"), 10000) << "55000 rpm reached the drive";
  EXPECT_NEAR(pin(m, "spindle.0.speed-out-rps"), 10000.0 / 60, 1e-3);
  EXPECT_TRUE(log_has(m, "spindle 0: 55000 rpm (50000 rpm x 110 %) is above [SPINDLE_0]MAX_FORWARD_VELOCITY 10000 rpm"))
      << m.log;
  const ipc::Status s = m.status();
  EXPECT_EQ(s.spindles[0].speed_out, 10000);
  EXPECT_TRUE(s.spindles[0].speed_limited);
  EXPECT_EQ(s.spindles[0].max_forward, 10000);
  EXPECT_EQ(s.spindles[0].max_reverse, 10000) << "MAX_REVERSE_VELOCITY defaults to MAX_FORWARD_VELOCITY";
}

TEST(TaskLimits, JogFasterThanTheLimitIsClampedAndSaid) {
  TaskMachine m;
  m.power_up_and_home();
  ipc::Command jog;
  jog.type = CommandType::JogCont;
  jog.i[0] = 0;
  jog.i[1] = 1;  // joint 0, free mode
  jog.d[0] = -1000;
  m.ok(m.send(jog), "jog joint 0 at 1000");
  double peak = 0;
  for (int i = 0; i < 1500; ++i) {
    m.step();
    peak = std::max(peak, std::fabs(pin(m, "joint.0.vel-cmd")));
  }
  EXPECT_LE(peak, 105 * 1.0001) << "[JOINT_0]MAX_VELOCITY";
  EXPECT_TRUE(log_has(m, "jog of joint 0 at 1000 units/s: limited to 105 units/s")) << m.log;
}

TEST(TaskLimits, ServoPeriodThatDiffersFromTheThreadStopsStartUp) {
  // The mill's HAL makes servo-thread from servo_period_nsec=[EMCMOT]SERVO_PERIOD;
  // a second, slower thread runs motion here.
  try {
    TaskMachine m({}, "loadrt threads name1=slow-thread period1=2000000\ndelf motion-controller servo-thread\n"
                      "addf motion-controller slow-thread\n");
    FAIL() << "started";
  } catch (const std::exception& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("[EMCMOT]SERVO_PERIOD = 1000000 ns"), std::string::npos) << w;
    EXPECT_NE(w.find("slow-thread with a period of 2000000 ns"), std::string::npos) << w;
  }
}

TEST(TaskLimits, ReverseSpindleInAProgramWhereReverseIsForbiddenStopsTheProgram) {
  TaskMachine m({}, "", "", "[SPINDLE_0]\nMAX_FORWARD_VELOCITY = 10000\nMAX_REVERSE_VELOCITY = 0\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, 2), "auto mode");
  m.ok(m.open("rev.ngc", "S1000 M4\nG1 X10 F600\nM2\n"), "open");
  ipc::Command run;
  run.type = CommandType::TaskPlanRun;
  m.send(run);
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 20000));
  const std::string e = m.errors();
  EXPECT_NE(e.find("spindle 0 may not turn in reverse ([SPINDLE_0]MAX_REVERSE_VELOCITY is 0)"), std::string::npos) << e;
  // The move (270 mm at 10 mm/s) would take 27 s: the program ended long before.
  EXPECT_GT(m.status().motion.position[0], 11) << "the program did not cut with the spindle stopped";
}
