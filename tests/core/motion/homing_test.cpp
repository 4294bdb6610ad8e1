// Homing against simulated switches and index pulses (the manual's 3.7 and
// LinuxCNC's HOME_* parameters).
#include <gtest/gtest.h>

#include "tests/core/motion/machine.hpp"

using namespace cnc;
using cnc::testing::Machine;
using motion::Cmd;

namespace {

motion::MotionConfig switch_config() {
  motion::MotionConfig c = cnc::testing::basic_config();
  auto& h = c.joints[0].homing;
  h.search_vel = 20;
  h.latch_vel = 2;
  h.offset = 190;   // the switch reads 190 in joint coordinates
  h.home = 180;     // where the joint goes after homing
  h.final_vel = 50;
  return c;
}

// Runs homing of one joint to completion; returns false on a failure.
bool home(Machine& m, int joint, int max_cycles = 200000) {
  EXPECT_TRUE(m.send(Cmd::Home, joint).accepted);
  return m.run_until([&] { return m.status().joints[joint].homed || !m.status().joints[joint].homing; }, max_cycles) &&
         m.status().joints[joint].homed;
}

}  // namespace

TEST(Homing, SwitchLatchedOnApproachAfterBackingOff) {
  Machine m(switch_config());
  m.sims[0].pos = 50;
  m.sims[0].home_min = 100;  // the switch closes at motor position 100
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 0)) << m.all_errors();
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(0).pos_cmd, 180);
  // The switch (motor 100) now reads 190: within one cycle at the latch velocity.
  EXPECT_NEAR(m.joint(0).motor_offset, 100 - 190, 2 * 0.001 + 1e-9);
  EXPECT_NEAR(m.sims[0].pos, 90, 2 * 0.001 + 1e-9);
}

TEST(Homing, SwitchLatchedOnRelease) {
  motion::MotionConfig c = switch_config();
  c.joints[0].homing.latch_vel = -2;
  Machine m(c);
  m.sims[0].pos = 50;
  m.sims[0].home_min = 100;
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 0)) << m.all_errors();
  EXPECT_NEAR(m.joint(0).motor_offset, 100 - 190, 2 * 0.001 + 1e-9);
}

TEST(Homing, IndexPulseLatchesExactly) {
  motion::MotionConfig c = switch_config();
  c.joints[0].homing.use_index = true;
  Machine m(c);
  m.sims[0].pos = 50;
  m.sims[0].home_min = 100;
  m.sims[0].index_spacing = 5;
  m.sims[0].index_offset = 0.7;  // pulses at ..., 95.7, 100.7, ...
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 0)) << m.all_errors();
  EXPECT_NEAR(m.joint(0).motor_offset, 100.7 - 190, 1e-9) << "the first index after the switch, exactly";
}

TEST(Homing, IndexOnlyWithoutSearch) {
  motion::MotionConfig c = switch_config();
  c.joints[0].homing.search_vel = 0;
  c.joints[0].homing.use_index = true;
  Machine m(c);
  m.sims[0].pos = 42;
  m.sims[0].index_spacing = 5;
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 0)) << m.all_errors();
  EXPECT_NEAR(m.joint(0).motor_offset, 45 - 190, 1e-9);
}

TEST(Homing, ImmediateHomingTakesTheCurrentPosition) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[1].homing.offset = 7;
  c.joints[1].homing.home = 5;
  Machine m(c);
  m.sims[1].pos = 33;
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 1));
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(1).pos_cmd, 5);
  EXPECT_DOUBLE_EQ(m.sims[1].pos, 31);
}

TEST(Homing, StartingOnTheSwitchBacksOffFirst) {
  Machine m(switch_config());
  m.sims[0].pos = 120;
  m.sims[0].home_min = 100;
  m.accept(Cmd::Enable);
  m.send(Cmd::Home, 0);
  m.step(10);
  EXPECT_EQ(m.joint(0).home_state, static_cast<int32_t>(motion::HomeState::InitialBackoff));
  EXPECT_LT(m.joint(0).vel_cmd, 0);
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; }, 200000)) << m.all_errors();
  EXPECT_NEAR(m.joint(0).motor_offset, -90, 0.002 + 1e-9);
}

TEST(Homing, SwitchNotFoundFailsWithAReason) {
  Machine m(switch_config());
  m.accept(Cmd::Enable);
  EXPECT_FALSE(home(m, 0));
  EXPECT_NE(m.all_errors().find("joint 0: homing failed: the home switch was not found within the travel"), std::string::npos);
  EXPECT_FALSE(m.status().joints[0].homing);
}

