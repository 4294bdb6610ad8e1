// One or more tests per motion command of the manual's 3.8: what it
// requires, what it does, and every reason it is refused.
#include <gtest/gtest.h>

#include "core/ini/ini_file.hpp"
#include "core/motion/config.hpp"
#include "core/motion/motion_component.hpp"
#include "core/motion/params.hpp"
#include "tests/core/motion/machine.hpp"

using namespace cnc;
using motion::Cmd;
using cnc::testing::Machine;

TEST(MotionAbort, AlwaysAcceptedAndStopsAJogWithinTheLimits) {
  Machine m;
  EXPECT_TRUE(m.send(Cmd::Abort).accepted) << "even when disabled";
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 0, 50);
  m.step(300);
  const double v = m.joint(0).vel_cmd;
  EXPECT_NEAR(v, 50, 1e-6);
  m.accept(Cmd::Abort);
  double prev_v = v, max_a = 0;
  for (int i = 0; i < 1000 && std::fabs(m.joint(0).vel_cmd) > 0; ++i) {
    m.step();
    max_a = std::max(max_a, std::fabs(m.joint(0).vel_cmd - prev_v) / 0.001);
    prev_v = m.joint(0).vel_cmd;
  }
  EXPECT_EQ(m.joint(0).vel_cmd, 0);
  EXPECT_LE(max_a, 1000 + 1e-6) << "decelerates at most at the joint's limit";
  EXPECT_TRUE(m.status().traj.inpos);
}

TEST(MotionModes, FreeIsRefusedWhileMovingAndAcceptedAtRest) {
  Machine m;
  m.enable_home_coord();
  ASSERT_TRUE(m.line(50, 0, 0, 20).accepted);
  m.step(20);
  const auto r = m.send(Cmd::Free);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "cannot change to FREE mode while the machine moves (in COORD mode)");
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  EXPECT_TRUE(m.send(Cmd::Free).accepted);
  EXPECT_EQ(m.mc().mode(), ipc::MotionMode::Free);
  EXPECT_TRUE(m.send(Cmd::Free).accepted) << "already free: nothing to do, still answered";
}

TEST(MotionModes, CoordAndTeleopNeedHomedJoints) {
  Machine m;
  m.accept(Cmd::Enable);
  auto r = m.send(Cmd::Coord);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "cannot change to COORD mode: joints 0, 1, 2 are not homed");
  m.accept(Cmd::Home, 1);
  m.step(10);
  r = m.send(Cmd::Teleop);
  EXPECT_STREQ(r.reason.c_str(), "cannot change to TELEOP mode: joints 0, 2 are not homed");
  m.accept(Cmd::Home, 0);
  m.accept(Cmd::Home, 2);
  m.step(10);
  EXPECT_TRUE(m.send(Cmd::Teleop).accepted);
  m.step();
  EXPECT_TRUE(m.out().teleop_mode);
  EXPECT_TRUE(m.send(Cmd::Coord).accepted);
  m.step();
  EXPECT_TRUE(m.out().coord_mode);
}

TEST(MotionModes, ChangingModeWhileAJogRunsIsRefused) {
  Machine m;
  m.accept(Cmd::Enable);
  for (int j = 0; j < 3; ++j) m.accept(Cmd::Home, j);
  m.step(10);
  m.accept(Cmd::JogCont, 0, 10);
  m.step(5);
  EXPECT_FALSE(m.send(Cmd::Coord).accepted);
  EXPECT_FALSE(m.send(Cmd::Teleop).accepted);
}

TEST(MotionEnable, EnableIsBumplessAndTurnsAmplifiersOn) {
  Machine m;
  m.sims[0].pos = 12.5;  // the machine was moved by hand while off
  m.step(3);
  EXPECT_FALSE(m.joint(0).amp_enable);
  EXPECT_DOUBLE_EQ(m.joint(0).pos_cmd, 12.5) << "while disabled the command follows the feedback";
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.joint(0).amp_enable);
  EXPECT_DOUBLE_EQ(m.joint(0).motor_pos_cmd, 12.5) << "no jump on enable";
  EXPECT_TRUE(m.out().motion_enabled);
  EXPECT_TRUE(m.send(Cmd::Enable).accepted) << "already enabled: nothing, still answered";
}

