// A HAL thread: an ordered list of realtime functions run once per period by
// an rt::PeriodicTask. The list is double-buffered so that addf/delf from
// another thread never make the servo thread wait or see a half-built list.
// It also keeps the thread's overrun account: which function each overrun
// is blamed on, when a streak or a gap reaches the overrun limit, and the
// reports of those events for the message channel (formatted outside the
// servo thread). run_cycle never allocates, locks, blocks or formats.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/hal/objects.hpp"
#include "core/rt/periodic_task.hpp"
#include "core/util/spsc_ring.hpp"

namespace cnc::hal {

// A report of a thread for the message channel: written by run_cycle, read
// and formatted by the controller's task cycle (describe()). A thread is
// late when overrun_limit consecutive cycles overran, or when one overrun
// missed that many periods at once (a gap); a late spell lasts until a
// cycle is on time again. The first spell is reported at once; later ones
// within kReportQuietNs of the last report are counted into one Summary,
// unless they miss at least twice the periods of the last report.
struct OverrunEvent {
  enum class Kind : uint8_t {
    Streak,   // overrun_limit consecutive overruns
    Gap,      // one overrun missed overrun_limit periods or more (a stall)
    Ended,    // a reported spell that went on after its report is over
    Summary,  // spells not reported one by one since the last report
  };
  Kind kind = Kind::Streak;
  uint32_t streak = 0;           // overrun cycles in a row (Ended: in all; Summary: spells counted)
  int64_t missed_cycles = 0;     // periods missed: in the spell (Summary: by the worst spell counted)
  int64_t period_ns = 0;
  const Function* function = nullptr;  // blamed for the last overrun; null: the thread woke late
  int64_t function_ns = 0;       // how long it ran in that cycle
  int64_t wake_latency_ns = 0;   // how late that cycle woke
  int64_t since_ns = 0;          // Summary: time since the last report
  uint32_t dropped_before = 0;   // reports lost before this one (the reader was too slow)
};

// The report as a person reads it, e.g. "3 consecutive overruns of the
// 1.000 ms period (3 periods missed); blamed on motion-controller, which ran
// 1.420 ms". Non-realtime.
std::string describe(const OverrunEvent& event);

class Thread {
 public:
  static constexpr std::size_t kMaxFunctions = 128;
  static constexpr uint32_t kDefaultOverrunLimit = 3;
  static constexpr int64_t kReportQuietNs = 10'000'000'000;
  using Clock = int64_t (*)() noexcept;

  Thread(std::string name, int64_t period_ns, bool uses_fp);
  Thread(const Thread&) = delete;
  Thread& operator=(const Thread&) = delete;

  const std::string& name() const noexcept { return name_; }
  int64_t period_ns() const noexcept { return period_ns_; }
  bool uses_fp() const noexcept { return uses_fp_; }

  // One cycle: every function in order, each timed. Realtime-safe. Public so
  // that tests and simulations can step a thread without a periodic task;
  // they set info.overrun_streak and info.missed_cycles as the periodic task
  // would (docs/architecture.md, "The servo cycle").
  void run_cycle(const rt::CycleInfo& info) noexcept;

  // Non-realtime, called with the HAL mutex held.
  std::vector<Function*> functions() const;
  void set_functions(const std::vector<Function*>& list);

  void start();
  void stop();
  bool is_running() const noexcept { return task_.is_running(); }
  rt::PeriodicTask& task() noexcept { return task_; }
  const rt::PeriodicTask& task() const noexcept { return task_; }

  // The last cycle's execution time split between the product's functions
  // and the simulators' (functions of components that are
  // is_simulation()), and the longest of each since the start. Any thread.
  int64_t product_exec_last_ns() const noexcept { return product_last_ns_.load(std::memory_order_relaxed); }
  int64_t product_exec_max_ns() const noexcept { return product_max_ns_.load(std::memory_order_relaxed); }
  int64_t simulation_exec_last_ns() const noexcept { return sim_last_ns_.load(std::memory_order_relaxed); }
  int64_t simulation_exec_max_ns() const noexcept { return sim_max_ns_.load(std::memory_order_relaxed); }