TEST(Homing, ALimitSwitchDuringHomingStopsIt) {
  Machine m(switch_config());
  m.sims[0].pos = 50;
  m.sims[0].pos_lim = 90;  // the limit comes before the home switch
  m.sims[0].home_min = 100;
  m.accept(Cmd::Enable);
  EXPECT_FALSE(home(m, 0));
  EXPECT_NE(m.all_errors().find("joint 0 on its positive limit switch while homing"), std::string::npos);
  EXPECT_FALSE(m.out().motion_enabled);
}

TEST(Homing, IgnoreLimitsWhenTheLimitSwitchIsTheHomeSwitch) {
  motion::MotionConfig c = switch_config();
  c.joints[0].homing.ignore_limits = true;
  Machine m(c);
  m.sims[0].pos = 50;
  m.sims[0].pos_lim = 100;
  m.sims[0].home_min = 100;
  m.accept(Cmd::Enable);
  ASSERT_TRUE(home(m, 0)) << m.all_errors();
}

TEST(Homing, SharedSwitchAlreadyActiveIsRefused) {
  motion::MotionConfig c = switch_config();
  c.joints[0].homing.is_shared = true;
  Machine m(c);
  m.sims[0].pos = 120;
  m.sims[0].home_min = 100;
  m.accept(Cmd::Enable);
  m.step();
  const auto r = m.send(Cmd::Home, 0);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "joint 0: its shared home switch is already active; move the joint off it first");
}

TEST(Homing, RefusedUnlessEnabledAndInFreeMode) {
  Machine m;
  EXPECT_STREQ(m.send(Cmd::Home, 0).reason.c_str(), "cannot home: motion is not enabled (machine off)");
  m.enable_home_coord();
  EXPECT_STREQ(m.send(Cmd::Home, 0).reason.c_str(), "homing needs free mode (now COORD)");
  m.accept(Cmd::Free);
  m.mc().in().homing_inhibit = true;
  EXPECT_STREQ(m.send(Cmd::Home, 0).reason.c_str(), "homing is inhibited (motion.homing-inhibit is set)");
  m.mc().in().homing_inhibit = false;
  EXPECT_STREQ(m.send(Cmd::Home, 5).reason.c_str(), "no joint 5");
  EXPECT_STREQ(m.send(Cmd::Home, -1).reason.c_str(), "no joint has a HOME_SEQUENCE: home joints one at a time");
}

TEST(Homing, HomeAllFollowsTheSequence) {
  motion::MotionConfig c = cnc::testing::basic_config();
  for (int j = 0; j < 3; ++j) {
    auto& h = c.joints[static_cast<std::size_t>(j)].homing;
    h.search_vel = 30;
    h.latch_vel = 3;
    h.offset = 100;
    h.home = 100;
    h.has_sequence = true;
  }
  c.joints[2].homing.sequence = 0;  // Z first
  c.joints[0].homing.sequence = 1;
  c.joints[1].homing.sequence = 1;
  Machine m(c);
  for (auto& s : m.sims) s.home_min = 60;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, -1);
  int64_t started[3] = {-1, -1, -1}, finished[3] = {-1, -1, -1};
  ASSERT_TRUE(m.run_until([&] {
    const auto s = m.status();
    for (int j = 0; j < 3; ++j) {
      if (s.joints[j].homing && started[j] < 0) started[j] = static_cast<int64_t>(m.cycles);
      if (s.joints[j].homed && finished[j] < 0) finished[j] = static_cast<int64_t>(m.cycles);
    }
    return s.all_homed && !s.any_homing;
  }, 400000)) << m.all_errors();
  EXPECT_LE(finished[2], started[0]) << "sequence 0 finishes before sequence 1 starts";
  EXPECT_GT(started[0], started[2]);
  EXPECT_EQ(started[0], started[1]) << "joints of one sequence start together";
}