TEST(MotionEnable, DisableStopsMotionFlushesAndTurnsAmplifiersOff) {
  Machine m;
  m.enable_home_coord();
  ASSERT_TRUE(m.line(100, 0, 0, 50).accepted);
  ASSERT_TRUE(m.line(0, 0, 0, 50).accepted);
  m.step(50);
  m.accept(Cmd::Disable);
  m.step();
  EXPECT_FALSE(m.joint(0).amp_enable);
  EXPECT_TRUE(m.status().tp_done) << "queues flushed";
  EXPECT_EQ(m.status().traj.queue, 0);
}

TEST(MotionAmplifier, EnableAndDisableOneAmplifier) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::DisableAmplifier, 1);
  m.step();
  EXPECT_FALSE(m.joint(1).amp_enable);
  EXPECT_TRUE(m.joint(0).amp_enable);
  m.accept(Cmd::EnableAmplifier, 1);
  m.step();
  EXPECT_TRUE(m.joint(1).amp_enable);
  EXPECT_STREQ(m.send(Cmd::EnableAmplifier, 7).reason.c_str(), "no joint 7");
}

// joint.N.amp-ready-in: after ENABLE the amplifiers are on, but motion
// moves nothing until every active joint's amplifier says it is ready (a
// drive's enable sequence takes cycles); meanwhile the command follows the
// feedback and commands that move are refused, naming the joint.
TEST(MotionAmplifierReady, MotionWaitsUntilEveryAmplifierIsReady) {
  Machine m;
  m.sims[2].ready_after = 10;
  m.step(3);  // the inputs of a running machine: drive 2 not ready while disabled
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.joint(2).amp_enable);
  EXPECT_TRUE(m.status().traj.enabled);
  EXPECT_FALSE(m.status().amps_ready);
  EXPECT_EQ(m.status().amp_waiting_joint, 2);
  EXPECT_STREQ(m.send(Cmd::Home, 0).reason.c_str(),
               "cannot home: joint 2's amplifier is not ready yet (joint.2.amp-ready-in)");
  EXPECT_STREQ(m.send(Cmd::JogCont, 1, 10).reason.c_str(),
               "cannot jog: joint 2's amplifier is not ready yet (joint.2.amp-ready-in)");
  m.sims[2].pos = 0.3;  // it sags while its drive enables: the command follows, no following error
  m.step();
  EXPECT_DOUBLE_EQ(m.joint(2).pos_cmd, 0.3);
  EXPECT_TRUE(m.status().traj.enabled);
  ASSERT_TRUE(m.run_until([&] { return m.status().amps_ready; }, 20));
  EXPECT_GE(m.sims[2].enabled_cycles, 10);
  EXPECT_EQ(m.status().amp_waiting_joint, -1);
  EXPECT_TRUE(m.send(Cmd::Home, 0).accepted);
  EXPECT_EQ(m.all_errors(), "");
}

TEST(MotionAmplifierReady, AnAmplifierNotReadyInTimeDisablesMotionNamingTheJoint) {
  motion::MotionConfig cfg = cnc::testing::basic_config();
  cfg.joints[1].amp_ready_timeout_s = 0.05;
  Machine m(cfg);
  m.sims[1].ready_after = -1;
  m.step(3);
  m.accept(Cmd::Enable);
  m.step(45);
  EXPECT_TRUE(m.status().traj.enabled);
  m.step(10);
  EXPECT_FALSE(m.status().traj.enabled);
  EXPECT_FALSE(m.joint(1).amp_enable);
  EXPECT_EQ(m.all_errors(),
            "joint 1 amplifier not ready 0.050 s after enable (joint.1.amp-ready-in stayed false): motion disabled\n");
}

TEST(MotionAmplifierReady, ReadyAmplifiersAndUnconnectedInputsNeedNoWait) {
  Machine m;  // every amp-ready-in true, as an unconnected pin is
  m.accept(Cmd::Enable);
  EXPECT_TRUE(m.send(Cmd::Home, 0).accepted) << "in the same cycle as the enable";
  m.step();
  EXPECT_TRUE(m.status().amps_ready);
}

TEST(MotionJointActivation, DeactivatedJointsKeepTheirAmplifierOnEnable) {
  Machine m;
  m.accept(Cmd::DeactivateJoint, 2);
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_FALSE(m.joint(2).amp_enable);
  EXPECT_FALSE(m.joint(2).active);
  m.accept(Cmd::Disable);
  m.accept(Cmd::ActivateJoint, 2);
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.joint(2).amp_enable);
  EXPECT_STREQ(m.send(Cmd::ActivateJoint, -1).reason.c_str(), "no joint -1");
}

