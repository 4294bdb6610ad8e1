// Distributed clocks arithmetic, free of I/O so that it can be tested on its
// own: propagation delays of a line from the latched port receive times,
// system-time offsets, and the master-follows-reference phase lock (M2R)
// that steers the servo thread's wake-up, with the statistics of its
// offset. Realtime-safe (no allocation).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cnc::ethercat {

// Port receive times latched by one BWR to 0x0900, in line order (every
// slave DC-capable). port1 is 0 when port 1 is not in use (end of line).
struct PortTimes {
  uint32_t port0 = 0, port1 = 0;
  bool port1_open = false;
  int64_t local_at_latch = 0;  // 0x0918
};
// Propagation delay of each slave from the first one (the reference), ns.
// In a line a frame passes slave i at t0 + d_i on its way out and returns on
// port 1 after the loop behind it: d_i = (loop_0 - loop_i) / 2.
std::vector<int64_t> line_delays(const std::vector<PortTimes>& t);
// System-time offsets (0x0920) that make every slave's system time equal
// the reference's: reference local time + its offset + delay - own local.
std::vector<int64_t> system_offsets(const std::vector<PortTimes>& t, const std::vector<int64_t>& delays,
                                    int64_t reference_offset);

// Running statistics of the lock offset (ns). No allocation.
struct OffsetStats {
  uint64_t count = 0;
  double mean = 0, m2 = 0;
  int64_t min = std::numeric_limits<int64_t>::max(), max = std::numeric_limits<int64_t>::min();
  int64_t max_abs = 0;
  void add(int64_t v) noexcept {
    ++count;
    const double d = static_cast<double>(v) - mean;
    mean += d / static_cast<double>(count);
    m2 += d * (static_cast<double>(v) - mean);
    if (v < min) min = v;
    if (v > max) max = v;
    const int64_t a = v < 0 ? -v : v;
    if (a > max_abs) max_abs = a;
  }
  double stddev() const noexcept { return count > 1 ? std::sqrt(m2 / static_cast<double>(count - 1)) : 0.0; }
  void reset() noexcept { *this = OffsetStats{}; }
};

// Master follows the reference clock: each cycle the reference's system
// time when the cycle's frame passed it gives the phase of the master's
// cycle on the DC grid; a PI controller returns how far to move the next
// wake-up so that the phase stays at `target` (ns into the DC cycle).
class PhaseLock {
 public:
  struct Options {
    int64_t cycle_ns = 1'000'000;
    int64_t target_ns = 0;
    double kp = 0.2, ki = 0.01;
    double max_step = 0.01;        // of the period per cycle once locked (1 %)
    int64_t lock_window_ns = 0;    // |offset| below this counts as locked; 0: 10 % of the cycle
  };
  PhaseLock() noexcept = default;
  explicit PhaseLock(const Options& o) noexcept : o_(o) {}
  void reset() noexcept;
  // Returns the wake-up shift for the next cycle, ns (negative: earlier).
  int64_t update(int64_t reference_system_time_ns) noexcept;
  int64_t offset_ns() const noexcept { return offset_; }  // last phase error
  // Locked after 100 cycles in a row inside the window, unlocked after 50 outside.
  bool is_locked() const noexcept { return locked_; }
  const OffsetStats& stats() const noexcept { return stats_; }          // offsets while locked
  const OffsetStats& stats_all() const noexcept { return stats_all_; }  // every offset after the first step
  void reset_stats() noexcept { stats_.reset(), stats_all_.reset(); }
  const Options& options() const noexcept { return o_; }

 private:
  Options o_;
  bool started_ = false;
  int64_t offset_ = 0;
  double integral_ = 0;
  uint64_t inside_ = 0, outside_ = 0;
  bool locked_ = false;
  OffsetStats stats_, stats_all_;
};

}  // namespace cnc::ethercat
