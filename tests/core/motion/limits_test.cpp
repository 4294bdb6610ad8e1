// Every velocity, acceleration and speed limit holds at motion's outputs
// whatever the command and the overrides say, and run-time changes of the
// limits (SET_xxx) take effect everywhere: for the next move the planner
// gets, for jogs, for the spindle at the next cycle; values beyond the INI
// file's (the machine's limits) and limit changes under running motion are
// refused with a reason. Each test drives the command past the limit and
// checks the output (joint velocity and acceleration commands, the
// spindle's speed output).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/motion/motion_component.hpp"
#include "core/motion/params.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "tests/core/motion/machine.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using cnc::testing::Machine;
using motion::Cmd;

namespace {

// The project's planner, planning inline (deterministic).
Machine::PlannerMaker real_planner() {
  return [](const tp::PlannerConfig& c) { return tp::make_planner(c, tp::PlannerThreading::Inline); };
}

// Largest |velocity| and |acceleration| commanded to a joint while `run` steps.
struct Peak {
  double vel = 0, acc = 0, path = 0;
};

template <class Until>
Peak watch(Machine& m, Until until, int max_cycles = 200000) {
  Peak p;
  m.step();
  for (int i = 0; i < max_cycles && !until(); ++i) {
    m.step();
    double path2 = 0;
    for (int j = 0; j < 3; ++j) {
      p.vel = std::max(p.vel, std::fabs(m.joint(j).vel_cmd));
      p.acc = std::max(p.acc, std::fabs(m.joint(j).acc_cmd));
      path2 += m.joint(j).vel_cmd * m.joint(j).vel_cmd;
    }
    p.path = std::max(p.path, std::sqrt(path2));
  }
  return p;
}

motion::MotionResult set(Machine& m, const char* name, int index, double value) {
  const auto idx = motion::find_param(name);
  EXPECT_TRUE(idx) << name;
  motion::MotionCommand c;
  c.type = Cmd::SetParameter;
  c.param = idx.value_or(0);
  c.joint = static_cast<int16_t>(index);
  c.value[0] = value;
  return m.send(c);
}

motion::MotionResult move(Machine& m, double x, double y, double z, double feed, tp::MotionType type) {
  motion::MotionCommand c;
  c.type = Cmd::SetLine;
  c.end[0] = x;
  c.end[1] = y;
  c.end[2] = z;
  c.segment.type = type;
  c.segment.feed = feed;
  c.segment.max_velocity = 1e99;
  c.segment.max_acceleration = 1e99;
  c.segment.line = 1;
  c.segment.term = tp::TermCond::ExactStop;
  return m.send(c);
}

// Runs a move to the end and returns the peaks along it.
Peak run_move(Machine& m, double x, double y, double z, double feed, tp::MotionType type = tp::MotionType::Feed) {
  const auto r = move(m, x, y, z, feed, type);
  EXPECT_TRUE(r.accepted) << r.reason.c_str();
  return watch(m, [&] { return m.status().tp_done && m.out().in_position; });
}

}  // namespace

// --- run-time changes reach the planner (the issue's `cnc set` then G0)

TEST(MotionLimits, AxisVelocitySetAtRunTimeHoldsForTheNextRapid) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  ASSERT_TRUE(set(m, "axis.max-velocity", 0, 10).accepted);
  const Peak p = run_move(m, 50, 0, 0, 1e6, tp::MotionType::Traverse);
  EXPECT_LE(p.vel, 10 * 1.0001) << "X ran past the axis limit set at run time";
  EXPECT_GT(p.vel, 9) << "and close to it";
  EXPECT_EQ(m.status().axes[0].max_velocity, 10) << "the status shows the limit in force";
  EXPECT_EQ(m.status().axes[0].velocity_limit, 10);
}

TEST(MotionLimits, PathVelocitySetAtRunTimeHoldsForTheNextMove) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  ASSERT_TRUE(set(m, "traj.max-velocity", 0, 5).accepted);
  const Peak p = run_move(m, 20, 20, 0, 1e6, tp::MotionType::Traverse);
  EXPECT_LE(p.path, 5 * 1.0001);
  EXPECT_EQ(m.status().traj.max_linear_velocity, 5);
}