TEST(MotionPause, PauseDeceleratesResumeContinuesStepRunsOneSegment) {
  Machine m;
  m.enable_home_coord();
  ASSERT_TRUE(m.line(40, 0, 0, 50, 10).accepted);
  ASSERT_TRUE(m.line(40, 40, 0, 50, 11).accepted);
  ASSERT_TRUE(m.line(0, 40, 0, 50, 12).accepted);
  m.step(200);
  m.accept(Cmd::Pause);
  m.step(300);
  const double x = m.joint(0).pos_cmd;
  m.step(100);
  EXPECT_EQ(m.joint(0).pos_cmd, x) << "held";
  EXPECT_TRUE(m.status().traj.paused);
  m.accept(Cmd::Step);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.paused && m.joint(1).vel_cmd == 0 && m.joint(0).pos_cmd == 40; }, 20000));
  EXPECT_EQ(m.status().traj.queue, 2) << "STEP finished only the current segment";
  m.accept(Cmd::Resume);
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  EXPECT_NEAR(m.joint(0).pos_cmd, 0, 1e-9);
  EXPECT_NEAR(m.joint(1).pos_cmd, 40, 1e-9);
}

TEST(MotionScale, FeedOverrideScalesCoordAndJogsButNotBeyondJointLimits) {
  Machine m;
  m.enable_home_coord();
  m.accept(Cmd::Scale, 0, 0.5);
  ASSERT_TRUE(m.line(100, 0, 0, 60).accepted);
  m.step(400);
  EXPECT_NEAR(m.joint(0).vel_cmd, 30, 1e-3);
  m.accept(Cmd::Scale, 0, 5.0);  // 300 requested, joint limit 95 (100 minus compensation reserve) wins elsewhere
  m.step(400);
  EXPECT_LE(m.joint(0).vel_cmd, 100 + 1e-9);
  EXPECT_STREQ(m.send(Cmd::Scale, 0, -0.1).reason.c_str(), "feed override -0.1 is outside 0 to 10");
  EXPECT_STREQ(m.send(Cmd::RapidScale, 0, 1.5).reason.c_str(), "rapid override 1.5 is outside 0 to 1");
  EXPECT_STREQ(m.send(Cmd::MaxVelocity, 0, 0).reason.c_str(), "maximum velocity 0 must be positive");
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  m.accept(Cmd::Free);
  m.accept(Cmd::Scale, 0, 0.25);
  m.accept(Cmd::JogCont, 1, 40);
  m.step(300);
  EXPECT_NEAR(m.joint(1).vel_cmd, 10, 1e-3) << "SCALE affects jogs too (3.8.16)";
}

TEST(MotionJog, IncrementsAccumulate) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogIncr, 0, 20, 1.0);
  m.step(5);
  m.accept(Cmd::JogIncr, 0, 20, 1.0);  // before the first one finishes
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(0).pos_cmd, 2.0);
}

TEST(MotionJog, AbsoluteJogRetargetsInFlight) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogAbs, 1, 50, 100);
  m.step(200);
  m.accept(Cmd::JogAbs, 1, 50, 10);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(1).pos_cmd, 10.0);
}

TEST(MotionJog, ContinuousJogStopsAtTheSoftLimitOnceHomed) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; }));
  m.accept(Cmd::JogCont, 0, -100);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(0).pos_cmd, -10.0);
  const auto r = m.send(Cmd::JogCont, 0, -10);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "joint 0 is at its minimum soft limit -10: jogging further in - is refused");
  EXPECT_TRUE(m.send(Cmd::JogCont, 0, 10).accepted) << "away from the limit is fine";
}

TEST(MotionJog, ContinuousJogStoppedByALimitSwitchDisablesWithAReason) {
  Machine m;
  m.sims[2].pos_lim = 30;
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 2, 20);
  ASSERT_TRUE(m.run_until([&] { return !m.out().motion_enabled; }, 5000));
  const auto errors = m.all_errors();
  EXPECT_NE(errors.find("joint 2 on its positive limit switch (send override-limits, then jog off it): motion disabled"),
            std::string::npos) << errors;
  // Jogging further onto the switch is refused even with the override...
  m.accept(Cmd::OverrideLimits, 0, 1);
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.out().motion_enabled) << "the override keeps the limit from tripping again";
  const auto r = m.send(Cmd::JogIncr, 2, 5, 1);
  EXPECT_STREQ(r.reason.c_str(), "joint 2 is on its positive limit switch: jogging further in + is refused");
  // ...but jogging off it works, and the override ends with that jog.
  m.accept(Cmd::JogIncr, 2, 5, -2);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_FALSE(m.status().joints[2].override_limits) << "OVERRIDE_LIMITS lasts until the end of the next jog";
  EXPECT_TRUE(m.out().motion_enabled);
}

