// The overrun account of a HAL thread, driven with synthetic cycle
// information (what the periodic task would tell) and a clock that the
// functions themselves advance: no real time is measured or asserted.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/hal/commands.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;

namespace {

int64_t g_now = 0;
int64_t fake_clock() noexcept { return g_now; }

// Functions that take the time the test gives them, and record what the
// thread told them.
class Workers : public Component {
 public:
  explicit Workers(Hal& hal) : Component(hal, "workers") {
    for (int i = 0; i < 3; ++i) {
      slots_[i].self = this;
      hal.export_function(
          this, "work." + std::to_string(i),
          [](void* arg, const cnc::rt::CycleInfo& info) {
            auto* s = static_cast<Slot*>(arg);
            g_now += s->cost_ns;
            s->self->last_is_late = info.is_late;
          },
          &slots_[i]);
    }
  }
  void set_cost(int i, int64_t ns) { slots_[i].cost_ns = ns; }
  bool last_is_late = false;

 private:
  struct Slot {
    Workers* self = nullptr;
    int64_t cost_ns = 10'000;
  };
  Slot slots_[3];
};

class HalThreadOverruns : public ::testing::Test {
 protected:
  void SetUp() override {
    g_now = 0;
    auto w = std::make_unique<Workers>(hal);
    workers = w.get();
    hal.add_component(std::move(w));
    thread = &hal.new_thread("servo-thread", 1'000'000);
    thread->set_clock(&fake_clock);
    for (int i = 0; i < 3; ++i) hal.add_function("work." + std::to_string(i), "servo-thread");
    info.period_ns = info.actual_period_ns = 1'000'000;
  }

  // One cycle that woke `latency_ns` late; `previous_overran` says what the
  // periodic task found about the cycle before (streak and missed slots).
  void cycle(int64_t latency_ns = 20'000) {
    info.now_ns += (1 + info.missed_cycles) * info.period_ns + latency_ns;
    info.wake_latency_ns = latency_ns;
    thread->run_cycle(info);
    ++info.cycle;
    info.missed_cycles = 0;
  }
  // Lets the quiet time between two overrun reports pass.
  void wait_quiet() { info.now_ns += Thread::kReportQuietNs; }
  // What the periodic task tells the next cycle after an overrun.
  void told_overrun(uint32_t streak, int64_t missed) {
    info.overrun_streak = streak;
    info.missed_cycles = missed;
  }
  void told_on_time() {
    info.overrun_streak = 0;
    info.missed_cycles = 0;
  }
  std::vector<OverrunEvent> events() {
    std::vector<OverrunEvent> out;
    OverrunEvent e;
    while (thread->poll_overrun_event(e)) out.push_back(e);
    return out;
  }
  uint32_t overruns(const std::string& f) { return static_cast<uint32_t>(std::stoul(hal.get_value(f + ".overruns"))); }

  Hal hal;
  Workers* workers = nullptr;
  Thread* thread = nullptr;
  cnc::rt::CycleInfo info;
};

}  // namespace

