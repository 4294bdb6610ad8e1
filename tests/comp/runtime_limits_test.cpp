// The motion controller with screw tables attached: the motor command
// (joint command + backlash/table correction + home offset) never exceeds
// the joint's velocity or acceleration limit, over seeded random moves with
// reversals in flight, in free and in coordinated mode; at rest the
// correction is exactly the table's; the table applies once homed; the
// servo cycle does not allocate.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "comp/screw_compensation.hpp"
#include "tests/core/motion/machine.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::comp;
using motion::Cmd;

namespace {

// A hostile table: 0.2 mm reversal, slopes up to 2 % with kinks at every
// entry, a step-like wiggle; the limits must hold whatever the table holds.
CompTable hostile_table() {
  CompTable t;
  for (int i = 0; i <= 42; ++i) {
    const double x = -10 + i * 5.0;
    const double wave = 0.02 * std::sin(i * 1.7) + (i % 2 ? 0.05 : -0.05);
    t.nominal.push_back(x);
    t.forward.push_back(wave + 0.1);
    t.reverse.push_back(wave - 0.1);
  }
  return t;
}

// Watches the motor command of a joint: finite-difference velocity and
// acceleration over the servo period against the joint's limits.
struct LimitWatch {
  double dt, vmax, amax;
  double prev = 0, prev_v = 0;
  int samples = 0;
  double worst_v = 0, worst_a = 0;
  void add(double motor) {
    if (samples >= 1) {
      const double v = (motor - prev) / dt;
      worst_v = std::max(worst_v, std::fabs(v));
      if (samples >= 2) worst_a = std::max(worst_a, std::fabs(v - prev_v) / dt);
      prev_v = v;
    }
    prev = motor;
    ++samples;
  }
};

}  // namespace

TEST(CompensationLimits, RandomFreeMovesWithReversalsNeverExceedTheJointLimits) {
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    motion::MotionConfig cfg = cnc::testing::basic_config(1);
    cnc::testing::Machine m(cfg);
    ScrewCompensation comp;
    comp.install(hostile_table());
    m.mc().set_compensation(0, &comp);
    LimitWatch w{cfg.servo_period_s, cfg.joints[0].max_velocity, cfg.joints[0].max_acceleration};
    m.accept(Cmd::Enable);
    m.accept(Cmd::Home, 0);
    for (int i = 0; i < 3000 && !m.status().joints[0].homed; ++i) {
      m.step();
      w.add(m.joint(0).motor_pos_cmd);
    }
    ASSERT_TRUE(m.status().joints[0].homed);
    std::uniform_real_distribution<double> target(-9, 199), vel(0.5, 100), hold(0.0, 0.4);
    std::uniform_int_distribution<int> action(0, 9);
    for (int move = 0; move < 40; ++move) {
      const int a = action(rng);
      if (a == 0) m.accept(Cmd::JogStop, 0);
      else m.accept(Cmd::JogAbs, 0, vel(rng), target(rng));
      // Run a random while: often a reversal comes in flight.
      const int cycles = static_cast<int>(hold(rng) / cfg.servo_period_s) + 1;
      for (int k = 0; k < cycles; ++k) {
        m.step();
        w.add(m.joint(0).motor_pos_cmd);
      }
    }
    // Come to rest: the correction settles exactly on the table's value.
    m.accept(Cmd::JogStop, 0);
    for (int k = 0; k < 4000; ++k) {
      m.step();
      w.add(m.joint(0).motor_pos_cmd);
    }
    EXPECT_LE(w.worst_v, cfg.joints[0].max_velocity * (1 + 1e-9)) << "motor velocity";
    EXPECT_LE(w.worst_a, cfg.joints[0].max_acceleration * (1 + 1e-6)) << "motor acceleration";
    const auto& o = m.joint(0);
    double expected = 0;
    ASSERT_TRUE(comp.correction(o.pos_cmd, 0, expected));
    EXPECT_EQ(o.backlash_filt, expected) << "at rest the applied correction is the table's";
    EXPECT_NEAR(o.motor_pos_cmd, o.pos_cmd + expected + o.motor_offset, 1e-12);
    EXPECT_NEAR(o.pos_fb, m.sims[0].pos - expected - o.motor_offset, 1e-12) << "and it leaves the feedback";
  }
}