TEST(MotionJog, RefusalsSayWhy) {
  Machine m;
  EXPECT_STREQ(m.send(Cmd::JogCont, 0, 10).reason.c_str(), "cannot jog: motion is not enabled (machine off)");
  m.enable_home_coord();
  EXPECT_STREQ(m.send(Cmd::JogCont, 0, 10).reason.c_str(), "joint jogs need free mode (now COORD): jog the axis instead");
  motion::MotionCommand c;
  c.type = Cmd::JogCont;
  c.axis_mode = true;
  c.joint = 0;
  c.value[0] = 10;
  EXPECT_STREQ(m.send(c).reason.c_str(), "axis jogs need teleop mode (now COORD)");
  c.joint = 5;
  EXPECT_STREQ(m.send(c).reason.c_str(), "no axis 5");
  m.accept(Cmd::Free);
  EXPECT_STREQ(m.send(Cmd::JogIncr, 0, 10, 0).reason.c_str(), "incremental jog needs a non-zero distance");
  EXPECT_STREQ(m.send(Cmd::JogCont, 0, 0).reason.c_str(), "continuous jog needs a non-zero velocity");
  m.mc().in().jog_inhibit = true;
  EXPECT_STREQ(m.send(Cmd::JogCont, 0, 1).reason.c_str(), "jogging is inhibited (motion.jog-inhibit is set)");
}

TEST(MotionTeleop, AxisJogAndTeleopVectorMoveInCartesianSpace) {
  Machine m;
  m.accept(Cmd::Enable);
  for (int j = 0; j < 3; ++j) m.accept(Cmd::Home, j);
  m.step(10);
  m.accept(Cmd::Teleop);
  motion::MotionCommand c;
  c.type = Cmd::JogIncr;
  c.axis_mode = true;
  c.joint = 1;
  c.value[0] = 20;
  c.value[1] = 5;
  ASSERT_TRUE(m.send(c).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(1).pos_cmd, 5);
  motion::MotionCommand v;
  v.type = Cmd::SetTeleopVector;
  v.end[0] = 10;
  v.end[2] = -5;
  ASSERT_TRUE(m.send(v).accepted);
  m.step(500);
  EXPECT_NEAR(m.joint(0).vel_cmd, 10, 1e-3);
  EXPECT_NEAR(m.joint(2).vel_cmd, -5, 1e-3);
  v.end = Pose{};
  ASSERT_TRUE(m.send(v).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  m.step();
  EXPECT_EQ(m.joint(0).vel_cmd, 0);
}

TEST(MotionSegments, LinesAndArcsRunInCoordModeOnly) {
  Machine m;
  m.accept(Cmd::Enable);
  EXPECT_STREQ(m.line(1, 0, 0, 10).reason.c_str(), "SET_LINE needs coord mode (now FREE)");
  for (int j = 0; j < 3; ++j) m.accept(Cmd::Home, j);
  m.step(10);
  m.accept(Cmd::Coord);
  EXPECT_STREQ(m.line(250, 0, 0, 10, 7).reason.c_str(), "line 7: X250.0000 is outside the soft limits -10..200");
  ASSERT_TRUE(m.line(10, 0, 0, 20, 1).accepted);
  motion::MotionCommand arc;
  arc.type = Cmd::SetCircle;
  arc.end[0] = 10;
  arc.end[1] = 20;
  arc.center = {10, 10, 0};
  arc.normal = {0, 0, 1};
  arc.segment.feed = 20;
  arc.segment.line = 2;
  ASSERT_TRUE(m.send(arc).accepted);
  int line_seen = 0;
  ASSERT_TRUE(m.run_until([&] {
    line_seen = std::max(line_seen, m.status().traj.motion_line);
    return m.status().tp_done;
  }));
  EXPECT_EQ(line_seen, 2);
  EXPECT_NEAR(m.joint(0).pos_cmd, 10, 1e-9);
  EXPECT_NEAR(m.joint(1).pos_cmd, 20, 1e-9);
}

TEST(MotionSegments, AFullPlannerQueueDefersTheCommandInsteadOfLosingIt) {
  Machine m;
  m.enable_home_coord();
  int taken = 0;
  motion::MotionCommand c;
  c.type = Cmd::SetLine;
  c.segment.feed = 100;
  for (int i = 0; i < 70; ++i) {
    c.end[0] = (i % 2) ? 1 : 0;
    c.serial = 1000 + static_cast<uint64_t>(i);
    motion::MotionResult r;
    if (m.mc().handle(c, r)) ++taken;
    else break;
  }
  EXPECT_EQ(taken, 64) << "the 65th waits: handle() returns false and the caller offers it again";
}

TEST(MotionProbe, StopsOnContactAndRecordsThePosition) {
  Machine m;
  m.enable_home_coord();
  motion::MotionCommand p;
  p.type = Cmd::Probe;
  p.end[2] = -8;
  p.segment.feed = 5;
  p.segment.line = 3;
  ASSERT_TRUE(m.send(p).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.joint(2).pos_cmd < -3; }));
  m.mc().in().probe_input = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  const auto s = m.status();
  EXPECT_TRUE(s.traj.probe_tripped);
  EXPECT_NEAR(s.traj.probed_position[2], -3, 0.01);
  EXPECT_GT(m.joint(2).pos_cmd, -3.1) << "stopped soon after contact";
  m.accept(Cmd::ClearProbeFlag);
  EXPECT_FALSE(m.status().traj.probe_tripped);
}

