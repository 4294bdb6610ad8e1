// The position latch (core/hal/latch.cpp): where each edge of a bit input
// happened, in the servo cycle, in both directions of travel.
#include <gtest/gtest.h>

#include <string>

#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/hal/hal.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;

namespace {

// A servo thread run by hand, a latch fed by two pins of the test
// (a switch at [lo, hi] on an axis the test moves one cycle at a time).
struct Bench {
  Hal hal;
  ComponentRegistry registry;
  CommandInterpreter interp{hal, registry, nullptr, nullptr};
  cnc::rt::CycleInfo info;
  double lo = 10.0, hi = 14.0;
  Bench() {
    register_core_components(registry);
    interp.run_text(
        "loadrt threads name1=t period1=1000000\nloadrt latch names=sw\naddf sw t\n"
        "newcomp axis\nnewpin axis axis.pos float out\nnewpin axis axis.sw bit out\n"
        "net pos axis.pos => sw.position\nnet sw axis.sw => sw.in\n",
        "bench.hal");
    info.period_ns = info.actual_period_ns = 1'000'000;
  }
  // One servo cycle with the axis at `x`.
  void at(double x) {
    hal.set_owned_pin("axis.pos", std::to_string(x), [](const Component*) { return true; });
    hal.set_owned_pin("axis.sw", x >= lo && x <= hi ? "1" : "0", [](const Component*) { return true; });
    hal.find_thread("t")->run_cycle(info);
    ++info.cycle;
  }
  // Moves from `from` to `to` by `step` a cycle.
  void move(double from, double to, double step) {
    const double s = to > from ? step : -step;
    for (double x = from; s > 0 ? x <= to : x >= to; x += s) at(x);
  }
  double num(const std::string& pin) const { return std::stod(hal.get_value(pin)); }
  int count(const std::string& pin) const { return std::stoi(hal.get_value(pin)); }
  bool bit(const std::string& pin) const {
    const std::string v = hal.get_value(pin);
    return v == "TRUE" || v == "1";
  }
};

}  // namespace

TEST(Latch, EachEdgeIsLatchedHalfwayBetweenTheCyclesAroundIt) {
  Bench b;
  b.move(0.0, 20.0, 0.01);  // 10 mm/s at 1 ms: 0.01 mm a cycle
  EXPECT_EQ(b.count("sw.rise-count"), 1);
  EXPECT_EQ(b.count("sw.fall-count"), 1);
  EXPECT_NEAR(b.num("sw.rise-position"), 10.0, 0.005 + 1e-6);
  EXPECT_NEAR(b.num("sw.fall-position"), 14.0, 0.005 + 1e-6);
  EXPECT_EQ(b.count("sw.rise-direction"), 1);
  EXPECT_EQ(b.count("sw.fall-direction"), 1);
  EXPECT_EQ(b.count("sw.last-edge"), -1);
}

TEST(Latch, MovingDownTheEdgesAreCrossedTheOtherWayRound) {
  Bench b;
  b.move(20.0, 0.0, 0.02);
  EXPECT_EQ(b.count("sw.rise-count"), 1);
  EXPECT_EQ(b.count("sw.fall-count"), 1);
  EXPECT_NEAR(b.num("sw.rise-position"), 14.0, 0.01 + 1e-6) << "entering from above: the upper edge rises";
  EXPECT_NEAR(b.num("sw.fall-position"), 10.0, 0.01 + 1e-6);
  EXPECT_EQ(b.count("sw.rise-direction"), -1);
  EXPECT_EQ(b.count("sw.fall-direction"), -1);
}

TEST(Latch, TheLastEdgeOfEachKindIsKeptAndEveryOneCounted) {
  Bench b;
  b.move(0.0, 20.0, 0.05);
  b.move(20.0, 12.0, 0.05);  // in again through the upper edge, and stop inside
  EXPECT_EQ(b.count("sw.rise-count"), 2);
  EXPECT_EQ(b.count("sw.fall-count"), 1);
  EXPECT_NEAR(b.num("sw.rise-position"), 14.0, 0.025 + 1e-6);
  EXPECT_EQ(b.count("sw.rise-direction"), -1);
  EXPECT_EQ(b.count("sw.last-edge"), 1);
}

