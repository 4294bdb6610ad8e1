// One joint's screw compensation: direction from the commanded velocity,
// kept at rest; tables handed over to the servo thread only at rest,
// without a lock, never torn; no allocation in the servo thread's path.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "comp/screw_compensation.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::comp;

namespace {

CompTable constant(double fwd, double rev, int entries = 3) {
  CompTable t;
  for (int i = 0; i < entries; ++i) {
    t.nominal.push_back(i * 10.0);
    t.forward.push_back(fwd);
    t.reverse.push_back(rev);
  }
  return t;
}

}  // namespace

TEST(ScrewCompensation, DirectionComesFromTheCommandedVelocityAndStaysAtRest) {
  ScrewCompensation c;
  CompTable t;
  t.nominal = {0, 100};
  t.forward = {0.010, 0.030};
  t.reverse = {-0.010, -0.030};
  c.install(t);
  double v = 0;
  ASSERT_TRUE(c.correction(50, 0, v));
  EXPECT_DOUBLE_EQ(v, 0.0) << "before any move: the mean of both trims";
  EXPECT_EQ(c.direction(), 0);
  ASSERT_TRUE(c.correction(50, 3.0, v));
  EXPECT_DOUBLE_EQ(v, 0.020);
  ASSERT_TRUE(c.correction(50, 0, v));
  EXPECT_DOUBLE_EQ(v, 0.020) << "at rest the last direction holds";
  ASSERT_TRUE(c.correction(25, -1e-12, v));
  EXPECT_DOUBLE_EQ(v, 0.015) << "rounding noise of a relabelled position is rest, not a reversal";
  ASSERT_TRUE(c.correction(25, -1e-6, v));
  EXPECT_DOUBLE_EQ(v, -0.015);
  EXPECT_EQ(c.direction(), -1);
  ASSERT_TRUE(c.correction(25, 0, v));
  EXPECT_DOUBLE_EQ(v, -0.015);
}

TEST(ScrewCompensation, WithoutATableTheControllerKeepsBacklash) {
  ScrewCompensation c;
  double v = 123;
  EXPECT_FALSE(c.correction(1, 1, v));
  EXPECT_EQ(c.entries(), 0u);
  c.install(constant(0.001, -0.001));
  EXPECT_TRUE(c.correction(1, 1, v));
  EXPECT_EQ(c.entries(), 3u);
}

TEST(ScrewCompensation, ANewTableIsTakenOnlyWhileTheJointIsAtRest) {
  ScrewCompensation c;
  c.install(constant(0.001, -0.001));
  c.offer(constant(0.005, -0.005, 7));
  EXPECT_TRUE(c.offer_pending());
  double v = 0;
  c.correction(5, 2.0, v);
  EXPECT_DOUBLE_EQ(v, 0.001) << "moving: the old table";
  EXPECT_TRUE(c.offer_pending());
  EXPECT_EQ(c.switches(), 0u);
  c.correction(5, 0.0, v);
  EXPECT_DOUBLE_EQ(v, 0.005) << "at rest: switched at the start of the cycle";
  EXPECT_FALSE(c.offer_pending());
  EXPECT_EQ(c.switches(), 1u);
  EXPECT_EQ(c.entries(), 7u);
}

TEST(ScrewCompensation, AnOfferNotTakenCanBeWithdrawnOrReplaced) {
  ScrewCompensation c;
  c.install(constant(0.001, -0.001));
  c.offer(constant(0.002, -0.002));
  EXPECT_TRUE(c.withdraw());
  EXPECT_FALSE(c.withdraw());
  double v = 0;
  c.correction(5, 0, v);
  EXPECT_DOUBLE_EQ(v, 0.0) << "mean of the old table";
  c.offer(constant(0.002, -0.002));
  c.offer(constant(0.004, -0.004));  // replaces the first offer
  c.correction(5, 1, v);
  c.correction(5, 0, v);
  EXPECT_DOUBLE_EQ(v, 0.004);
  EXPECT_EQ(c.switches(), 1u);
}

TEST(ScrewCompensation, HandOverWhileTheServoThreadRunsIsNeverTorn) {
  // Every table has one value everywhere; the servo thread must only ever
  // see one of the values offered, each table whole.
  ScrewCompensation c;
  c.install(constant(0.0, 0.0, 64));
  std::atomic<bool> stop{false};
  std::atomic<long> bad{0}, calls{0};
  std::thread servo([&] {
    long k = 0;
    while (!stop.load(std::memory_order_relaxed)) {
      double v = -1;
      const double vel = (k++ % 3 == 0) ? 0.0 : 1.0;
      if (!c.correction(static_cast<double>(k % 640), vel, v)) ++bad;
      const double scaled = v * 1e6;
      if (std::fabs(scaled - std::round(scaled)) > 1e-6 || scaled < 0 || scaled > 400) ++bad;
      calls.fetch_add(1, std::memory_order_relaxed);
    }
  });
  uint64_t withdrawn = 0;
  for (int i = 1; i <= 400; ++i) {
    const double value = i * 1e-6;
    c.offer(constant(value, value, 64 + i % 7));
    if (i % 5 == 0 && c.withdraw()) ++withdrawn;
    while (c.offer_pending()) std::this_thread::yield();  // the servo thread takes it at its next rest
  }
  stop = true;
  servo.join();
  EXPECT_EQ(bad.load(), 0);
  EXPECT_GT(calls.load(), 0);
  EXPECT_EQ(c.switches() + withdrawn, 400u) << "every offer was taken or withdrawn, none lost";
}

TEST(ScrewCompensation, TheServoThreadPathDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter not available";
  ScrewCompensation c;
  CompTable big;
  for (int i = 0; i < 5000; ++i) {
    big.nominal.push_back(i * 0.1);
    big.forward.push_back(1e-5 * i);
    big.reverse.push_back(-1e-5 * i);
  }
  c.install(big);
  c.offer(constant(0.003, -0.003));
  double sum = 0;
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 100000; ++i) {
      double v = 0;
      c.correction((i % 6000) * 0.0833, (i / 50) % 2 ? 1.0 : (i % 7 == 0 ? 0.0 : -1.0), v);
      sum += v;
    }
    EXPECT_EQ(check.allocations(), 0u);
  }
  EXPECT_EQ(c.switches(), 1u) << "the switch happened inside the checked loop";
  EXPECT_TRUE(std::isfinite(sum));
}
