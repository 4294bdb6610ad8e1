#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "core/rt/periodic_task.hpp"

using namespace cnc::rt;

TEST(PeriodicTask, CallsBackEveryPeriodWithMeasuredPeriod) {
  PeriodicTask task;
  struct Ctx {
    std::atomic<uint64_t> calls{0};
    std::atomic<int64_t> last_period{0};
    std::atomic<uint64_t> last_cycle{0};
  } ctx;
  ASSERT_TRUE(task.start({"test-thread", 1'000'000, -1},
                         [](void* arg, const CycleInfo& info) {
                           auto* c = static_cast<Ctx*>(arg);
                           c->calls.fetch_add(1);
                           c->last_period = info.actual_period_ns;
                           c->last_cycle = info.cycle;
                           EXPECT_EQ(info.period_ns, 1'000'000);
                         },
                         &ctx));
  EXPECT_FALSE(task.start({"x", 1'000'000, -1}, [](void*, const CycleInfo&) {}, nullptr)) << "already running";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  task.stop();
  EXPECT_FALSE(task.is_running());
  const auto calls = ctx.calls.load();
  EXPECT_GT(calls, 10u);
  EXPECT_EQ(ctx.last_cycle.load() + 1, calls) << "cycle counts from 0 without gaps";
  const auto s = task.stats().snapshot();
  EXPECT_EQ(s.cycles, calls);
  EXPECT_GT(ctx.last_period.load(), 0);
  EXPECT_GE(s.latency_max_ns, s.latency_min_ns);
  uint64_t in_hist = 0;
  for (auto c : s.latency_histogram) in_hist += c;
  EXPECT_EQ(in_hist, calls);
}

TEST(PeriodicTask, OverrunsAreCountedAndTheGridIsRejoined) {
  PeriodicTask task;
  ASSERT_TRUE(task.start({"slow", 200'000, -1},
                         [](void*, const CycleInfo& info) {
                           if (info.cycle % 10 == 5) std::this_thread::sleep_for(std::chrono::microseconds(900));
                         },
                         nullptr));
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  task.stop();
  const auto s = task.stats().snapshot();
  EXPECT_GT(s.overruns, 0u);
  EXPECT_LT(s.overruns, s.cycles);
}

TEST(TimingSnapshot, PercentilesFromHistogram) {
  TimingSnapshot s;
  s.latency_histogram[3] = 50;   // 3..4 us
  s.latency_histogram[10] = 49;  // 10..11 us
  s.latency_histogram[200] = 1;  // 200..201 us
  s.latency_max_ns = 200'500;
  EXPECT_EQ(s.latency_percentile_ns(0.5), 11'000);
  EXPECT_EQ(s.latency_percentile_ns(0.25), 4'000);
  EXPECT_EQ(s.latency_percentile_ns(1.0), 200'500);
}

TEST(EndCycle, CycleEndingByTheNextSlotIsOnTimeAndMissesNothing) {
  const CycleEnd e = end_cycle(10'000'000, 10'999'000, 1'000'000);
  EXPECT_FALSE(e.overran);
  EXPECT_EQ(e.missed, 0);
  EXPECT_EQ(e.next_ns, 11'000'000);
  EXPECT_FALSE(end_cycle(10'000'000, 11'000'000, 1'000'000).overran) << "ending exactly at the deadline is on time";
}

TEST(EndCycle, OverrunSkipsTheSlotsItRanIntoAndRejoinsTheGrid) {
  // Ended 0.2 periods after its deadline: the slot at 11 ms gets no cycle.
  const CycleEnd e = end_cycle(10'000'000, 11'200'000, 1'000'000);
  EXPECT_TRUE(e.overran);
  EXPECT_EQ(e.missed, 1);
  EXPECT_EQ(e.next_ns, 12'000'000);
  const CycleEnd f = end_cycle(10'000'000, 13'500'000, 1'000'000);
  EXPECT_EQ(f.missed, 3);
  EXPECT_EQ(f.next_ns, 14'000'000);
}

TEST(EndCycle, StallOfTwoSecondsIsOneOverrunThatMissesTwoThousandCycles) {
  // SIGSTOP while asleep: the cycle of the 10 ms slot wakes 2 s late and runs 30 us.
  const CycleEnd e = end_cycle(10'000'000, 2'010'030'000, 1'000'000);
  EXPECT_TRUE(e.overran);
  EXPECT_EQ(e.missed, 2000);
  EXPECT_EQ(e.next_ns, 2'011'000'000);
}

TEST(TimingStats, StreakCountsConsecutiveOverrunsAndEndsWithACycleOnTime) {
  TimingStats st;
  st.reset(1'000'000);
  const CycleEnd on_time{false, 0, 0};
  const CycleEnd over{true, 1, 0};
  const CycleEnd stall{true, 2000, 0};
  for (const CycleEnd& e : {over, over, on_time, over, over, over, stall, on_time, on_time}) st.record_cycle_end(e);
  const TimingSnapshot s = st.snapshot();
  EXPECT_EQ(s.overruns, 6u);
  EXPECT_EQ(s.missed_cycles, 2005u);
  EXPECT_EQ(s.longest_streak, 4u);
  EXPECT_EQ(s.overrun_streak, 0u);
  EXPECT_EQ(s.longest_gap, 2000);
  st.record_cycle_end(over);
  EXPECT_EQ(st.overrun_streak(), 1u);
}

TEST(PeriodicTask, CycleAfterAnOverrunIsToldTheStreakAndTheCyclesMissed) {
  PeriodicTask task;
  struct Ctx {
    std::atomic<int64_t> missed{0};
    std::atomic<uint32_t> streak{0};
    std::atomic<bool> overran{false};
  } ctx;
  ASSERT_TRUE(task.start({"told", 200'000, -1},
                         [](void* arg, const CycleInfo& info) {
                           auto* c = static_cast<Ctx*>(arg);
                           if (c->overran.load()) {
                             if (info.missed_cycles > c->missed.load()) c->missed = info.missed_cycles;
                             if (info.overrun_streak > c->streak.load()) c->streak = info.overrun_streak;
                           }
                           // Sleeps through at least 4 slots of 200 us, once.
                           if (info.cycle == 5) {
                             std::this_thread::sleep_for(std::chrono::microseconds(1000));
                             c->overran = true;
                           }
                         },
                         &ctx));
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  task.stop();
  EXPECT_GE(ctx.missed.load(), 4);
  EXPECT_GE(ctx.streak.load(), 1u);
  const auto s = task.stats().snapshot();
  EXPECT_GE(s.missed_cycles, 4u);
  EXPECT_GE(s.longest_gap, 4);
  EXPECT_GE(s.missed_cycles, s.overruns) << "every overrun misses at least its next slot";
}
