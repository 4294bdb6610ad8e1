// Timing statistics of a periodic thread: wake-up latency and period
// histograms, extremes, overruns, execution time. Written by the thread
// itself with relaxed atomics (no allocation, no lock); read by anybody.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>

namespace cnc::rt {

// 1 us buckets up to 2 ms; the last bucket collects everything above.
inline constexpr int kHistogramBuckets = 2001;
inline constexpr int64_t kHistogramBucketNs = 1000;

struct TimingSnapshot {
  uint64_t cycles = 0;
  uint64_t overruns = 0;
  int64_t period_ns = 0;
  int64_t latency_min_ns = 0, latency_max_ns = 0;
  int64_t actual_period_min_ns = 0, actual_period_max_ns = 0;
  int64_t exec_last_ns = 0, exec_max_ns = 0;
  std::array<uint32_t, kHistogramBuckets> latency_histogram{};

  // Latency at quantile q in [0,1] from the histogram (bucket upper edge).
  int64_t latency_percentile_ns(double q) const;
};

class TimingStats {
 public:
  void reset(int64_t period_ns) noexcept;
  // Called by the thread once per cycle.
  void record_wake(int64_t latency_ns, int64_t actual_period_ns, bool first) noexcept;
  void record_exec(int64_t exec_ns) noexcept;
  void record_overrun() noexcept { overruns_.fetch_add(1, std::memory_order_relaxed); }
  // Forgets the maxima (halcmd "setp <thread>.tmax 0").
  void reset_maxima() noexcept;

  TimingSnapshot snapshot() const noexcept;
  uint64_t cycles() const noexcept { return cycles_.load(std::memory_order_relaxed); }
  uint64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }
  int64_t exec_last_ns() const noexcept { return exec_last_.load(std::memory_order_relaxed); }
  int64_t exec_max_ns() const noexcept { return exec_max_.load(std::memory_order_relaxed); }
  int64_t latency_max_ns() const noexcept { return latency_max_.load(std::memory_order_relaxed); }

 private:
  std::atomic<int64_t> period_ns_{0};
  std::atomic<uint64_t> cycles_{0};
  std::atomic<uint64_t> overruns_{0};
  std::atomic<int64_t> latency_min_{std::numeric_limits<int64_t>::max()};
  std::atomic<int64_t> latency_max_{0};
  std::atomic<int64_t> period_min_{std::numeric_limits<int64_t>::max()};
  std::atomic<int64_t> period_max_{0};
  std::atomic<int64_t> exec_last_{0};
  std::atomic<int64_t> exec_max_{0};
  std::array<std::atomic<uint32_t>, kHistogramBuckets> hist_{};
};

}  // namespace cnc::rt
