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
