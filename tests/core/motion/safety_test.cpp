// Faults stop motion and say which joint and why; a late servo thread is
// acted on as OVERRUN_ACTION says; the servo path does not allocate in any
// mode.
#include <gtest/gtest.h>

#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/motion/config.hpp"
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

namespace {
// A machine in coordinated mode moving X along a long line at 20 mm/s.
void start_long_move(Machine& m) {
  m.enable_home_coord();
  ASSERT_TRUE(m.line(150, 0, 0, 20).accepted);
  m.step(300);
  ASSERT_GT(m.status().traj.current_vel, 1.0);
}
// The servo thread is late (as the HAL thread tells motion through CycleInfo).
void servo_late(Machine& m, bool late, uint32_t streak = 3, int64_t missed = 1) {
  m.mc().in().servo_late = late;
  m.mc().in().overrun_streak = late ? streak : 0;
  m.mc().in().missed_cycles = late ? missed : 0;
}
}  // namespace

TEST(MotionOverrun, WarnLeavesMotionRunning) {
  Machine m;  // OVERRUN_ACTION defaults to WARN
  start_long_move(m);
  servo_late(m, true);
  m.step(200);
  EXPECT_FALSE(m.status().traj.paused);
  EXPECT_FALSE(m.status().overrun_hold);
  EXPECT_TRUE(m.status().traj.enabled);
  EXPECT_GT(m.status().traj.current_vel, 1.0);
  EXPECT_EQ(m.all_errors(), "");
}

TEST(MotionOverrun, HoldBrakesCoordinatedMotionAndHoldsUntilResume) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.overrun_action = motion::OverrunAction::Hold;
  Machine m(c);
  start_long_move(m);
  servo_late(m, true);
  m.step();
  EXPECT_TRUE(m.status().overrun_hold);
  EXPECT_EQ(m.status().overrun_holds, 1u);
  EXPECT_TRUE(m.status().traj.paused);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.current_vel == 0; }, 2000)) << "brakes to a stop";
  servo_late(m, false);  // the thread is on time again: the hold stays until the operator resumes
  m.step(100);
  const double held_at = m.status().traj.position[0];
  m.step(100);
  EXPECT_EQ(m.status().traj.position[0], held_at);
  EXPECT_TRUE(m.status().overrun_hold);
  EXPECT_TRUE(m.status().traj.enabled);
  m.accept(Cmd::Resume);
  EXPECT_FALSE(m.status().overrun_hold);
  m.step(300);
  EXPECT_GT(m.status().traj.position[0], held_at);
  EXPECT_EQ(m.all_errors(), "");
}

TEST(MotionOverrun, HoldIsTakenOncePerLateSpellAndAgainOnTheNext) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.overrun_action = motion::OverrunAction::Hold;
  Machine m(c);
  start_long_move(m);
  servo_late(m, true);
  m.step();
  m.accept(Cmd::Resume);  // the operator resumes while the thread is still late
  m.step(50);
  EXPECT_FALSE(m.status().traj.paused) << "no second hold within one late spell";
  EXPECT_EQ(m.status().overrun_holds, 1u);
  servo_late(m, false);
  m.step();
  servo_late(m, true, 1, 2000);  // a gap: a new late spell
  m.step();
  EXPECT_TRUE(m.status().traj.paused);
  EXPECT_EQ(m.status().overrun_holds, 2u);
}

TEST(MotionOverrun, HoldLeavesJogsAlone) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.overrun_action = motion::OverrunAction::Hold;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 0, 20);
  m.step(100);
  servo_late(m, true);
  m.step(100);
  EXPECT_FALSE(m.status().overrun_hold);
  EXPECT_GT(std::fabs(m.status().joints[0].velocity), 1.0);
}

TEST(MotionOverrun, StopDisablesMotionWithTheReason) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.overrun_action = motion::OverrunAction::Stop;
  Machine m(c);
  start_long_move(m);
  servo_late(m, true, 1, 2000);
  m.step();
  EXPECT_FALSE(m.status().traj.enabled);
  EXPECT_TRUE(m.status().faulted);
  EXPECT_FALSE(m.joint(0).amp_enable);
  const std::string e = m.all_errors();
  EXPECT_NE(e.find("the servo thread is late: 1 consecutive overruns, 2000 periods missed just now (OVERRUN_ACTION = "
                   "STOP): motion disabled"),
            std::string::npos)
      << e;
  m.step(10);
  EXPECT_EQ(m.all_errors(), "") << "said once";
}

TEST(MotionOverrun, OverrunKeysAreReadAndABadActionNamesFileLineAndTheChoices) {
  const auto ini = ini::IniFile::parse("[EMCMOT]\nOVERRUN_STREAK = 5\nOVERRUN_ACTION = hold\n", "m.ini");
  const motion::MotionConfig c = motion::load_motion_config(ini, 3);
  EXPECT_EQ(c.overrun_streak, 5);
  EXPECT_EQ(c.overrun_action, motion::OverrunAction::Hold);
  const motion::MotionConfig d = motion::load_motion_config(ini::IniFile::parse("", "e.ini"), 3);
  EXPECT_EQ(d.overrun_streak, 3);
  EXPECT_EQ(d.overrun_action, motion::OverrunAction::Warn);
  try {
    motion::load_motion_config(ini::IniFile::parse("[EMCMOT]\n\nOVERRUN_ACTION = PANIC\n", "bad.ini"), 3);
    FAIL() << "accepted PANIC";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("bad.ini:3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("expected WARN, HOLD or STOP"), std::string::npos) << e.what();
  }
  try {
    motion::load_motion_config(ini::IniFile::parse("[EMCMOT]\nOVERRUN_STREAK = 0\n", "zero.ini"), 3);
    FAIL() << "accepted 0";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("zero.ini:2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("OVERRUN_STREAK"), std::string::npos) << e.what();
  }
}

TEST(MotionOverrun, HoldAndStopAllocateNothing) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  for (const auto action : {motion::OverrunAction::Hold, motion::OverrunAction::Stop}) {
    motion::MotionConfig c = cnc::testing::basic_config();
    c.overrun_action = action;
    Machine m(c);
    start_long_move(m);
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 50; ++i) {
      servo_late(m, i % 5 != 0, 3, i);
      m.step(5);
    }
    EXPECT_EQ(check.allocations(), 0u) << motion::to_string(action);
    if (action == motion::OverrunAction::Stop) EXPECT_FALSE(m.status().traj.enabled) << "the stop really happened";
    else EXPECT_GT(m.status().overrun_holds, 0u) << "the hold really happened";
  }
}
