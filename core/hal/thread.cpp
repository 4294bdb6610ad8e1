#include "core/hal/thread.hpp"

#include <chrono>
#include <thread>

#include "core/util/time.hpp"

namespace cnc::hal {

Thread::Thread(std::string name, int64_t period_ns, bool uses_fp)
    : name_(std::move(name)), period_ns_(period_ns), uses_fp_(uses_fp) {}

void Thread::run_cycle(const rt::CycleInfo& info) noexcept {
  // Sequentially consistent: pairs with set_functions' store-then-load.
  cycle_state_.fetch_add(1);
  const List& list = lists_[active_.load()];
  const int64_t start = monotonic_ns();
  int64_t t0 = start;
  for (std::size_t i = 0; i < list.count; ++i) {
    Function* f = list.items[i];
    f->fn(f->arg, info);
    const int64_t t1 = monotonic_ns();
    const int64_t dt = t1 - t0;
    f->time->cell.set<int64_t>(dt);
    if (dt > f->tmax->cell.get<int64_t>()) f->tmax->cell.set<int64_t>(dt);
    t0 = t1;
  }
  const int64_t total = t0 - start;
  if (time_) {
    time_->cell.set<int64_t>(total);
    if (total > tmax_->cell.get<int64_t>()) tmax_->cell.set<int64_t>(total);
  }
  cycle_state_.fetch_add(1, std::memory_order_acq_rel);
}

std::vector<Function*> Thread::functions() const {
  const List& list = lists_[active_.load(std::memory_order_acquire)];
  return std::vector<Function*>(list.items.begin(), list.items.begin() + static_cast<long>(list.count));
}

void Thread::set_functions(const std::vector<Function*>& list) {
  const int next = 1 - active_.load(std::memory_order_relaxed);
  List& l = lists_[next];
  l.count = list.size() < kMaxFunctions ? list.size() : kMaxFunctions;
  for (std::size_t i = 0; i < l.count; ++i) l.items[i] = list[i];
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