// A drive's touch-probe latch whose PDO comes after the probe move has
// stopped: the result waits for it (probe_latch_pending) and takes it.
TEST(MotionProbe, ALatchArrivingAfterTheMoveStoppedIsWaitedForAndTaken) {
  Machine m;
  m.enable_home_coord();
  m.mc().in().joints[2].probe_latch_wired = true;
  motion::MotionCommand p;
  p.type = Cmd::Probe;
  p.end[2] = -8;
  p.segment.feed = 5;
  ASSERT_TRUE(m.send(p).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.joint(2).pos_cmd < -3; }));
  m.mc().in().probe_input = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  EXPECT_TRUE(m.status().traj.probe_tripped);
  EXPECT_TRUE(m.status().traj.probe_latch_pending) << "no latch yet: the result is not final";
  m.step(20);
  EXPECT_TRUE(m.status().traj.probe_latch_pending);
  // The latch arrives, 20 ms after the move ended.
  m.mc().in().joints[2].probe_position = -3.0021;
  m.mc().in().joints[2].probe_count += 1;
  m.step(1);
  const auto s = m.status();
  EXPECT_FALSE(s.traj.probe_latch_pending);
  const double offset = m.joint(2).motor_pos_cmd - m.joint(2).pos_cmd;  // motor offset, backlash, compensation
  EXPECT_NEAR(s.traj.probed_position[2], -3.0021 - offset, 1e-9);
}

TEST(MotionProbe, ALatchThatNeverComesEndsTheWaitWithAMessageNamingTheJoint) {
  Machine m;
  m.enable_home_coord();
  m.mc().in().joints[2].probe_latch_wired = true;
  motion::MotionCommand p;
  p.type = Cmd::Probe;
  p.end[2] = -8;
  p.segment.feed = 5;
  ASSERT_TRUE(m.send(p).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.joint(2).pos_cmd < -3; }));
  m.mc().in().probe_input = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  (void)m.all_messages();
  ASSERT_TRUE(m.run_until([&] { return !m.status().traj.probe_latch_pending; }));
  EXPECT_TRUE(m.status().traj.probe_tripped);
  EXPECT_NEAR(m.status().traj.probed_position[2], -3, 0.01) << "the commanded position at the trip";
  const std::string msgs = m.all_messages();
  EXPECT_NE(msgs.find("joint 2's touch probe latched nothing within 100 ms"), std::string::npos) << msgs;
}

// Without a wired latch nothing is waited for.
TEST(MotionProbe, NoWiredLatchMeansNoWait) {
  Machine m;
  m.enable_home_coord();
  motion::MotionCommand p;
  p.type = Cmd::Probe;
  p.end[2] = -8;
  p.segment.feed = 5;
  ASSERT_TRUE(m.send(p).accepted);
  ASSERT_TRUE(m.run_until([&] { return m.joint(2).pos_cmd < -3; }));
  m.mc().in().probe_input = true;
  m.step(1);
  EXPECT_FALSE(m.status().traj.probe_latch_pending);
}