TEST(MotionLimits, AxisAccelerationSetAtRunTimeHoldsForTheNextMove) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  ASSERT_TRUE(set(m, "axis.max-acceleration", 1, 100).accepted);
  const Peak p = run_move(m, 0, 60, 0, 80);
  EXPECT_LE(p.acc, 100 * 1.02) << "Y accelerated past the limit set at run time";
}

TEST(MotionLimits, JointLimitsHoldInCoordinatedMotion) {
  // The axis allows 100 units/s but its joint only 20 (and 200 units/s^2):
  // the planner moves the axis within both.
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[0].max_velocity = 20;
  c.joints[0].max_acceleration = 200;
  Machine m(c, "XYZ", real_planner());
  m.enable_home_coord();
  const Peak p = run_move(m, 100, 0, 0, 1e6, tp::MotionType::Traverse);
  EXPECT_LE(p.vel, 20 * 1.0001);
  EXPECT_LE(p.acc, 200 * 1.02);
  EXPECT_EQ(m.status().axes[0].velocity_limit, 20) << "the status says what the axis moves under";
}

// --- overrides cannot push past the limits

TEST(MotionLimits, FeedOverrideOfTenKeepsAxisVelocityAndAcceleration) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  m.accept(Cmd::Scale, 0, 10);
  const Peak p = run_move(m, 150, 0, 0, 90);
  EXPECT_LE(p.vel, 100 * 1.0001);
  EXPECT_LE(p.acc, 1000 * 1.02);
}

TEST(MotionLimits, MaxVelocityOverrideAboveTheLimitsDoesNotRaiseThem) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  m.accept(Cmd::MaxVelocity, 0, 1e6);
  m.accept(Cmd::RapidScale, 0, 1);
  const Peak p = run_move(m, 150, 0, 0, 1e6, tp::MotionType::Traverse);
  EXPECT_LE(p.vel, 100 * 1.0001);
}

TEST(MotionLimits, AdaptiveFeedAboveOneDoesNotRaiseTheFeed) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  m.accept(Cmd::AdaptiveFeedEnable, 0, 1);
  m.mc().in().adaptive_feed = 5;
  const Peak p = run_move(m, 100, 0, 0, 30);
  EXPECT_LE(p.vel, 30 * 1.0001) << "adaptive feed scales down only";
}

// --- jogs

TEST(MotionLimits, JointJogFasterThanTheLimitInForceIsClamped) {
  Machine m;
  m.accept(Cmd::Enable);
  ASSERT_TRUE(set(m, "joint.max-velocity", 0, 30).accepted);
  m.accept(Cmd::Scale, 0, 2);  // the feed override scales jogs too
  m.accept(Cmd::JogCont, 0, 1000);
  const Peak p = watch(m, [&] { return m.cycles > 2000; });
  EXPECT_LE(p.vel, 30 * 1.0001);
  EXPECT_GT(p.vel, 29);
  EXPECT_EQ(m.status().joints[0].velocity_limit, 30);
}

TEST(MotionLimits, AxisJogIsLimitedByTheJointThatMovesTheAxis) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.joints[1].max_velocity = 25;
  Machine m(c);
  m.accept(Cmd::Enable);
  for (int j = 0; j < 3; ++j) {
    m.accept(Cmd::Home, j);
    ASSERT_TRUE(m.run_until([&] { return m.status().joints[j].homed; }, 20000));
  }
  m.accept(Cmd::Teleop);
  motion::MotionCommand jog;
  jog.type = Cmd::JogCont;
  jog.axis_mode = true;
  jog.joint = 1;
  jog.value[0] = 100;
  ASSERT_TRUE(m.send(jog).accepted);
  const Peak p = watch(m, [&] { return m.cycles > 3000; });
  EXPECT_LE(p.vel, 25 * 1.0001) << "axis Y's jog ran its joint past MAX_VELOCITY";
}

// --- how and when run-time changes are accepted

