// Feed moves wait for spindle.N.at-speed after a spindle start or speed
// change, as LinuxCNC's motion does; rapids do not; [SPINDLE_n]
// AT_SPEED_TIMEOUT aborts the wait. Runs the real look-ahead planner.
#include <gtest/gtest.h>

#include "core/tp/lookahead_planner.hpp"
#include "tests/core/motion/machine.hpp"

namespace cnc::testing {
namespace {

using motion::Cmd;

Machine::PlannerMaker lookahead() {
  return [](const tp::PlannerConfig& c) { return tp::make_planner(c, tp::PlannerThreading::Inline); };
}

motion::MotionConfig spindle_config(double timeout_s = 0) {
  motion::MotionConfig c = basic_config();
  c.spindles = 1;
  c.spindle[0].at_speed_timeout_s = timeout_s;
  return c;
}

motion::MotionResult rapid(Machine& m, double x) {
  motion::MotionCommand c;
  c.type = Cmd::SetLine;
  c.end[0] = x;
  c.segment.type = tp::MotionType::Traverse;
  c.segment.feed = 50;
  c.segment.max_acceleration = 1000;
  return m.send(c);
}

TEST(MotionSpindleAtSpeed, FeedMoveAfterSpindleStartWaitsUntilAtSpeed) {
  Machine m(spindle_config(), "XYZ", lookahead());
  m.enable_home_coord();
  m.mc().in().spindles[0].at_speed = false;
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  ASSERT_TRUE(m.line(10, 0, 0, 50).accepted);
  m.step(500);
  EXPECT_EQ(m.status().traj.position[0], 0);
  EXPECT_EQ(m.status().traj.spindle_wait, 0);
  EXPECT_GT(m.status().traj.spindle_wait_s, 0.4);
  m.mc().in().spindles[0].at_speed = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }, 5000));
  EXPECT_NEAR(m.status().traj.position[0], 10, 1e-9);
  EXPECT_EQ(m.status().traj.spindle_wait, -1);
  EXPECT_EQ(m.status().spindle_timeouts, 0u);
}

// The pin still says TRUE for the old command (a stopped VFD is at speed)
// in the cycle the new one is sent: the wait does not end on it.
TEST(MotionSpindleAtSpeed, AtSpeedOfTheOldCommandDoesNotEndTheWait) {
  Machine m(spindle_config(), "XYZ", lookahead());
  m.enable_home_coord();
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  ASSERT_TRUE(m.line(10, 0, 0, 50).accepted);
  m.step();
  m.mc().in().spindles[0].at_speed = false;  // the drive has seen the command
  m.step(200);
  EXPECT_EQ(m.status().traj.position[0], 0);
  EXPECT_EQ(m.status().traj.spindle_wait, 0);
}

TEST(MotionSpindleAtSpeed, SpeedChangeMakesTheNextFeedMoveWaitAgain) {
  Machine m(spindle_config(), "XYZ", lookahead());
  m.enable_home_coord();
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  ASSERT_TRUE(m.line(5, 0, 0, 50).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }, 5000));
  m.mc().in().spindles[0].at_speed = false;
  m.accept(Cmd::SetSpindle, 0, 2000, 1);
  ASSERT_TRUE(m.line(10, 0, 0, 50).accepted);
  m.step(300);
  EXPECT_NEAR(m.status().traj.position[0], 5, 1e-9);
  EXPECT_EQ(m.status().traj.spindle_wait, 0);
}

TEST(MotionSpindleAtSpeed, RapidsAreNotHeldButTheFeedMoveAfterThemIs) {
  Machine m(spindle_config(), "XYZ", lookahead());
  m.enable_home_coord();
  m.mc().in().spindles[0].at_speed = false;
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  ASSERT_TRUE(rapid(m, 10).accepted);
  ASSERT_TRUE(m.line(20, 0, 0, 50).accepted);
  m.step(2000);
  EXPECT_NEAR(m.status().traj.position[0], 10, 1e-9);
  EXPECT_EQ(m.status().traj.spindle_wait, 0);
  m.mc().in().spindles[0].at_speed = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }, 5000));
  EXPECT_NEAR(m.status().traj.position[0], 20, 1e-9);
}

TEST(MotionSpindleAtSpeed, FeedMovesWithoutASpindleChangeDoNotWait) {
  Machine m(spindle_config(), "XYZ", lookahead());
  m.enable_home_coord();
  m.mc().in().spindles[0].at_speed = false;
  ASSERT_TRUE(m.line(10, 0, 0, 50).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }, 5000));
  EXPECT_NEAR(m.status().traj.position[0], 10, 1e-9);
}

TEST(MotionSpindleAtSpeed, TimeoutAbortsTheMovesAndNamesTheSpindle) {
  Machine m(spindle_config(0.2), "XYZ", lookahead());
  m.enable_home_coord();
  m.mc().in().spindles[0].at_speed = false;
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  ASSERT_TRUE(m.line(10, 0, 0, 50).accepted);
  ASSERT_TRUE(m.line(20, 0, 0, 50).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.status().spindle_timeouts > 0; }, 1000));
  m.step(100);
  const motion::MotionStatus s = m.status();
  EXPECT_EQ(s.spindle_timeouts, 1u);
  EXPECT_STREQ(s.spindle_timeout_reason.c_str(),
               "spindle 0 did not reach speed within 0.2 s ([SPINDLE_0]AT_SPEED_TIMEOUT; spindle.0.at-speed stayed "
               "FALSE)");
  EXPECT_TRUE(s.tp_done);
  EXPECT_EQ(s.traj.position[0], 0);
  EXPECT_EQ(s.traj.spindle_wait, -1);
  // The queue was dropped: at-speed arriving later moves nothing.
  m.mc().in().spindles[0].at_speed = true;
  m.step(500);
  EXPECT_EQ(m.status().traj.position[0], 0);
}

}  // namespace
}  // namespace cnc::testing