TEST(MotionParameters, OneTableSetsJointAxisAndTrajectoryParameters) {
  Machine m;
  const auto idx = motion::find_param("joint.max-velocity");
  ASSERT_TRUE(idx);
  motion::MotionCommand c;
  c.type = Cmd::SetParameter;
  c.param = *idx;
  c.joint = 1;
  c.value[0] = 25;
  ASSERT_TRUE(m.send(c).accepted);
  EXPECT_EQ(m.mc().config().joints[1].max_velocity, 25);
  c.value[0] = -1;
  EXPECT_STREQ(m.send(c).reason.c_str(), "joint.max-velocity: value out of range");
  c.joint = 9;
  c.value[0] = 5;
  EXPECT_STREQ(m.send(c).reason.c_str(), "joint.max-velocity: no such joint");
  c.param = *motion::find_param("joint.min-limit");
  c.joint = 0;
  c.value[0] = 500;
  EXPECT_STREQ(m.send(c).reason.c_str(), "joint.min-limit: the minimum limit must stay below the maximum");
  c.param = 999;
  EXPECT_STREQ(m.send(c).reason.c_str(), "no parameter number 999");
  // Limits are not moved under a running motion.
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 0, 10);
  m.step(5);
  c.param = *motion::find_param("joint.max-limit");
  c.value[0] = 150;
  EXPECT_STREQ(m.send(c).reason.c_str(),
               "joint.max-limit cannot change while the machine moves (jogs, homing and queued moves keep the limits "
               "they were planned with): stop it first");
  EXPECT_FALSE(motion::find_param("joint.colour"));
}

TEST(MotionParameters, PlannerLookaheadAndBlendWindowComeFromTraj) {
  const auto ini = ini::IniFile::parse(
      "[TRAJ]\nLOOKAHEAD_SEGMENTS = 4000\nBLEND_SPAN_SEGMENTS = 12\nMAX_BLEND_HALF_WIDTH = 2.5\n", "m.ini");
  const tp::PlannerConfig p = motion::planner_config(motion::load_motion_config(ini, 3), 0x7);
  EXPECT_EQ(p.lookahead_segments, 4000);
  EXPECT_EQ(p.blend_span_segments, 12);
  EXPECT_EQ(p.max_blend_half_width, 2.5);
  const tp::PlannerConfig d = motion::planner_config(motion::load_motion_config(ini::IniFile::parse("", "e.ini"), 3), 0x7);
  EXPECT_EQ(d.lookahead_segments, 1000);
  EXPECT_EQ(d.blend_span_segments, 8);
  try {
    motion::load_motion_config(ini::IniFile::parse("[TRAJ]\nBLEND_SPAN_SEGMENTS = 40\n", "bad.ini"), 3);
    FAIL() << "accepted 40";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("bad.ini"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("BLEND_SPAN_SEGMENTS"), std::string::npos) << e.what();
  }
}

TEST(MotionOutputs, SynchronisedOutputsChangeWithTheNextMove) {
  Machine m;
  m.enable_home_coord();
  m.accept(Cmd::SetDigitalOut, 1, 1, 0);  // immediate (M64)
  EXPECT_TRUE(m.out().digital_out[1]);
  m.accept(Cmd::SetDigitalOut, 2, 1, 1);  // with motion (M62)
  EXPECT_FALSE(m.out().digital_out[2]);
  motion::MotionCommand c;
  c.type = Cmd::SetLine;
  c.end[0] = 5;
  c.segment.feed = 20;
  c.segment.id = 1;  // the task numbers its segments
  ASSERT_TRUE(m.send(c).accepted);
  m.step();
  m.step(2);
  EXPECT_TRUE(m.out().digital_out[2]);
  EXPECT_STREQ(m.send(Cmd::SetDigitalOut, 9, 1).reason.c_str(), "no digital output 9 (there are 4)");
}