TEST(MotionLimits, ValuesBeyondTheIniAreRefusedNamingTheKey) {
  Machine m;
  auto r = set(m, "axis.max-velocity", 0, 500);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(),
               "axis.max-velocity: 500 is above [AXIS_X]MAX_VELOCITY = 100, the machine's limit (run-time changes may "
               "only be stricter)");
  r = set(m, "joint.min-limit", 2, -50);
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(std::string(r.reason.c_str()).find("below [JOINT_2]MIN_LIMIT = -10"), std::string::npos) << r.reason.c_str();
  r = set(m, "joint.ferror", 0, 5);
  EXPECT_FALSE(r.accepted) << "a looser following-error limit than the INI's";
  EXPECT_EQ(m.mc().config().axes[0].max_velocity, 100) << "nothing changed";
  EXPECT_TRUE(set(m, "axis.max-velocity", 0, 100).accepted) << "back to the INI's value is allowed";
}

TEST(MotionLimits, LimitChangesAreRefusedWhileMotionIsQueuedOrMoving) {
  Machine m(cnc::testing::basic_config(), "XYZ", real_planner());
  m.enable_home_coord();
  ASSERT_TRUE(move(m, 100, 0, 0, 50, tp::MotionType::Feed).accepted);
  m.step(20);
  const auto r = set(m, "axis.max-velocity", 0, 10);
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(std::string(r.reason.c_str()).find("cannot change while the machine moves"), std::string::npos)
      << r.reason.c_str();
  EXPECT_TRUE(set(m, "joint.ferror", 0, 0.5).accepted) << "a following-error limit applies from the next cycle";
  EXPECT_EQ(m.status().joints[0].ferror, 0.5);
}

// --- spindle speed limits ([SPINDLE_n])

TEST(MotionLimits, SpindleSpeedAboveMaxForwardIsClampedAtTheOutput) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.spindles = 1;
  c.spindle[0].max_forward = 10000;
  c.spindle[0].max_reverse = 10000;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::SpindleOverride, 0, 1.1);
  m.accept(Cmd::SetSpindle, 0, 50000, 1);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 10000) << "50000 rpm x 110 % reached the drive";
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out_rps, 10000.0 / 60);
  EXPECT_TRUE(m.status().spindles[0].speed_limited);
  EXPECT_DOUBLE_EQ(m.status().spindles[0].speed, 50000) << "the command stays as given";
  m.accept(Cmd::SetSpindle, 0, -20000, 1);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, -10000);
  EXPECT_TRUE(m.out().spindles[0].reverse);
  m.accept(Cmd::SetSpindle, 0, 8000, 1);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 8800) << "within the limits: command x override";
  EXPECT_FALSE(m.status().spindles[0].speed_limited);
}

TEST(MotionLimits, SpindleSpeedBelowMinimumIsRaisedToIt) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.spindles = 1;
  c.spindle[0].min_forward = 500;
  c.spindle[0].min_reverse = 800;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::SetSpindle, 0, 100, 1);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 500);
  m.accept(Cmd::SetSpindle, 0, -100, 1);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, -800);
  m.accept(Cmd::SetSpindle, 0, 0, 0);
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 0) << "a stopped spindle stays stopped";
}

TEST(MotionLimits, SpindleWithoutReverseRefusesReverse) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.spindles = 1;
  c.spindle[0].max_forward = 10000;
  c.spindle[0].max_reverse = 0;
  Machine m(c);
  m.accept(Cmd::Enable);
  const auto r = m.send(Cmd::SetSpindle, 0, -1000, 1);
  EXPECT_FALSE(r.accepted);
  EXPECT_STREQ(r.reason.c_str(), "spindle 0 may not turn in reverse ([SPINDLE_0]MAX_REVERSE_VELOCITY is 0)");
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 0);
}

TEST(MotionLimits, SpindleLimitSetAtRunTimeAppliesFromTheNextCycle) {
  motion::MotionConfig c = cnc::testing::basic_config();
  c.spindles = 1;
  c.spindle[0].max_forward = 10000;
  Machine m(c);
  m.accept(Cmd::Enable);
  m.accept(Cmd::SetSpindle, 0, 9000, 1);
  m.step();
  ASSERT_DOUBLE_EQ(m.out().spindles[0].speed_out, 9000);
  ASSERT_TRUE(set(m, "spindle.max-forward-velocity", 0, 6000).accepted) << "while the spindle turns";
  m.step();
  EXPECT_DOUBLE_EQ(m.out().spindles[0].speed_out, 6000);
  EXPECT_EQ(m.status().spindles[0].max_forward, 6000);
  EXPECT_FALSE(set(m, "spindle.max-forward-velocity", 0, 12000).accepted) << "above the INI's";
}

