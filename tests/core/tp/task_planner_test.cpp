// The real look-ahead planner behind motion, driven by the task controller
// on the ideal mill of tests/core/task/mill: programs run to their end
// point without stalling where the interpreter stops feeding (end of the
// program, synch points, waits for motion to be idle). The task tests use a
// simple exact-stop planner; these are about the hand-over between task,
// motion and tp::LookaheadPlanner.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "core/tp/lookahead_planner.hpp"
#include "tests/core/task/fixture.hpp"

namespace cnc::tp {
namespace {

using ipc::CommandState;
using ipc::CommandType;
using testing::TaskMachine;

// The mill of tests/core/task (sim_joint axes) with tp::make_planner behind
// motion, stepped one servo cycle and one task cycle at a time.
class PlannerMill : public TaskMachine {
 public:
  explicit PlannerMill(PlannerThreading threading)
      : TaskMachine({}, "", "", "", [threading](const PlannerConfig& c) { return make_planner(c, threading); }) {}

  void power_up_home_auto() {
    power_up_and_home();
    ok(send(CommandType::TaskSetMode, 2), "auto");
  }
  // Opens and runs `program`; steps until it ends or `max_cycles` pass.
  // Returns false on a stall (still running after max_cycles).
  bool run(const std::string& program, int max_cycles) {
    ok(open("p.ngc", program), "open");
    ok(send(CommandType::TaskPlanRun, 0), "run");
    for (int i = 0; i < max_cycles; ++i) {
      if (!program_running()) return true;
      step();
    }
    return false;
  }
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