  // Thread parameters <name>.time and <name>.tmax, set by the HAL.
  void set_params(detail::ParamObj* time, detail::ParamObj* tmax) { time_ = time; tmax_ = tmax; }

  // --- overruns ---
  // Consecutive overruns, or slots missed at once, that make the thread late
  // ([EMCMOT]OVERRUN_STREAK, set through Hal::set_overrun_limit).
  void set_overrun_limit(uint32_t cycles) noexcept { overrun_limit_.store(cycles < 1 ? 1 : cycles); }
  uint32_t overrun_limit() const noexcept { return overrun_limit_.load(std::memory_order_relaxed); }
  // The next report for the message channel; false when there is none.
  // One reader (the controller's task cycle).
  bool poll_overrun_event(OverrunEvent& out) noexcept { return events_.pop(out); }
  // Overruns blamed on a late wake-up (the host or the scheduler), not on a function.
  uint64_t late_wakes() const noexcept { return late_wakes_.load(std::memory_order_relaxed); }
  // The function blamed for the most overruns of this thread; null if none.
  const Function* worst_function() const noexcept { return worst_.load(std::memory_order_acquire); }
  static uint32_t overruns_of(const Function& f) noexcept { return f.overruns->cell.get<uint32_t>(); }
  // Replaces the clock that times the functions (tests make it step).
  void set_clock(Clock clock) noexcept { clock_ = clock; }

 private:
  struct List {
    std::array<Function*, kMaxFunctions> items{};
    std::array<bool, kMaxFunctions> simulation{};  // the function's component is a simulator
    std::size_t count = 0;
  };
  static void trampoline(void* self, const rt::CycleInfo& info);
  void account_overruns(rt::CycleInfo& info) noexcept;
  void blame_previous_cycle() noexcept;
  void begin_late_spell(OverrunEvent::Kind kind, int64_t missed, int64_t now_ns) noexcept;
  void end_late_spell() noexcept;
  // A stall inside a late spell (the process stopped while a streak went
  // on): said as a gap of its own.
  void report_gap_in_spell(int64_t missed, int64_t now_ns) noexcept;
  void push(const OverrunEvent& e) noexcept;
  OverrunEvent event(OverrunEvent::Kind kind, int64_t missed) const noexcept;

  std::string name_;
  int64_t period_ns_;
  bool uses_fp_;
  List lists_[2];
  std::atomic<int> active_{0};
  std::atomic<uint64_t> cycle_state_{0};  // odd while a cycle runs
  detail::ParamObj* time_ = nullptr;
  detail::ParamObj* tmax_ = nullptr;
  Clock clock_;
  std::atomic<int64_t> product_last_ns_{0}, product_max_ns_{0}, sim_last_ns_{0}, sim_max_ns_{0};

  // Overrun account, servo thread only except where atomic.
  std::atomic<uint32_t> overrun_limit_{kDefaultOverrunLimit};
  std::atomic<uint64_t> late_wakes_{0};
  std::atomic<const Function*> worst_{nullptr};
  SpscRing<OverrunEvent, 16> events_;
  uint32_t events_dropped_ = 0;
  // The previous cycle, for blaming it when the next one learns it overran.
  int64_t prev_latency_ns_ = 0;
  int64_t prev_exec_ns_ = 0;
  Function* prev_longest_ = nullptr;
  int64_t prev_longest_ns_ = 0;
  // The last overrun's culprit and the streak so far.
  const Function* blamed_ = nullptr;
  int64_t blamed_ns_ = 0;
  int64_t blamed_latency_ns_ = 0;
  uint32_t streak_ = 0;
  int64_t streak_missed_ = 0;
  bool late_ = false;  // the limit was reached and no cycle was on time since
  // Report pacing: the spell under way was reported (with its streak then),
  // when and how big the last report was, spells counted since.
  bool spell_reported_ = false;
  uint32_t spell_reported_streak_ = 0;
  int64_t spell_worst_gap_ = 0;  // the most periods one cycle of the spell missed at once
  bool reported_any_ = false;
  int64_t last_report_ns_ = 0;
  int64_t last_report_missed_ = 0;
  uint32_t unreported_spells_ = 0;
  int64_t unreported_worst_ = 0;

  rt::PeriodicTask task_;
};

}  // namespace cnc::hal
