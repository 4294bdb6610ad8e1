// A periodic thread: wakes on an absolute CLOCK_MONOTONIC grid, calls one
// callback per period, measures itself. Uses SCHED_FIFO and locked memory
// when the process may, and says once, clearly, when it may not (a normal
// kernel still works, with worse timing). The loop never allocates.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include "core/rt/cycle_info.hpp"
#include "core/rt/timing_stats.hpp"

namespace cnc::rt {

// What the process could get from the kernel for realtime work.
struct RealtimeCapabilities {
  bool memory_locked = false;
  bool fifo_scheduling = false;
  std::string note;  // empty when everything was granted
};

// Once per process, before threads start: mlockall and a SCHED_FIFO probe.
// Set CNC_NO_REALTIME=1 in the environment to skip both (tests, laptops).
const RealtimeCapabilities& prepare_process();

class PeriodicTask {
 public:
  using Callback = void (*)(void* arg, const CycleInfo& info);

  struct Config {
    std::string name;       // thread name (first 15 characters reach the kernel)
    int64_t period_ns = 1'000'000;
    int priority = -1;      // SCHED_FIFO priority; -1: highest minus one
  };

  PeriodicTask() = default;
  PeriodicTask(const PeriodicTask&) = delete;
  PeriodicTask& operator=(const PeriodicTask&) = delete;
  ~PeriodicTask() { stop(); }

  // Starts the thread; false if already running.
  bool start(const Config& config, Callback callback, void* arg);
  // Stops after the current cycle and joins. Safe to call twice.
  void stop();
  bool is_running() const noexcept { return running_.load(std::memory_order_acquire); }
  bool uses_fifo() const noexcept { return fifo_.load(std::memory_order_relaxed); }

  // Shifts the next wake-up by delta (bus-clock lock); applied once.
  void adjust_phase_ns(int64_t delta_ns) noexcept { phase_adjust_ns_.fetch_add(delta_ns, std::memory_order_relaxed); }

  const TimingStats& stats() const noexcept { return stats_; }
  TimingStats& stats() noexcept { return stats_; }
  int64_t period_ns() const noexcept { return period_ns_; }

 private:
  void loop();

  Config config_;
  Callback callback_ = nullptr;
  void* arg_ = nullptr;
  int64_t period_ns_ = 0;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> fifo_{false};
  std::atomic<int64_t> phase_adjust_ns_{0};
  TimingStats stats_;
};

}  // namespace cnc::rt
