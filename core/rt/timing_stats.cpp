#include "core/rt/timing_stats.hpp"

namespace cnc::rt {
namespace {
void store_max(std::atomic<int64_t>& a, int64_t v) {
  if (v > a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}
void store_min(std::atomic<int64_t>& a, int64_t v) {
  if (v < a.load(std::memory_order_relaxed)) a.store(v, std::memory_order_relaxed);
}
}  // namespace

void TimingStats::reset(int64_t period_ns) noexcept {
  period_ns_.store(period_ns, std::memory_order_relaxed);
  cycles_.store(0, std::memory_order_relaxed);
  overruns_.store(0, std::memory_order_relaxed);
  missed_.store(0, std::memory_order_relaxed);
  streak_.store(0, std::memory_order_relaxed);
  longest_streak_.store(0, std::memory_order_relaxed);
  longest_gap_.store(0, std::memory_order_relaxed);
  reset_maxima();
  for (auto& b : hist_) b.store(0, std::memory_order_relaxed);
}

void TimingStats::reset_maxima() noexcept {
  latency_min_.store(std::numeric_limits<int64_t>::max(), std::memory_order_relaxed);
  latency_max_.store(0, std::memory_order_relaxed);
  period_min_.store(std::numeric_limits<int64_t>::max(), std::memory_order_relaxed);
  period_max_.store(0, std::memory_order_relaxed);
  exec_max_.store(0, std::memory_order_relaxed);
}

void TimingStats::record_wake(int64_t latency_ns, int64_t actual_period_ns, bool first) noexcept {
  cycles_.fetch_add(1, std::memory_order_relaxed);
  store_min(latency_min_, latency_ns);
  store_max(latency_max_, latency_ns);
  if (!first) {
    store_min(period_min_, actual_period_ns);
    store_max(period_max_, actual_period_ns);
  }
  int64_t bucket = latency_ns < 0 ? 0 : latency_ns / kHistogramBucketNs;
  if (bucket >= kHistogramBuckets) bucket = kHistogramBuckets - 1;
  hist_[static_cast<std::size_t>(bucket)].fetch_add(1, std::memory_order_relaxed);
}

void TimingStats::record_exec(int64_t exec_ns) noexcept {
  exec_last_.store(exec_ns, std::memory_order_relaxed);
  store_max(exec_max_, exec_ns);
}

void TimingStats::record_cycle_end(const CycleEnd& end) noexcept {
  if (!end.overran) {
    streak_.store(0, std::memory_order_relaxed);
    return;
  }
  overruns_.fetch_add(1, std::memory_order_relaxed);
  missed_.fetch_add(static_cast<uint64_t>(end.missed), std::memory_order_relaxed);
  const uint32_t streak = streak_.load(std::memory_order_relaxed) + 1;
  streak_.store(streak, std::memory_order_relaxed);
  if (streak > longest_streak_.load(std::memory_order_relaxed)) longest_streak_.store(streak, std::memory_order_relaxed);
  store_max(longest_gap_, end.missed);
}

TimingSnapshot TimingStats::snapshot() const noexcept {
  TimingSnapshot s;
  s.cycles = cycles_.load(std::memory_order_relaxed);
  s.overruns = overruns_.load(std::memory_order_relaxed);
  s.missed_cycles = missed_.load(std::memory_order_relaxed);
  s.overrun_streak = streak_.load(std::memory_order_relaxed);
  s.longest_streak = longest_streak_.load(std::memory_order_relaxed);
  s.longest_gap = longest_gap_.load(std::memory_order_relaxed);
  s.period_ns = period_ns_.load(std::memory_order_relaxed);
  const int64_t lmin = latency_min_.load(std::memory_order_relaxed);
  s.latency_min_ns = lmin == std::numeric_limits<int64_t>::max() ? 0 : lmin;
  s.latency_max_ns = latency_max_.load(std::memory_order_relaxed);
  const int64_t pmin = period_min_.load(std::memory_order_relaxed);
  s.actual_period_min_ns = pmin == std::numeric_limits<int64_t>::max() ? 0 : pmin;
  s.actual_period_max_ns = period_max_.load(std::memory_order_relaxed);
  s.exec_last_ns = exec_last_.load(std::memory_order_relaxed);
  s.exec_max_ns = exec_max_.load(std::memory_order_relaxed);
  for (std::size_t i = 0; i < hist_.size(); ++i) s.latency_histogram[i] = hist_[i].load(std::memory_order_relaxed);
  return s;
}

int64_t TimingSnapshot::latency_percentile_ns(double q) const {
  uint64_t total = 0;
  for (uint32_t c : latency_histogram) total += c;
  if (total == 0) return 0;
  const auto target = static_cast<uint64_t>(q * static_cast<double>(total));
  uint64_t acc = 0;
  for (std::size_t i = 0; i < latency_histogram.size(); ++i) {
    acc += latency_histogram[i];
    if (acc > target || acc == total) {
      const int64_t edge = static_cast<int64_t>(i + 1) * kHistogramBucketNs;
      return edge < latency_max_ns ? edge : latency_max_ns;
    }
  }
  return latency_max_ns;
}

}  // namespace cnc::rt