TEST(Homing, GantryJointsHomeInSyncAndSquareTheirAxis) {
  motion::MotionConfig c = cnc::testing::basic_config(4);
  for (int j = 1; j <= 2; ++j) {
    auto& h = c.joints[static_cast<std::size_t>(j)].homing;
    h.search_vel = 20;
    h.latch_vel = 2;
    h.offset = 150;
    h.home = 100;
    h.has_sequence = true;
    h.sequence = -1;  // synchronised
  }
  c.joints[3] = c.joints[0];
  Machine m(c, "XYYZ");
  m.sims[1].pos = 10;
  m.sims[2].pos = 10.4;       // the gantry is racked by 0.4 mm
  m.sims[1].home_min = 80;
  m.sims[2].home_min = 80.9;  // and the switches sit 0.9 mm apart
  m.accept(Cmd::Enable);
  // Homing one joint of a synchronised group homes the whole group.
  m.accept(Cmd::Home, 1);
  bool final_seen = false;
  double max_skew_change = 0;
  double skew0 = 0;
  ASSERT_TRUE(m.run_until([&] {
    const auto& a = m.joint(1);
    const auto& b = m.joint(2);
    if (a.home_state == static_cast<int32_t>(motion::HomeState::FinalMove)) {
      if (!final_seen) skew0 = a.pos_cmd - b.pos_cmd;
      final_seen = true;
      // In the final move both go to HOME together: the skew shrinks
      // proportionally and both arrive in the same cycle.
      EXPECT_EQ(a.home_state, b.home_state);
      max_skew_change = std::max(max_skew_change, std::fabs(a.pos_cmd - b.pos_cmd));
    }
    return m.status().joints[1].homed && m.status().joints[2].homed;
  }, 400000)) << m.all_errors();
  EXPECT_TRUE(final_seen);
  EXPECT_LE(max_skew_change, std::fabs(skew0) + 1e-9);
  EXPECT_DOUBLE_EQ(m.joint(1).pos_cmd, 100);
  EXPECT_DOUBLE_EQ(m.joint(2).pos_cmd, 100);
  // Each joint latched its own switch: the gantry is square now.
  EXPECT_NEAR(m.sims[2].pos - m.sims[1].pos, 0.9, 0.004);
  EXPECT_FALSE(m.status().joints[0].homed) << "joints outside the group are untouched";
  // Joint jogs of a group joint are refused before homing (no racking).
  EXPECT_TRUE(m.send(Cmd::JogIncr, 1, 5, 1).accepted) << "after homing a group joint may be jogged";
}

TEST(Homing, DriveHomingSuspendsFollowingErrorAndResumesWithoutAJump) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].homing.mode = motion::HomeMode::Drive;
  c.joints[0].homing.home = 20;
  c.joints[0].homing.final_vel = 40;
  Machine m(c);
  m.sims[0].pos = 70;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  m.step();
  EXPECT_TRUE(m.joint(0).drive_home_start);
  // The drive moves on its own (far more than FERROR) and reports busy.
  auto& in = m.mc().in().joints[0];
  for (int i = 0; i < 500; ++i) {
    m.sims[0].pos -= 0.1;
    in.drive_home_busy = true;
    m.step();
  }
  EXPECT_TRUE(m.out().motion_enabled) << m.all_errors();
  EXPECT_NEAR(m.joint(0).pos_cmd, m.joint(0).pos_fb, 0.11) << "the command followed the feedback";
  m.sims[0].pos = 0;  // the drive set its reference: HOME_OFFSET (0) here
  in.drive_home_busy = false;
  in.drive_home_done = true;
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; })) << m.all_errors();
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos; }));
  EXPECT_DOUBLE_EQ(m.joint(0).pos_cmd, 20);
  EXPECT_DOUBLE_EQ(m.sims[0].pos, 20);
}

TEST(Homing, DriveHomingErrorIsReported) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].homing.mode = motion::HomeMode::Drive;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  m.step(3);
  m.mc().in().joints[0].drive_home_error = true;
  m.step(3);
  EXPECT_FALSE(m.status().joints[0].homing);
  EXPECT_NE(m.all_errors().find("joint 0: homing failed: the drive reported a homing error"), std::string::npos);
}

TEST(Homing, LockingIndexerUnlocksFirstAndLocksAfter) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[2].homing.locking_indexer = true;
  c.joints[2].homing.home = 3;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 2);
  m.step(5);
  EXPECT_TRUE(m.joint(2).unlock);
  EXPECT_EQ(m.joint(2).pos_cmd, 0) << "no motion before the indexer is unlocked";
  m.mc().in().joints[2].is_unlocked = true;
  ASSERT_TRUE(m.run_until([&] { return !m.joint(2).unlock; }));
  EXPECT_FALSE(m.status().joints[2].homed) << "waits for the lock";
  m.mc().in().joints[2].is_unlocked = false;
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[2].homed; }));
  EXPECT_DOUBLE_EQ(m.joint(2).pos_cmd, 3);
}

TEST(Homing, UnhomeAllOrOnlyVolatileJoints) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[1].homing.volatile_home = true;
  Machine m(c);
  m.enable_home_coord();
  m.accept(Cmd::Unhome, -2);
  m.step();
  EXPECT_TRUE(m.status().joints[0].homed);
  EXPECT_FALSE(m.status().joints[1].homed);
  EXPECT_EQ(m.mc().mode(), ipc::MotionMode::Free) << "coord mode needs homed joints";
  m.accept(Cmd::Unhome, -1);
  m.step();
  EXPECT_FALSE(m.status().joints[0].homed);
  EXPECT_STREQ(m.send(Cmd::Unhome, 8).reason.c_str(), "no joint 8");
}
