// Timing statistics of a periodic thread: wake-up latency and period
// histograms, extremes, execution time, overruns (streaks and missed
// cycles). Written by the thread itself with relaxed atomics (no
// allocation, no lock); read by anybody.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>

namespace cnc::rt {

// 1 us buckets up to 2 ms; the last bucket collects everything above.
inline constexpr int kHistogramBuckets = 2001;
inline constexpr int64_t kHistogramBucketNs = 1000;

// How a cycle ended with respect to the thread's grid of slots.
struct CycleEnd {
  bool overran = false;   // it ended after the next slot (its deadline)
  int64_t missed = 0;     // slots it ran into, which get no cycle (>= 1 when it overran)
  int64_t next_ns = 0;    // the slot the next cycle starts at
};

// The grid arithmetic of one cycle that started in the slot at `slot_ns`
// and ended at `done_ns`: on time when it ends by slot + period; otherwise
// the thread rejoins the grid at the first slot after `done_ns` instead of
// bursting through the slots it missed. A stall of 2 s at 1 ms (SIGSTOP, a
// stalled host) is one overrun with ~2000 missed slots.
constexpr CycleEnd end_cycle(int64_t slot_ns, int64_t done_ns, int64_t period_ns) noexcept {
  const int64_t deadline = slot_ns + period_ns;
  if (done_ns <= deadline) return {false, 0, deadline};
  const int64_t missed = (done_ns - deadline) / period_ns + 1;
  return {true, missed, deadline + missed * period_ns};
}

struct TimingSnapshot {
  uint64_t cycles = 0;
  uint64_t overruns = 0;          // cycles that ended after their deadline
  uint64_t missed_cycles = 0;     // slots that got no cycle (a 2 s stall at 1 ms: ~2000)
  uint32_t overrun_streak = 0;    // consecutive overrun cycles up to the last one
  uint32_t longest_streak = 0;
  int64_t longest_gap = 0;        // most slots missed by one overrun
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
  // Called by the thread once per cycle, after its functions ran.
  void record_cycle_end(const CycleEnd& end) noexcept;
  // Forgets the maxima (halcmd "setp <thread>.tmax 0").
  void reset_maxima() noexcept;

  TimingSnapshot snapshot() const noexcept;
  uint64_t cycles() const noexcept { return cycles_.load(std::memory_order_relaxed); }
  uint64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }
  uint32_t overrun_streak() const noexcept { return streak_.load(std::memory_order_relaxed); }
  int64_t exec_last_ns() const noexcept { return exec_last_.load(std::memory_order_relaxed); }
  int64_t exec_max_ns() const noexcept { return exec_max_.load(std::memory_order_relaxed); }
  int64_t latency_max_ns() const noexcept { return latency_max_.load(std::memory_order_relaxed); }

 private:
  std::atomic<int64_t> period_ns_{0};
  std::atomic<uint64_t> cycles_{0};
  std::atomic<uint64_t> overruns_{0};
  std::atomic<uint64_t> missed_{0};
  std::atomic<uint32_t> streak_{0};
  std::atomic<uint32_t> longest_streak_{0};
  std::atomic<int64_t> longest_gap_{0};
  std::atomic<int64_t> latency_min_{std::numeric_limits<int64_t>::max()};
  std::atomic<int64_t> latency_max_{0};
  std::atomic<int64_t> period_min_{std::numeric_limits<int64_t>::max()};
  std::atomic<int64_t> period_max_{0};
  std::atomic<int64_t> exec_last_{0};
  std::atomic<int64_t> exec_max_{0};
  std::array<std::atomic<uint32_t>, kHistogramBuckets> hist_{};
};

}  // namespace cnc::rt
