#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/hal/commands.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;

namespace {
class Counter : public Component {
 public:
  explicit Counter(Hal& hal) : Component(hal, "counter") {
    out = make_pin<uint32_t>("counter.out", PinDir::Out);
    export_method<&Counter::update>("counter.update", this);
  }
  void update(const cnc::rt::CycleInfo&) noexcept { out.set(out.get() + 1); }
  U32Pin out;
};
}  // namespace

TEST(HalThread, FunctionsRunInOrderAndAreTimed) {
  Hal hal;
  ComponentRegistry reg;
  register_core_components(reg);
  CommandInterpreter interp(hal, reg, nullptr, nullptr);
  hal.add_component(std::make_unique<Counter>(hal));
  interp.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt not count=2\n"
      "net a not.0.out => not.1.in\n"
      "addf not.1 servo-thread\n"
      "addf not.0 servo-thread\n"
      "addf counter.update servo-thread\n",
      "t.hal");
  Thread* t = hal.find_thread("servo-thread");
  ASSERT_NE(t, nullptr);
  cnc::rt::CycleInfo info;
  info.period_ns = 1'000'000;
  t->run_cycle(info);
  // not.1 ran before not.0 wrote its first TRUE: it saw the initial FALSE.
  EXPECT_EQ(hal.get_value("not.1.out"), "TRUE");
  EXPECT_EQ(hal.get_value("counter.out"), "1");
  EXPECT_GE(std::stoll(hal.get_value("counter.update.tmax")), 0);
  interp.execute("delf counter.update servo-thread");
  t->run_cycle(info);
  EXPECT_EQ(hal.get_value("counter.out"), "1");
  EXPECT_THROW(interp.execute("delf counter.update servo-thread"), HalError);
  EXPECT_THROW(interp.execute("addf not.0 servo-thread"), HalError) << "already in the thread";
}

TEST(HalThread, ServoCycleDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  Hal hal;
  ComponentRegistry reg;
  register_core_components(reg);
  CommandInterpreter interp(hal, reg, nullptr, nullptr);
  interp.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt and2 count=4\nloadrt or2\nloadrt not\nloadrt mux2\nloadrt sum2\nloadrt scale\nloadrt lowpass\n"
      "loadrt ddt\nloadrt estop_latch\nloadrt siggen\nloadrt xor2\n"
      "net s siggen.0.sine => ddt.0.in scale.0.in lowpass.0.in mux2.0.in0 sum2.0.in0\n"
      "net c siggen.0.clock => and2.0.in0 or2.0.in0 not.0.in xor2.0.in0 estop-latch.0.reset mux2.0.sel\n",
      "t.hal");
  for (const char* f : {"siggen.0.update", "and2.0", "and2.1", "and2.2", "and2.3", "or2.0", "not.0", "mux2.0", "sum2.0",
                        "scale.0", "lowpass.0", "ddt.0", "estop-latch.0", "xor2.0"}) {
    hal.add_function(f, "servo-thread");
  }
  Thread* t = hal.find_thread("servo-thread");
  cnc::rt::CycleInfo info;
  info.period_ns = info.actual_period_ns = 1'000'000;
  cnc::testing::ScopedAllocationCheck check;
  for (int i = 0; i < 20000; ++i) {
    info.cycle = static_cast<uint64_t>(i);
    t->run_cycle(info);
  }
  EXPECT_EQ(check.allocations(), 0u);
  EXPECT_NE(hal.get_value("ddt.0.out"), "0") << "the functions really ran";
}

TEST(HalThread, AddfWhileRunningIsSafe) {
  Hal hal;
  ComponentRegistry reg;
  register_core_components(reg);
  CommandInterpreter interp(hal, reg, nullptr, nullptr);
  hal.add_component(std::make_unique<Counter>(hal));
  interp.run_text("loadrt threads name1=servo-thread period1=100000\nloadrt not count=8\n", "t.hal");
  hal.add_function("counter.update", "servo-thread");
  hal.start_threads();
  for (int round = 0; round < 50; ++round) {
    for (int i = 0; i < 8; ++i) hal.add_function("not." + std::to_string(i), "servo-thread");
    for (int i = 0; i < 8; ++i) hal.remove_function("not." + std::to_string(i), "servo-thread");
  }
  // Liveness, not timing: wait (up to 10 s on a loaded machine) for cycles.
  for (int i = 0; i < 1000 && std::stoul(hal.get_value("counter.out")) <= 10; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  hal.stop_threads();
  EXPECT_GT(std::stoul(hal.get_value("counter.out")), 10u);
  EXPECT_EQ(hal.thread_views()[0].functions.size(), 1u);
}

// A function keeps state between calls: two threads must never call it.
TEST(HalThread, AFunctionRunsInOneThreadOnly) {
  Hal hal;
  ComponentRegistry reg;
  register_core_components(reg);
  CommandInterpreter interp(hal, reg, nullptr, nullptr);
  hal.add_component(std::make_unique<Counter>(hal));
  interp.run_text(
      "loadrt threads name1=servo-thread period1=1000000 name2=slow-thread period2=10000000\n"
      "addf counter.update servo-thread\n",
      "t.hal");
  try {
    interp.execute("addf counter.update slow-thread");
    FAIL() << "a function was added to a second thread";
  } catch (const HalError& e) {
    EXPECT_STREQ(e.what(),
                 "function counter.update is already in thread servo-thread; a function runs in one thread only "
                 "(delf it there first)");
  }
  interp.execute("delf counter.update servo-thread");
  interp.execute("addf counter.update slow-thread");  // moved: fine
}
