// E-stop in the servo thread: a request word bumped by any client and the
// E-stop chain input are acted on in the very cycle they are seen (motion
// disabled, spindles off, planners flushed, homing aborted) and latched
// until an E-stop reset with the chain closed. The watchdog toward the
// drives runs whenever motion is enabled. A spindle amplifier fault stops
// motion as a joint's does.
#include <gtest/gtest.h>

#include "core/ipc/estop.hpp"
#include "tests/core/motion/machine.hpp"

using namespace cnc;
using cnc::testing::Machine;
using motion::Cmd;

namespace {

uint64_t request_word(uint32_t count, int32_t pid) {
  return (static_cast<uint64_t>(count) << 32) | static_cast<uint32_t>(pid);
}

}  // namespace

TEST(MotionEstop, ARequestDisablesMotionInTheCycleItIsSeenAndIsAcknowledged) {
  Machine m;
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogCont, 0, 50);
  m.step(100);
  ASSERT_TRUE(m.joint(0).amp_enable);
  ASSERT_GT(m.status().joints[0].velocity, 1);
  const uint64_t word = request_word(1, 4242);
  m.mc().in().estop_request = word;
  m.step();
  EXPECT_FALSE(m.out().motion_enabled);
  for (int j = 0; j < 3; ++j) EXPECT_FALSE(m.joint(j).amp_enable) << "joint " << j;
  EXPECT_EQ(m.mc().estop_request_seen(), word);
  const motion::MotionStatus s = m.status();
  EXPECT_TRUE(s.traj.estop_latched);
  EXPECT_EQ(s.traj.estop_cause, ipc::EstopCause::Request);
  EXPECT_EQ(s.traj.estop_pid, 4242);
  EXPECT_FALSE(s.traj.enabled);
}

TEST(MotionEstop, TheLatchRefusesEnableUntilResetAndEachNewRequestLatchesAgain) {
  Machine m;
  m.mc().in().estop_request = request_word(1, 7);
  m.step();
  const auto refused = m.send(Cmd::Enable);
  EXPECT_FALSE(refused.accepted);
  EXPECT_STREQ(refused.reason.c_str(), "cannot enable: E-stop is latched (request by a client): reset the E-stop first");
  m.accept(Cmd::EstopReset);
  m.step();
  EXPECT_FALSE(m.status().traj.estop_latched);
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.out().motion_enabled);
  // The same word again is not a new request; a bumped one is.
  m.step(5);
  EXPECT_TRUE(m.out().motion_enabled);
  m.mc().in().estop_request = request_word(2, 8);
  m.step();
  EXPECT_FALSE(m.out().motion_enabled);
  EXPECT_EQ(m.status().traj.estop_pid, 8);
}

TEST(MotionEstop, AnOpenChainLatchesAndResetIsRefusedUntilItCloses) {
  Machine m;
  m.accept(Cmd::Enable);
  m.step();
  m.mc().in().estop_chain_closed = false;
  m.step();
  EXPECT_FALSE(m.out().motion_enabled);
  EXPECT_TRUE(m.status().traj.estop_latched);
  EXPECT_EQ(m.status().traj.estop_cause, ipc::EstopCause::ChainOpen);
  const auto refused = m.send(Cmd::EstopReset);
  EXPECT_FALSE(refused.accepted);
  EXPECT_STREQ(refused.reason.c_str(), "the E-stop chain is open (iocontrol.0.emc-enable-in is false)");
  m.mc().in().estop_chain_closed = true;
  m.step();
  EXPECT_TRUE(m.status().traj.estop_latched) << "closing the chain alone does not reset";
  m.accept(Cmd::EstopReset);
  m.step();
  EXPECT_FALSE(m.status().traj.estop_latched);
  EXPECT_EQ(m.status().traj.estop_cause, ipc::EstopCause::None);
}

