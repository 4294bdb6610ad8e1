#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/motion/free_planner.hpp"

using namespace cnc::motion;

namespace {
struct Trace {
  double max_v = 0, max_a = 0, max_j = 0;
  double overshoot = 0;
  int cycles = 0;
};

// Runs until done (or max cycles), checking limits with finite differences.
Trace run(FreePlanner& fp, double dt, int max_cycles, double start_target) {
  Trace t;
  double p0 = fp.position(), v0 = fp.velocity(), a0 = fp.acceleration();
  const double dir = start_target >= fp.position() ? 1 : -1;
  for (; t.cycles < max_cycles && !fp.done(); ++t.cycles) {
    fp.update(dt);
    const double v = fp.velocity(), a = fp.acceleration();
    t.max_v = std::max(t.max_v, std::fabs(v));
    t.max_a = std::max(t.max_a, std::fabs(a));
    t.max_j = std::max(t.max_j, std::fabs(a - a0) / dt);
    t.overshoot = std::max(t.overshoot, (fp.position() - start_target) * dir);
    p0 = fp.position();
    v0 = v;
    a0 = a;
  }
  (void)p0;
  (void)v0;
  return t;
}
}  // namespace

TEST(FreePlanner, StoppingDistanceMatchesClosedForms) {
  // From rest: nothing to stop.
  EXPECT_DOUBLE_EQ(stopping_distance(0, 0, 1000, 50000), 0);
  // Without an acceleration plateau: v=1, A large: ap = sqrt(J v), distance = v * sqrt(v/J).
  EXPECT_NEAR(stopping_distance(1.0, 0, 1e9, 100.0), 1.0 * std::sqrt(1.0 / 100.0), 1e-12);
  // With a plateau: v=100, A=1000, J=1e9 (almost trapezoidal): ~ v^2/(2A).
  EXPECT_NEAR(stopping_distance(100, 0, 1000, 1e12), 5.0, 1e-3);
  // Symmetric for negative velocity.
  EXPECT_DOUBLE_EQ(stopping_distance(-3, 0.5, 1000, 5e4), -stopping_distance(3, -0.5, 1000, 5e4));
}

TEST(FreePlanner, PointToPointRespectsLimitsAndLandsExactly) {
  FreePlanner fp;
  fp.reset(0);
  const FreeLimits lim{100, 1000, 50000};
  fp.set_target(50, lim);
  const Trace t = run(fp, 0.001, 100000, 50);
  EXPECT_TRUE(fp.done());
  EXPECT_EQ(fp.position(), 50.0);
  EXPECT_LE(t.max_v, 100 + 1e-9);
  EXPECT_LE(t.max_a, 1000 + 1e-9);
  EXPECT_LE(t.max_j, 50000 * (1 + 1e-9));
  EXPECT_LE(t.overshoot, 1e-9);
  EXPECT_NEAR(t.max_v, 100, 1e-6) << "cruises at the velocity limit";
  // Near time-optimal: 0.5 s cruise + 0.1 s accel + 0.02 s jerk ramps ~ 0.62 s.
  EXPECT_LT(t.cycles, 700);
}

TEST(FreePlanner, RandomRetargetsNeverBreakLimits) {
  const unsigned seed = 12345;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-200, 200), vel(5, 300), acc(100, 5000), jerk(1000, 500000);
  for (int trial = 0; trial < 300; ++trial) {
    FreePlanner fp;
    fp.reset(pos(rng));
    const FreeLimits lim{vel(rng), acc(rng), jerk(rng)};
    double a_prev = 0;
    for (int k = 0; k < 6; ++k) {
      const double target = pos(rng);
      fp.set_target(target, lim);
      const int cycles = k < 5 ? static_cast<int>(rng() % 400) : 200000;
      for (int c = 0; c < cycles && !fp.done(); ++c) {
        fp.update(0.001);
        ASSERT_LE(std::fabs(fp.velocity()), lim.max_velocity * (1 + 1e-9)) << "seed " << seed << " trial " << trial;
        ASSERT_LE(std::fabs(fp.acceleration()), lim.max_acceleration * (1 + 1e-9)) << "seed " << seed;
        ASSERT_LE(std::fabs(fp.acceleration() - a_prev), lim.max_jerk * 0.001 * (1 + 1e-9)) << "seed " << seed;
        a_prev = fp.acceleration();
      }
    }
    EXPECT_TRUE(fp.done()) << "seed " << seed << " trial " << trial;
    EXPECT_EQ(fp.position(), fp.target());
  }
}

TEST(FreePlanner, PointToPointMovesAreMonotone) {
  // A move from rest never steps backwards (backlash compensation reads the
  // direction of every step).
  const unsigned seed = 777;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> dist(-50, 50), vel(1, 200), acc(50, 5000), jerk(500, 1e6);
  for (int trial = 0; trial < 500; ++trial) {
    FreePlanner fp;
    fp.reset(0);
    const double target = dist(rng);
    fp.set_target(target, {vel(rng), acc(rng), jerk(rng)});
    double prev = 0;
    for (int c = 0; c < 200000 && !fp.done(); ++c) {
      fp.update(0.001);
      ASSERT_GE((fp.position() - prev) * (target > 0 ? 1 : -1), 0) << "seed " << seed << " trial " << trial << " cycle " << c;
      prev = fp.position();
    }
    ASSERT_TRUE(fp.done()) << "seed " << seed << " trial " << trial;
    ASSERT_EQ(fp.position(), target);
  }
}

TEST(FreePlanner, StopBrakesWithinTheLimits) {
  FreePlanner fp;
  fp.reset(0);
  const FreeLimits lim{100, 1000, 50000};
  fp.set_target(1e6, lim);  // continuous jog
  for (int i = 0; i < 500; ++i) fp.update(0.001);
  const double v = fp.velocity();
  EXPECT_NEAR(v, 100, 1e-9);
  const double expected = fp.position() + stopping_distance(v, fp.acceleration(), 1000, 50000);
  fp.stop();
  const Trace t = run(fp, 0.001, 100000, fp.target());
  EXPECT_TRUE(fp.done());
  EXPECT_NEAR(fp.position(), expected, 1e-9);
  EXPECT_LE(t.max_a, 1000 + 1e-9);
}

TEST(FreePlanner, LoweredVelocityLimitDeceleratesSmoothly) {
  FreePlanner fp;
  fp.reset(0);
  fp.set_target(1000, {100, 1000, 50000});
  for (int i = 0; i < 400; ++i) fp.update(0.001);
  fp.set_target(1000, {20, 1000, 50000});
  double a_prev = fp.acceleration();
  for (int i = 0; i < 400; ++i) {
    fp.update(0.001);
    ASSERT_LE(std::fabs(fp.acceleration() - a_prev), 50000 * 0.001 * (1 + 1e-9));
    a_prev = fp.acceleration();
  }
  EXPECT_NEAR(fp.velocity(), 20, 1e-6);
}