TEST(Latch, AnInputTrueAtTheFirstCycleIsNotAnEdge) {
  Bench b;
  b.at(11.0);
  b.at(11.0);
  EXPECT_EQ(b.count("sw.rise-count"), 0);
  EXPECT_EQ(b.count("sw.last-edge"), 0);
  b.at(9.0);  // a jump: still halfway
  EXPECT_EQ(b.count("sw.fall-count"), 1);
  EXPECT_DOUBLE_EQ(b.num("sw.fall-position"), 10.0);
  b.at(9.0);
  b.at(9.0);
  EXPECT_EQ(b.count("sw.fall-count"), 1) << "no edge while the input holds";
}

TEST(Latch, AnInputAheadOfThePositionByACycleIsPlacedAfterTheCycleThatSawIt) {
  Bench b;
  b.hal.set_value("sw.input-lead-cycles", "1");
  // Each cycle's input is the one of the next cycle's position (a switch
  // at 10 seen at 9.75 moving 0.25 a cycle): it leads by a cycle.
  b.lo = 9.75;
  b.move(0.0, 12.0, 0.25);
  EXPECT_EQ(b.count("sw.rise-count"), 1);
  EXPECT_DOUBLE_EQ(b.num("sw.rise-position"), 9.875) << "between the positions 9.75 (it was seen) and 10 (the next)";
  b.hal.set_value("sw.input-lead-cycles", "0");
  b.move(12.0, 0.0, 0.25);
  EXPECT_DOUBLE_EQ(b.num("sw.fall-position"), 9.625) << "without the lead: between the cycle before (9.75) and the one that saw it (9.5)";
}

TEST(Latch, ArmedChangedTurnsTrueInTheCycleTheInputLeavesItsLevelAndHoldsUntilDisarmed) {
  Bench b;
  b.move(0.0, 5.0, 0.5);
  EXPECT_FALSE(b.bit("sw.changed")) << "not armed";
  b.hal.set_value("sw.arm", "1");
  b.move(5.0, 9.5, 0.5);
  EXPECT_FALSE(b.bit("sw.changed")) << "the input still at its level when armed";
  b.at(10.0);
  EXPECT_TRUE(b.bit("sw.changed")) << "the cycle the switch was reached";
  EXPECT_DOUBLE_EQ(b.num("sw.changed-position"), 9.75);
  b.at(9.0);  // off the switch again and on (a bounce): still changed, where it first did
  b.at(10.5);
  EXPECT_TRUE(b.bit("sw.changed"));
  EXPECT_DOUBLE_EQ(b.num("sw.changed-position"), 9.75);
  EXPECT_EQ(b.count("sw.rise-count"), 2);
  b.hal.set_value("sw.arm", "0");
  b.at(11.0);
  EXPECT_FALSE(b.bit("sw.changed")) << "disarmed";
  // Armed on the switch (a normally closed input reads so): leaving it counts.
  b.hal.set_value("sw.arm", "1");
  b.at(11.5);
  EXPECT_FALSE(b.bit("sw.changed"));
  b.at(14.5);
  EXPECT_TRUE(b.bit("sw.changed"));
  EXPECT_DOUBLE_EQ(b.num("sw.changed-position"), 13.0) << "halfway between 11.5 and 14.5";
}

TEST(Latch, ServoCycleDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  Bench b;
  b.at(0.0);
  // The pins are set through the HAL (which may allocate for the text):
  // only the thread's cycles are counted.
  Thread* t = b.hal.find_thread("t");
  auto* sw = b.hal.find_pin("axis.sw");
  ASSERT_NE(sw, nullptr);
  int toggles = 0;
  cnc::testing::ScopedAllocationCheck check;
  for (int i = 0; i < 20000; ++i) {
    if (i % 100 == 0) {
      sw->cell.load()->set_raw((++toggles) & 1);
    }
    t->run_cycle(b.info);
  }
  EXPECT_EQ(check.allocations(), 0u);
  EXPECT_EQ(b.count("sw.rise-count"), 100) << "the function really ran";
}
