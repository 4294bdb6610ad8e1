#include "comp/screw_compensation.hpp"

#include <cmath>
#include <thread>
#include <utility>

namespace cnc::comp {

void ScrewCompensation::install(CompTable table) {
  withdraw();
  const int a = active_.load(std::memory_order_relaxed);
  slots_[a] = std::move(table);
  entries_.store(slots_[a].size(), std::memory_order_release);
}

bool ScrewCompensation::withdraw() noexcept {
  for (;;) {
    int state = handover_.load(std::memory_order_acquire);
    if (state == kFree) return false;
    if (state == kPending &&
        handover_.compare_exchange_strong(state, kFree, std::memory_order_acq_rel, std::memory_order_acquire)) {
      return true;
    }
    // The servo thread is switching: it ends within its cycle.
    std::this_thread::yield();
  }
}

void ScrewCompensation::offer(CompTable table) {
  withdraw();
  // With no offer pending only this thread could make one, so the servo
  // thread does not switch now: the spare slot is ours to fill.
  const int spare = 1 - active_.load(std::memory_order_acquire);
  slots_[spare] = std::move(table);
  handover_.store(kPending, std::memory_order_release);
}

bool ScrewCompensation::correction(double pos_cmd, double vel_cmd, double& value) noexcept {
  if (vel_cmd > kRestVelocity) direction_ = 1;
  else if (vel_cmd < -kRestVelocity) direction_ = -1;
  int expected = kPending;
  if (std::fabs(vel_cmd) <= kRestVelocity && handover_.load(std::memory_order_relaxed) == kPending &&
      handover_.compare_exchange_strong(expected, kSwitching, std::memory_order_acq_rel, std::memory_order_relaxed)) {
    const int next = 1 - active_.load(std::memory_order_relaxed);
    active_.store(next, std::memory_order_release);
    entries_.store(slots_[next].size(), std::memory_order_release);
    switches_.fetch_add(1, std::memory_order_acq_rel);
    handover_.store(kFree, std::memory_order_release);
  }
  const CompTable& t = slots_[active_.load(std::memory_order_relaxed)];
  if (t.empty()) return false;
  value = t.at(pos_cmd, direction_);
  return true;
}

}  // namespace cnc::comp
