#include "core/hal/thread.hpp"

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "core/hal/component.hpp"
#include "core/util/time.hpp"

namespace cnc::hal {

Thread::Thread(std::string name, int64_t period_ns, bool uses_fp)
    : name_(std::move(name)), period_ns_(period_ns), uses_fp_(uses_fp), clock_(&monotonic_ns) {}

void Thread::run_cycle(const rt::CycleInfo& in) noexcept {
  // Sequentially consistent: pairs with set_functions' store-then-load.
  cycle_state_.fetch_add(1);
  rt::CycleInfo info = in;
  account_overruns(info);
  const List& list = lists_[active_.load()];
  const int64_t start = clock_();
  int64_t t0 = start;
  Function* longest = nullptr;
  int64_t longest_ns = -1;
  int64_t simulation_ns = 0;
  for (std::size_t i = 0; i < list.count; ++i) {
    Function* f = list.items[i];
    f->fn(f->arg, info);
    const int64_t t1 = clock_();
    const int64_t dt = t1 - t0;
    if (list.simulation[i]) simulation_ns += dt;
    f->time->cell.set<int64_t>(dt);
    if (dt > f->tmax->cell.get<int64_t>()) f->tmax->cell.set<int64_t>(dt);
    if (dt > longest_ns) {
      longest = f;
      longest_ns = dt;
    }
    t0 = t1;
  }
  const int64_t total = t0 - start;
  const int64_t product_ns = total - simulation_ns;
  product_last_ns_.store(product_ns, std::memory_order_relaxed);
  sim_last_ns_.store(simulation_ns, std::memory_order_relaxed);
  if (product_ns > product_max_ns_.load(std::memory_order_relaxed)) {
    product_max_ns_.store(product_ns, std::memory_order_relaxed);
  }
  if (simulation_ns > sim_max_ns_.load(std::memory_order_relaxed)) {
    sim_max_ns_.store(simulation_ns, std::memory_order_relaxed);
  }
  if (time_) {
    time_->cell.set<int64_t>(total);
    if (total > tmax_->cell.get<int64_t>()) tmax_->cell.set<int64_t>(total);
  }
  prev_latency_ns_ = info.wake_latency_ns;
  prev_exec_ns_ = total;
  prev_longest_ = longest;
  prev_longest_ns_ = longest_ns;
  cycle_state_.fetch_add(1, std::memory_order_acq_rel);
}

// The periodic task tells a cycle whether the one before it overran; that
// cycle is blamed now, and the streak is followed: a late spell begins when
// the streak (or the periods missed at once) reaches the limit and ends
// with the first cycle on time. info.is_late tells the functions (the
// motion controller acts on it).
void Thread::account_overruns(rt::CycleInfo& info) noexcept {
  if (info.missed_cycles > 0) {
    blame_previous_cycle();
    streak_ = info.overrun_streak;
    streak_missed_ += info.missed_cycles;
  } else if (info.overrun_streak == 0) {
    if (late_) end_late_spell();
    late_ = false;
    streak_ = 0;
    streak_missed_ = 0;
  }
  const uint32_t limit = overrun_limit_.load(std::memory_order_relaxed);
  if (!late_ && info.missed_cycles >= static_cast<int64_t>(limit)) {
    begin_late_spell(OverrunEvent::Kind::Gap, info.missed_cycles, info.now_ns);
  } else if (!late_ && info.overrun_streak >= limit) {
    begin_late_spell(OverrunEvent::Kind::Streak, streak_missed_, info.now_ns);
  } else if (late_ && info.missed_cycles >= static_cast<int64_t>(limit) &&
             info.missed_cycles >= 2 * spell_worst_gap_) {
    report_gap_in_spell(info.missed_cycles, info.now_ns);
  }
  if (late_ && info.missed_cycles > spell_worst_gap_) spell_worst_gap_ = info.missed_cycles;
  // Spells counted but not reported are summed up once the quiet time is over.
  if (unreported_spells_ > 0 && info.now_ns - last_report_ns_ >= kReportQuietNs) {
    OverrunEvent e = event(OverrunEvent::Kind::Summary, unreported_worst_);
    e.streak = unreported_spells_;
    e.since_ns = info.now_ns - last_report_ns_;
    push(e);
    last_report_ns_ = info.now_ns;
    last_report_missed_ = unreported_worst_;
    unreported_spells_ = 0;
    unreported_worst_ = 0;
  }
  info.is_late = late_;
}

void Thread::begin_late_spell(OverrunEvent::Kind kind, int64_t missed, int64_t now_ns) noexcept {
  late_ = true;
  spell_worst_gap_ = 0;
  const bool quiet = reported_any_ && now_ns - last_report_ns_ < kReportQuietNs;
  spell_reported_ = !quiet || missed >= 2 * last_report_missed_;
  if (!spell_reported_) {
    ++unreported_spells_;
    if (missed > unreported_worst_) unreported_worst_ = missed;
    return;
  }
  push(event(kind, missed));
  spell_reported_streak_ = streak_;
  reported_any_ = true;
  last_report_ns_ = now_ns;
  last_report_missed_ = missed;
}

// Within the quiet time only a gap twice as bad as the last report is said
// (as for a new spell). A spell that was only counted becomes a reported
// one; a reported one still says when it ends.
void Thread::report_gap_in_spell(int64_t missed, int64_t now_ns) noexcept {
  const bool quiet = reported_any_ && now_ns - last_report_ns_ < kReportQuietNs;
  if (quiet && missed < 2 * last_report_missed_) return;
  push(event(OverrunEvent::Kind::Gap, missed));
  if (!spell_reported_) {
    if (unreported_spells_ > 0) --unreported_spells_;
    spell_reported_ = true;
    spell_reported_streak_ = streak_;
  }
  reported_any_ = true;
  last_report_ns_ = now_ns;
  last_report_missed_ = missed;
}

// Only a reported spell that went on after its report says when it ended
// (a single gap needs no second message).
void Thread::end_late_spell() noexcept {
  if (spell_reported_ && streak_ > spell_reported_streak_) {
    push(event(OverrunEvent::Kind::Ended, streak_missed_));
  } else if (!spell_reported_ && streak_missed_ > unreported_worst_) {
    unreported_worst_ = streak_missed_;  // the spell grew after it was counted
  }
  spell_reported_ = false;
}

// The previous cycle overran: it woke prev_latency_ns_ late and its
// functions ran prev_exec_ns_. The larger part is blamed: the late wake-up
// (the host or the scheduler: a stall, SIGSTOP, no SCHED_FIFO) or else the
// function that ran longest, which is the one whose speed-up would help most.
void Thread::blame_previous_cycle() noexcept {
  blamed_latency_ns_ = prev_latency_ns_;
  if (!prev_longest_ || prev_latency_ns_ >= prev_exec_ns_) {
    late_wakes_.fetch_add(1, std::memory_order_relaxed);
    blamed_ = nullptr;
    blamed_ns_ = 0;
    return;
  }
  Function* f = prev_longest_;
  // Atomic add: a function may run in two threads.
  f->overruns->cell.bits.fetch_add(1, std::memory_order_relaxed);
  if (prev_longest_ns_ > f->overrun_max_ns.load(std::memory_order_relaxed)) {
    f->overrun_max_ns.store(prev_longest_ns_, std::memory_order_relaxed);
  }
  const Function* worst = worst_.load(std::memory_order_relaxed);
  if (!worst || overruns_of(*f) > overruns_of(*worst)) worst_.store(f, std::memory_order_release);
  blamed_ = f;
  blamed_ns_ = prev_longest_ns_;
}

OverrunEvent Thread::event(OverrunEvent::Kind kind, int64_t missed) const noexcept {
  OverrunEvent e;
  e.kind = kind;
  e.streak = streak_;
  e.missed_cycles = missed;
  e.period_ns = period_ns_;
  e.function = blamed_;
  e.function_ns = blamed_ns_;
  e.wake_latency_ns = blamed_latency_ns_;
  return e;
}

void Thread::push(const OverrunEvent& event) noexcept {
  OverrunEvent e = event;
  e.dropped_before = events_dropped_;
  if (events_.push(e)) events_dropped_ = 0;
  else ++events_dropped_;
}

namespace {
// "0.420 ms" below a second, "2.003 s" above.
std::string duration(int64_t ns) {
  char b[32];
  if (ns >= 1'000'000'000 || ns <= -1'000'000'000) std::snprintf(b, sizeof b, "%.3f s", static_cast<double>(ns) * 1e-9);
  else std::snprintf(b, sizeof b, "%.3f ms", static_cast<double>(ns) * 1e-6);
  return b;
}
}  // namespace

std::string describe(const OverrunEvent& e) {
  const std::string missed = std::to_string(e.missed_cycles);
  std::string s;
  switch (e.kind) {
    case OverrunEvent::Kind::Streak:
      s = std::to_string(e.streak) + " consecutive overruns of the " + duration(e.period_ns) + " period (" + missed +
          " periods missed)";
      break;
    case OverrunEvent::Kind::Gap:
      s = "no cycle for " + duration(e.missed_cycles * e.period_ns) + ": " + missed + " periods of " +
          duration(e.period_ns) + " missed at once";
      break;
    case OverrunEvent::Kind::Ended:
      s = "on time again after " + std::to_string(e.streak) + " overrun cycle" + (e.streak == 1 ? "" : "s") + " (" +
          missed + " periods missed)";
      break;
    case OverrunEvent::Kind::Summary:
      s = std::to_string(e.streak) + " more late spell" + (e.streak == 1 ? "" : "s") + " in the last " +
          duration(e.since_ns) + ", the worst missing " + missed + " periods of " + duration(e.period_ns);
      break;
  }
  if (e.kind == OverrunEvent::Kind::Streak || e.kind == OverrunEvent::Kind::Gap) {
    if (e.function) {
      s += "; blamed on " + e.function->name + ", which ran " + duration(e.function_ns) + " (the cycle woke " +
           duration(e.wake_latency_ns) + " late)";
    } else {
      s += "; the thread woke " + duration(e.wake_latency_ns) + " late (the host or the scheduler, not a function)";
    }
  }
  if (e.dropped_before) s += " (" + std::to_string(e.dropped_before) + " earlier overrun reports lost)";
  return s;
}

std::vector<Function*> Thread::functions() const {
  const List& list = lists_[active_.load(std::memory_order_acquire)];
  return std::vector<Function*>(list.items.begin(), list.items.begin() + static_cast<long>(list.count));
}

void Thread::set_functions(const std::vector<Function*>& list) {
  const int next = 1 - active_.load(std::memory_order_relaxed);
  List& l = lists_[next];
  l.count = list.size() < kMaxFunctions ? list.size() : kMaxFunctions;
  for (std::size_t i = 0; i < l.count; ++i) {
    l.items[i] = list[i];
    l.simulation[i] = list[i]->owner && list[i]->owner->is_simulation();
  }
  active_.store(next);
  // The old list may still be in use by a cycle that began before the swap:
  // wait (here, never in the servo thread) until that cycle has ended.
  const uint64_t s = cycle_state_.load();
  if (s & 1U) {
    while (cycle_state_.load() == s) std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
}

void Thread::trampoline(void* self, const rt::CycleInfo& info) { static_cast<Thread*>(self)->run_cycle(info); }

void Thread::start() {
  rt::PeriodicTask::Config cfg;
  cfg.name = name_;
  cfg.period_ns = period_ns_;
  task_.start(cfg, &Thread::trampoline, this);
}

void Thread::stop() { task_.stop(); }

}  // namespace cnc::hal
