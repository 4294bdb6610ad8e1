// Faults stop motion and say which joint and why; the servo path does not
// allocate in any mode.
#include <gtest/gtest.h>

#include "tests/core/motion/machine.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using cnc::testing::Machine;
using motion::Cmd;

TEST(MotionSafety, FollowingErrorTripsWithTheJointAndTheFigures) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[1].ferror = 0.2;
  c.joints[1].min_ferror = 0.05;
  Machine m(c);
  m.sims[1].lag = 0.9;  // a loop with far too low a gain
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 1, 80);
  ASSERT_TRUE(m.run_until([&] { return !m.out().motion_enabled; }, 5000));
  const std::string e = m.all_errors();
  EXPECT_NE(e.find("joint 1 following error"), std::string::npos) << e;
  EXPECT_NE(e.find("exceeds its limit"), std::string::npos) << e;
  EXPECT_TRUE(m.status().joints[1].fault);
  EXPECT_TRUE(m.status().faulted);
  EXPECT_FALSE(m.joint(1).amp_enable);
}

TEST(MotionSafety, FollowingErrorLimitScalesWithVelocity) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].ferror = 1.0;
  c.joints[0].min_ferror = 0.1;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_DOUBLE_EQ(m.joint(0).f_error_lim, 0.1) << "MIN_FERROR at rest";
  m.accept(Cmd::JogCont, 0, 50);
  m.step(400);
  EXPECT_NEAR(m.joint(0).f_error_lim, 0.5, 1e-3) << "FERROR scaled by velocity / max velocity";
}

TEST(MotionSafety, AmplifierFaultDisablesMotion) {
  Machine m;
  m.accept(Cmd::Enable);
  m.step(2);
  m.sims[2].amp_fault = true;
  m.step(2);
  EXPECT_FALSE(m.out().motion_enabled);
  EXPECT_NE(m.all_errors().find("joint 2 amplifier fault (joint.2.amp-fault-in): motion disabled"), std::string::npos);
  EXPECT_TRUE(m.joint(2).faulted);
}

TEST(MotionSafety, ExternalEnableInputIsAStop) {
  Machine m;
  m.accept(Cmd::Enable);
  m.step();
  m.mc().in().enable = false;
  m.step();
  EXPECT_FALSE(m.out().motion_enabled);
  EXPECT_NE(m.all_errors().find("motion.enable went false (external stop): motion disabled"), std::string::npos);
}

TEST(MotionSafety, CoordMotionBeyondTheSoftLimitIsRefused) {
  Machine m;
  m.enable_home_coord();
  const auto r = m.line(0, 0, -11, 10, 42);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "line 42: Z-11.0000 is outside the soft limits -10..200");
}

TEST(MotionRealtime, ServoPathAllocatesNothingInAnyMode) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].homing.search_vel = 20;
  c.joints[0].homing.latch_vel = 2;
  c.joints[0].homing.use_index = true;
  c.joints[0].homing.offset = 150;
  c.joints[0].homing.home = 100;
  c.joints[0].backlash = 0.05;
  Machine m(c);
  m.sims[0].pos = 50;
  m.sims[0].home_min = 100;
  m.sims[0].index_spacing = 5;
  cnc::testing::ScopedAllocationCheck check;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  m.run_until([&] { return m.status().joints[0].homed; }, 200000);
  m.accept(Cmd::Home, 1);
  m.accept(Cmd::Home, 2);
  m.run_until([&] { return m.status().all_homed && m.status().traj.inpos; }, 200000);
  m.accept(Cmd::JogIncr, 1, 30, 4);
  m.accept(Cmd::JogCont, 2, 10);
  m.step(300);
  m.accept(Cmd::Abort);
  m.run_until([&] { return m.status().traj.inpos; });
  m.accept(Cmd::Teleop);
  motion::MotionCommand v;
  v.type = Cmd::SetTeleopVector;
  v.end[0] = -5;
  m.send(v);
  m.step(300);
  v.end = Pose{};
  m.send(v);
  m.run_until([&] { return m.status().traj.inpos; });
  m.accept(Cmd::Coord);
  for (int i = 0; i < 20; ++i) m.line(100 + (i % 2) * 10, 10 + i, 5, 40, i);
  motion::MotionCommand arc;
  arc.type = Cmd::SetCircle;
  arc.end[0] = 110;
  arc.end[1] = 49;
  arc.end[2] = 5;
  arc.center = {110, 39, 5};
  arc.normal = {0, 0, 1};
  arc.segment.feed = 30;
  m.send(arc);
  m.accept(Cmd::Scale, 0, 0.7);
  m.step(500);
  m.accept(Cmd::Pause);
  m.step(300);
  m.accept(Cmd::Resume);
  m.run_until([&] { return m.status().tp_done; }, 400000);
  motion::MotionCommand p;
  p.type = Cmd::Probe;
  p.end = m.status().traj.position;
  p.end[2] = -5;
  p.segment.feed = 10;
  m.send(p);
  m.step(200);
  m.mc().in().probe_input = true;
  m.run_until([&] { return m.status().tp_done; });
  m.accept(Cmd::SetSpindle, 0, 1000, 1);
  m.step(100);
  m.accept(Cmd::Disable);
  m.step(10);
  EXPECT_EQ(check.allocations(), 0u);
  EXPECT_TRUE(m.status().traj.probe_tripped) << "every mode really ran";
  EXPECT_GT(m.cycles, 5000u);
}