TEST_F(HalThreadOverruns, OverrunIsBlamedOnTheFunctionThatRanLongest) {
  workers->set_cost(1, 1'300'000);  // work.1 takes 1.3 ms of the 1 ms period
  cycle();
  told_overrun(1, 1);
  workers->set_cost(1, 10'000);
  cycle();
  EXPECT_EQ(overruns("work.0"), 0u);
  EXPECT_EQ(overruns("work.1"), 1u);
  EXPECT_EQ(overruns("work.2"), 0u);
  EXPECT_EQ(thread->late_wakes(), 0u);
  ASSERT_NE(thread->worst_function(), nullptr);
  EXPECT_EQ(thread->worst_function()->name, "work.1");
  EXPECT_EQ(thread->worst_function()->overrun_max_ns.load(), 1'300'000);
  EXPECT_TRUE(events().empty()) << "one overrun is below the limit of 3";
}

TEST_F(HalThreadOverruns, OverrunOfACycleThatWokeLateIsBlamedOnTheWakeUp) {
  cycle(/*latency_ns=*/990'000);  // functions ran 30 us: the late wake-up made it overrun
  told_overrun(1, 1);
  cycle();
  EXPECT_EQ(thread->late_wakes(), 1u);
  for (const char* f : {"work.0", "work.1", "work.2"}) EXPECT_EQ(overruns(f), 0u) << f;
  EXPECT_EQ(thread->worst_function(), nullptr);
}

TEST_F(HalThreadOverruns, StreakReachingTheLimitIsReportedOnceAndItsEndOnce) {
  workers->set_cost(2, 1'100'000);
  cycle();
  for (uint32_t n = 1; n <= 6; ++n) {
    told_overrun(n, 1);
    cycle();
  }
  told_on_time();
  workers->set_cost(2, 10'000);
  cycle();
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].kind, OverrunEvent::Kind::Streak);
  EXPECT_EQ(ev[0].streak, 3u);
  EXPECT_EQ(ev[0].missed_cycles, 3);
  ASSERT_NE(ev[0].function, nullptr);
  EXPECT_EQ(ev[0].function->name, "work.2");
  EXPECT_EQ(ev[0].function_ns, 1'100'000);
  EXPECT_EQ(ev[1].kind, OverrunEvent::Kind::Ended);
  EXPECT_EQ(ev[1].streak, 6u);
  EXPECT_EQ(ev[1].missed_cycles, 6);
  EXPECT_EQ(overruns("work.2"), 6u);
  EXPECT_EQ(describe(ev[0]),
            "3 consecutive overruns of the 1.000 ms period (3 periods missed); blamed on work.2, which ran 1.100 ms "
            "(the cycle woke 0.020 ms late)");
  EXPECT_EQ(describe(ev[1]), "on time again after 6 overrun cycles (6 periods missed)");
}

TEST_F(HalThreadOverruns, ShortStreaksBelowTheLimitAreNotReported) {
  workers->set_cost(0, 1'500'000);
  cycle();
  for (int round = 0; round < 10; ++round) {
    told_overrun(1, 1);
    cycle();
    told_overrun(2, 1);
    cycle();
    told_on_time();
    cycle();
  }
  EXPECT_TRUE(events().empty());
  EXPECT_EQ(overruns("work.0"), 20u);
}

TEST_F(HalThreadOverruns, StallIsReportedAsAGapWithTheCyclesMissedAndBlamedOnTheWakeUp) {
  cycle(/*latency_ns=*/2'000'000'000);  // SIGSTOP for 2 s while the thread slept
  told_overrun(1, 2000);
  cycle();
  told_on_time();
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 1u) << "a gap that is over at once needs no second message";
  EXPECT_EQ(ev[0].kind, OverrunEvent::Kind::Gap);
  EXPECT_EQ(ev[0].missed_cycles, 2000);
  EXPECT_EQ(ev[0].function, nullptr);
  EXPECT_EQ(describe(ev[0]),
            "no cycle for 2.000 s: 2000 periods of 1.000 ms missed at once; the thread woke 2.000 s late (the host or "
            "the scheduler, not a function)");
  EXPECT_EQ(thread->late_wakes(), 1u);
}

TEST_F(HalThreadOverruns, LaterSpellsWithinTheQuietTimeAreSummedUpInOneReport) {
  cycle(3'500'000);
  told_overrun(1, 3);
  cycle();
  told_on_time();
  cycle();
  ASSERT_EQ(events().size(), 1u) << "the first spell is reported at once";
  for (int i = 0; i < 20; ++i) {  // 20 more, within the quiet time, none twice as bad
    cycle(4'500'000);
    told_overrun(1, i == 7 ? 5 : 4);
    cycle();
    told_on_time();
    cycle();
  }
  EXPECT_TRUE(events().empty());
  wait_quiet();
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, OverrunEvent::Kind::Summary);
  EXPECT_EQ(ev[0].streak, 20u);
  EXPECT_EQ(ev[0].missed_cycles, 5);
  EXPECT_NE(describe(ev[0]).find("20 more late spells in the last 1"), std::string::npos) << describe(ev[0]);
  EXPECT_NE(describe(ev[0]).find("the worst missing 5 periods of 1.000 ms"), std::string::npos) << describe(ev[0]);
  wait_quiet();
  cycle();
  EXPECT_TRUE(events().empty()) << "nothing more to sum up";
  cycle(4'500'000);
  told_overrun(1, 4);
  cycle();
  EXPECT_EQ(events().size(), 1u) << "after a quiet time the next spell is reported at once";
}

TEST_F(HalThreadOverruns, SpellTwiceAsBadIsReportedWithinTheQuietTime) {
  cycle(3'500'000);
  told_overrun(1, 3);
  cycle();
  told_on_time();
  cycle();
  cycle(2'000'000'000);
  told_overrun(1, 2000);
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[1].kind, OverrunEvent::Kind::Gap);
  EXPECT_EQ(ev[1].missed_cycles, 2000);
}