TEST(MotionSpindle, SpeedDirectionOverrideAndBrake) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::SetSpindle, 0, -1200, 1);
  m.step();
  EXPECT_TRUE(m.out().spindles[0].reverse);
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, -1200);
  EXPECT_FALSE(m.out().spindles[0].brake);
  m.accept(Cmd::SpindleOverride, 0, 0.5);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out_abs, 600);
  EXPECT_STREQ(m.send(Cmd::SpindleBrake, 0, 1).reason.c_str(), "the spindle brake cannot engage while the spindle turns");
  m.accept(Cmd::SetSpindle, 0, 0, 0);
  m.accept(Cmd::SpindleBrake, 0, 1);
  m.step();
  EXPECT_TRUE(m.out().spindles[0].brake);
  EXPECT_STREQ(m.send(Cmd::SetSpindle, 3, 100, 1).reason.c_str(), "no spindle 3 (there are 1)");
}

TEST(MotionPositions, TheSevenFormsFollowTheManual) {
  motion::MotionConfig cfg = cnc::testing::basic_config();
  cfg.joints[0].backlash = 0.2;
  Machine m(cfg);
  m.sims[0].pos = 3;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);  // immediate homing: this position becomes HOME_OFFSET (0)
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; }));
  m.accept(Cmd::JogIncr, 0, 10, 5);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos && m.joint(0).backlash_filt == 0.1; }));
  m.step(3);
  const auto& o = m.joint(0);
  // motor = joint + backlash + screw comp + home offset, and back.
  EXPECT_NEAR(o.pos_cmd, 5, 1e-12);
  EXPECT_NEAR(o.motor_pos_cmd, o.pos_cmd + o.backlash_filt + o.motor_offset, 1e-12);
  EXPECT_NEAR(o.motor_offset, 3, 1e-12);
  EXPECT_NEAR(o.backlash_filt, 0.1, 1e-12);
  EXPECT_NEAR(o.pos_fb, m.sims[0].pos - o.backlash_filt - o.motor_offset, 1e-12);
  const auto s = m.status();
  EXPECT_TRUE(s.traj.carte_fb_valid);
  EXPECT_NEAR(s.traj.actual_position[0], o.pos_fb, 1e-12) << "carte_pos_fb from forward kinematics";
  EXPECT_NEAR(s.traj.position[0], o.pos_cmd, 1e-12);
}

TEST(MotionBacklash, CorrectionNeverExceedsTheReservedLimits) {
  motion::MotionConfig cfg = cnc::testing::basic_config();
  cfg.joints[0].backlash = 0.5;
  Machine m(cfg);
  m.accept(Cmd::Enable);
  double prev = 0, prev_v = 0, max_v = 0, max_a = 0;
  for (int rev = 0; rev < 6; ++rev) {
    m.accept(Cmd::JogIncr, 0, 100, rev % 2 ? -3 : 3);
    for (int i = 0; i < 400; ++i) {
      m.step();
      const double motor = m.joint(0).motor_pos_cmd;
      const double v = (motor - prev) / 0.001;
      if (i > 0 || rev > 0) {
        max_v = std::max(max_v, std::fabs(v));
        max_a = std::max(max_a, std::fabs(v - prev_v) / 0.001);
      }
      prev = motor;
      prev_v = v;
    }
  }
  EXPECT_LE(max_v, 100 * (1 + 1e-9)) << "motor velocity (joint + backlash) within the joint limit";
  EXPECT_LE(max_a, 1000 * (1 + 1e-6)) << "motor acceleration within the joint limit";
}

// Status distance to go per axis (the DRO's "to go" column) follows the
// executing move in coord mode and is zero when it has ended.
TEST(MotionStatusDtg, PerAxisDistanceToGoFollowsTheExecutingMove) {
  Machine m;
  m.enable_home_coord();
  ASSERT_TRUE(m.line(50, 20, 0, 20).accepted);
  m.step(200);
  const auto s = m.status();
  ASSERT_GT(s.traj.current_vel, 0);
  for (int a = 0; a < 3; ++a) {
    const double end[3] = {50, 20, 0};
    EXPECT_NEAR(s.traj.dtg[a], end[a] - s.traj.position[a], 1e-9) << "axis " << a;
  }
  EXPECT_GT(s.traj.dtg[0], 1);
  EXPECT_NEAR(s.traj.distance_to_go, std::hypot(s.traj.dtg[0], s.traj.dtg[1]), 1e-6);
  ASSERT_TRUE(m.run_until([&] { return m.status().tp_done; }));
  for (int a = 0; a < 3; ++a) EXPECT_EQ(m.status().traj.dtg[a], 0) << "axis " << a;
}