TEST(MotionLimits, SpindleLimitsAreReadFromTheIni) {
  const auto ini = ini::IniFile::parse(
      "[SPINDLE_0]\nMAX_FORWARD_VELOCITY = 10000\nMIN_FORWARD_VELOCITY = 100\n[SPINDLE_1]\nMAX_REVERSE_VELOCITY = 0\n",
      "m.ini");
  const motion::MotionConfig c = motion::load_motion_config(ini, 3);
  EXPECT_EQ(c.spindle[0].max_forward, 10000);
  EXPECT_EQ(c.spindle[0].max_reverse, 10000) << "MAX_REVERSE_VELOCITY defaults to MAX_FORWARD_VELOCITY";
  EXPECT_EQ(c.spindle[0].min_reverse, 100) << "MIN_REVERSE_VELOCITY defaults to MIN_FORWARD_VELOCITY";
  EXPECT_EQ(c.spindle[1].max_reverse, 0);
  EXPECT_GT(c.spindle[1].max_forward, 1e98);
  const auto bad = ini::IniFile::parse("[SPINDLE_0]\nMAX_FORWARD_VELOCITY = 100\nMIN_FORWARD_VELOCITY = 500\n", "m.ini");
  try {
    motion::load_motion_config(bad, 3);
    FAIL() << "MIN above MAX accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("m.ini:3: [SPINDLE_0]MIN_FORWARD_VELOCITY"), std::string::npos) << e.what();
  }
}

// --- the servo period is the period of the thread that runs motion

namespace {

// Builds motmod on a HAL from HAL lines and an INI text; returns the
// error of on_ready ("" when it started).
std::string start_motmod(const std::string& ini_text, const std::vector<std::string>& hal_lines) {
  const auto ini = ini::IniFile::parse(ini_text, "m.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  kin::register_kinematics_components(registry);
  motion::register_components(registry, [](const tp::PlannerConfig& c) {
    return std::make_unique<cnc::testing::SimplePlanner>(c);
  });
  hal::CommandInterpreter interp(hal, registry, &ini, nullptr);
  try {
    for (const auto& l : hal_lines) interp.execute(l);
    for (hal::Component* c : hal.components()) c->on_ready();
    auto* m = hal.find<motion::MotionComponent>("motmod");
    if (!m) return "no motmod";
    return "ok " + std::to_string(m->config().servo_period_s);
  } catch (const std::exception& e) {
    return e.what();
  }
}

const char* kAxes = "[AXIS_X]\n[AXIS_Y]\n[AXIS_Z]\n";

}  // namespace

TEST(MotionServoPeriod, ComesFromTheThreadThatRunsMotion) {
  const std::string r = start_motmod(kAxes, {"loadrt trivkins coordinates=XYZ", "loadrt threads name1=servo-thread period1=2000000",
                                             "loadrt motmod num_joints=3", "addf motion-controller servo-thread"});
  EXPECT_EQ(r, "ok " + std::to_string(0.002));
}

TEST(MotionServoPeriod, ConfiguredPeriodThatDiffersFromTheThreadIsRefused) {
  const std::string r =
      start_motmod(std::string("[EMCMOT]\nSERVO_PERIOD = 2000000\n") + kAxes,
                   {"loadrt trivkins coordinates=XYZ", "loadrt threads name1=servo-thread period1=1000000",
                    "loadrt motmod num_joints=3", "addf motion-controller servo-thread"});
  EXPECT_NE(r.find("m.ini:2: [EMCMOT]SERVO_PERIOD = 2000000 ns"), std::string::npos) << r;
  EXPECT_NE(r.find("servo-thread with a period of 1000000 ns"), std::string::npos) << r;
}

TEST(MotionServoPeriod, LoadrtPeriodThatDiffersFromTheIniIsRefused) {
  const std::string r = start_motmod(std::string("[EMCMOT]\nSERVO_PERIOD = 2000000\n") + kAxes,
                                     {"loadrt trivkins coordinates=XYZ", "loadrt motmod servo_period_nsec=1000000 num_joints=3"});
  EXPECT_NE(r.find("servo_period_nsec=1000000 differs from m.ini:2: [EMCMOT]SERVO_PERIOD = 2000000 ns"), std::string::npos)
      << r;
}