TEST_F(HalThreadOverruns, StallDuringALateSpellIsReportedAsAGap) {
  // A loaded host: a streak of overruns is going on (reported) when the
  // process is stopped for 2 s. The stall is a new event, not more of the
  // streak, and must be said at once.
  workers->set_cost(1, 1'200'000);
  cycle();
  for (uint32_t n = 1; n <= 4; ++n) {
    told_overrun(n, 1);
    cycle();
  }
  cycle(2'000'000'000);
  told_overrun(5, 2000);
  cycle();
  workers->set_cost(1, 10'000);
  told_on_time();
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 3u);
  EXPECT_EQ(ev[0].kind, OverrunEvent::Kind::Streak);
  EXPECT_EQ(ev[1].kind, OverrunEvent::Kind::Gap);
  EXPECT_EQ(ev[1].missed_cycles, 2000);
  EXPECT_EQ(ev[1].function, nullptr) << "blamed on the late wake-up";
  EXPECT_EQ(ev[2].kind, OverrunEvent::Kind::Ended);
  EXPECT_EQ(ev[2].missed_cycles, 2004);
}

TEST_F(HalThreadOverruns, StallDuringAnUnreportedLateSpellIsReportedAsAGap) {
  // The first spell is reported; a second within the quiet time is only
  // counted; a stall during that one is still said at once.
  cycle(3'500'000);
  told_overrun(1, 3);
  cycle();
  told_on_time();
  cycle();
  ASSERT_EQ(events().size(), 1u);
  cycle(3'500'000);
  told_overrun(1, 3);
  cycle();
  EXPECT_TRUE(events().empty()) << "a second spell as bad within the quiet time is counted, not said";
  cycle(2'000'000'000);
  told_overrun(2, 2000);
  cycle();
  const auto ev = events();
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, OverrunEvent::Kind::Gap);
  EXPECT_EQ(ev[0].missed_cycles, 2000);
}

TEST_F(HalThreadOverruns, FunctionsSeeTheThreadLateFromTheLimitUntilACycleIsOnTime) {
  workers->set_cost(0, 1'200'000);
  cycle();
  told_overrun(1, 1);
  cycle();
  EXPECT_FALSE(workers->last_is_late);
  told_overrun(2, 1);
  cycle();
  EXPECT_FALSE(workers->last_is_late);
  told_overrun(3, 1);
  cycle();
  EXPECT_TRUE(workers->last_is_late);
  info.overrun_streak = 4;  // still overrunning
  info.missed_cycles = 1;
  cycle();
  EXPECT_TRUE(workers->last_is_late);
  told_on_time();
  cycle();
  EXPECT_FALSE(workers->last_is_late);
  // A gap of the limit's length at once is late at once.
  told_overrun(1, 3);
  cycle();
  EXPECT_TRUE(workers->last_is_late);
}

TEST_F(HalThreadOverruns, OverrunLimitComesFromTheHalForPresentAndLaterThreads) {
  hal.set_overrun_limit(5);
  EXPECT_EQ(thread->overrun_limit(), 5u);
  EXPECT_EQ(hal.new_thread("slow-thread", 10'000'000).overrun_limit(), 5u);
  workers->set_cost(0, 1'200'000);
  cycle();
  for (uint32_t n = 1; n <= 4; ++n) {
    told_overrun(n, 1);
    cycle();
  }
  EXPECT_TRUE(events().empty()) << "4 overruns are below the limit of 5";
  told_overrun(5, 1);
  cycle();
  EXPECT_EQ(events().size(), 1u);
}

TEST_F(HalThreadOverruns, ReportsAreDroppedAndCountedWhenNobodyReadsThem) {
  for (int i = 0; i < 40; ++i) {
    wait_quiet();
    cycle(5'500'000);
    told_overrun(1, 5);
    cycle();
    told_on_time();
    cycle();
  }
  ASSERT_EQ(events().size(), 16u) << "the report ring holds 16";
  wait_quiet();
  cycle(5'500'000);
  told_overrun(1, 5);
  cycle();
  const auto next = events();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].dropped_before, 24u);
  EXPECT_NE(describe(next[0]).find("24 earlier overrun reports lost"), std::string::npos) << describe(next[0]);
}

TEST_F(HalThreadOverruns, OverrunAccountingDoesNotAllocate) {
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  workers->set_cost(1, 1'200'000);
  OverrunEvent e;
  cnc::testing::ScopedAllocationCheck check;
  for (int i = 0; i < 20000; ++i) {
    const int phase = i % 10;
    if (phase < 6) told_overrun(static_cast<uint32_t>(phase + 1), phase == 4 ? 500 : 1);
    else told_on_time();
    if (i % 1000 == 0) wait_quiet();
    cycle(phase == 3 ? 1'000'000'000 : 20'000);
    if (i % 100 == 0) {
      while (thread->poll_overrun_event(e)) {
      }
    }
  }
  EXPECT_EQ(check.allocations(), 0u);
}

// A simulator in the servo thread (a component that marks itself as one):
// its functions' time is counted apart from the product's.
namespace {
class SimulatedPlant : public Component {
 public:
  explicit SimulatedPlant(Hal& hal) : Component(hal, "plant") {
    mark_as_simulation();
    hal.export_function(
        this, "plant.update", [](void*, const cnc::rt::CycleInfo&) { g_now += 70'000; }, nullptr);
  }
};
}  // namespace

TEST_F(HalThreadOverruns, SimulatorFunctionsAreTimedApartFromTheProducts) {
  hal.add_component(std::make_unique<SimulatedPlant>(hal));
  hal.add_function("plant.update", "servo-thread");
  workers->set_cost(0, 30'000);
  cycle();
  EXPECT_EQ(thread->simulation_exec_last_ns(), 70'000);
  EXPECT_EQ(thread->product_exec_last_ns(), 30'000 + 10'000 + 10'000);
  workers->set_cost(0, 10'000);
  cycle();
  EXPECT_EQ(thread->product_exec_last_ns(), 30'000);
  EXPECT_EQ(thread->product_exec_max_ns(), 50'000);
  EXPECT_EQ(thread->simulation_exec_max_ns(), 70'000);
}