TEST(MotionEstop, SpindlesStopPlannersAreFlushedAndNothingRestartsAfterReset) {
  Machine m;
  m.enable_home_coord();
  m.accept(Cmd::SetSpindle, 0, 1200, 1);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(m.line(20.0 * (i + 1), 0, 0, 50, i + 1).accepted);
  m.step(50);
  ASSERT_TRUE(m.out().spindles[0].on);
  ASSERT_FALSE(m.status().tp_done);
  m.mc().in().estop_request = request_word(1, 1);
  m.step();
  EXPECT_FALSE(m.out().spindles[0].on);
  EXPECT_EQ(m.out().spindles[0].speed_out, 0.0);
  EXPECT_TRUE(m.out().spindles[0].brake);
  EXPECT_TRUE(m.status().tp_done) << "the queue was dropped";
  m.accept(Cmd::EstopReset);
  m.accept(Cmd::Enable);
  m.step(200);
  EXPECT_FALSE(m.out().spindles[0].on) << "the spindle stays off when the machine comes back";
  EXPECT_TRUE(m.status().tp_done) << "no old segment resumes";
  EXPECT_LT(std::fabs(m.status().joints[0].velocity), 1e-9);
}

TEST(MotionEstop, HomingIsAborted) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].homing.search_vel = 20;
  c.joints[0].homing.latch_vel = 2;
  Machine m(c);
  m.sims[0].home_min = 150;
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  m.step(50);
  ASSERT_TRUE(m.status().any_homing);
  m.mc().in().estop_chain_closed = false;
  m.step();
  EXPECT_FALSE(m.status().any_homing);
  EXPECT_FALSE(m.status().joints[0].homed);
  EXPECT_FALSE(m.joint(0).amp_enable);
}

TEST(MotionWatchdog, RunsWheneverMotionIsEnabledWithoutACommand) {
  Machine m;
  m.step(3);
  EXPECT_FALSE(m.out().watchdog);
  EXPECT_FALSE(m.out().watchdog_enabled);
  m.accept(Cmd::Enable);
  bool seen_true = false, seen_false = false;
  for (int i = 0; i < 4; ++i) {
    m.step();
    EXPECT_TRUE(m.out().watchdog_enabled);
    (m.out().watchdog ? seen_true : seen_false) = true;
  }
  EXPECT_TRUE(seen_true && seen_false) << "the pin changes every cycle";
  EXPECT_TRUE(m.status().traj.watchdog_enabled);
  m.accept(Cmd::Disable);
  m.step(3);
  EXPECT_FALSE(m.out().watchdog);
  EXPECT_FALSE(m.out().watchdog_enabled);
  EXPECT_FALSE(m.status().traj.watchdog_enabled);
}

TEST(MotionSafety, SpindleAmplifierFaultDisablesMotionNamingTheSpindle) {
  Machine m;
  m.enable_home_coord();
  m.accept(Cmd::SetSpindle, 0, 1200, 1);
  ASSERT_TRUE(m.line(100, 0, 0, 20, 7).accepted);
  m.step(100);
  ASSERT_TRUE(m.out().motion_enabled);
  m.mc().in().spindles[0].amp_fault = true;
  m.step();
  EXPECT_FALSE(m.out().motion_enabled);
  EXPECT_FALSE(m.out().spindles[0].on);
  EXPECT_NE(m.all_errors().find("spindle 0 amplifier fault (spindle.0.amp-fault-in): motion disabled"),
            std::string::npos);
  const motion::MotionStatus s = m.status();
  EXPECT_TRUE(s.faulted);
  EXPECT_TRUE(s.spindles[0].amp_fault);
  EXPECT_EQ(s.fault_spindle, 0);
  EXPECT_EQ(s.fault_joint, -1);
  EXPECT_STREQ(s.fault_reason.c_str(), "spindle 0 amplifier fault (spindle.0.amp-fault-in)");
  // The next enable clears the report (the fault input is gone by then).
  m.mc().in().spindles[0].amp_fault = false;
  m.accept(Cmd::Enable);
  m.step();
  EXPECT_TRUE(m.status().fault_reason.empty());
  EXPECT_FALSE(m.status().spindles[0].amp_fault);
}

TEST(MotionSafety, JointAmplifierFaultIsReportedWithTheJoint) {
  Machine m;
  m.accept(Cmd::Enable);
  m.step(2);
  m.sims[1].amp_fault = true;
  m.step();
  const motion::MotionStatus s = m.status();
  EXPECT_EQ(s.fault_joint, 1);
  EXPECT_EQ(s.fault_spindle, -1);
  EXPECT_STREQ(s.fault_reason.c_str(), "joint 1 amplifier fault (joint.1.amp-fault-in)");
}