TEST(CompensationLimits, CoordinatedMovesAtFullSpeedStayWithinTheJointLimits) {
  // The planner may use the joint's whole velocity here (axis limit = joint
  // limit): the correction then only gets what is left, and still gets there.
  for (uint64_t seed = 1; seed <= 6; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    motion::MotionConfig cfg = cnc::testing::basic_config(3);
    cnc::testing::Machine m(cfg);
    ScrewCompensation comp[3];
    for (int j = 0; j < 3; ++j) {
      comp[j].install(hostile_table());
      m.mc().set_compensation(j, &comp[j]);
    }
    m.enable_home_coord();
    LimitWatch w[3];
    for (int j = 0; j < 3; ++j) w[j] = LimitWatch{cfg.servo_period_s, 100, 1000};
    std::uniform_real_distribution<double> pos(0, 190), feed(10, 100);
    for (int seg = 0; seg < 12; ++seg) {
      ASSERT_TRUE(m.line(pos(rng), pos(rng), pos(rng), feed(rng), seg + 1).accepted);
      for (int k = 0; k < 20000; ++k) {
        m.step();
        for (int j = 0; j < 3; ++j) w[j].add(m.joint(j).motor_pos_cmd);
        if (m.status().tp_done && k > 2) break;
      }
    }
    for (int k = 0; k < 3000; ++k) {
      m.step();
      for (int j = 0; j < 3; ++j) w[j].add(m.joint(j).motor_pos_cmd);
    }
    for (int j = 0; j < 3; ++j) {
      EXPECT_LE(w[j].worst_v, 100 * (1 + 1e-9)) << "joint " << j;
      EXPECT_LE(w[j].worst_a, 1000 * (1 + 1e-6)) << "joint " << j;
      double expected = 0;
      ASSERT_TRUE(comp[j].correction(m.joint(j).pos_cmd, 0, expected));
      EXPECT_EQ(m.joint(j).backlash_filt, expected) << "joint " << j << " settled on the table";
    }
  }
}

TEST(CompensationLimits, TheTableAppliesOnceHomedAndReplacesBacklash) {
  motion::MotionConfig cfg = cnc::testing::basic_config(1);
  cfg.joints[0].backlash = 0.3;
  cnc::testing::Machine m(cfg);
  ScrewCompensation comp;
  CompTable t;
  t.nominal = {0, 100};
  t.forward = {0.01, 0.01};
  t.reverse = {-0.01, -0.01};
  comp.install(t);
  m.mc().set_compensation(0, &comp);
  m.accept(Cmd::Enable);
  m.accept(Cmd::JogIncr, 0, 10, 1);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos && m.joint(0).backlash_filt == 0.15; }, 5000))
      << "not homed: BACKLASH as before (" << m.joint(0).backlash_filt << ")";
  m.accept(Cmd::Home, 0);
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; }, 5000));
  ASSERT_TRUE(m.run_until([&] { return m.joint(0).backlash_filt == 0.01; }, 5000))
      << "homed: the table's forward trim (" << m.joint(0).backlash_filt << ")";
  m.accept(Cmd::JogIncr, 0, 10, -1);
  ASSERT_TRUE(m.run_until([&] { return m.status().traj.inpos && m.joint(0).backlash_filt == -0.01; }, 5000));
  EXPECT_EQ(m.status().joints[0].compensation, -0.01);
}

TEST(CompensationLimits, TheServoCycleWithTablesDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter not available";
  motion::MotionConfig cfg = cnc::testing::basic_config(1);
  cnc::testing::Machine m(cfg);
  ScrewCompensation comp;
  comp.install(hostile_table());
  m.mc().set_compensation(0, &comp);
  m.accept(Cmd::Enable);
  m.accept(Cmd::Home, 0);
  ASSERT_TRUE(m.run_until([&] { return m.status().joints[0].homed; }, 5000));
  m.accept(Cmd::JogAbs, 0, 80, 150);
  comp.offer(hostile_table());
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int k = 0; k < 6000; ++k) {
      if (k == 1500) {
        motion::MotionCommand c;
        c.type = Cmd::JogAbs;
        c.value[0] = 60;
        c.value[1] = 20;
        motion::MotionResult r;
        m.mc().handle(c, r);
      }
      m.step();
    }
    EXPECT_EQ(check.allocations(), 0u);
  }
  EXPECT_EQ(comp.switches(), 1u);
}
