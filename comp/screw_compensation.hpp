// One joint's screw compensation for the motion controller: a CompTable
// looked up by commanded position and direction, with the direction taken
// from the commanded velocity and kept at rest. A new table can be handed
// over while the controller runs: it is built aside and the servo thread
// switches to it at the start of a cycle in which the joint is at rest,
// without a lock (a double buffer: an atomic index and a hand-over flag).
// correction() runs in the servo thread and never allocates, blocks or
// throws; install/offer/withdraw run on one non-realtime thread.
#pragma once

#include <atomic>
#include <cstdint>

#include "comp/comp_table.hpp"
#include "core/motion/compensation.hpp"

namespace cnc::comp {

class ScrewCompensation : public motion::JointCompensation {
 public:
  // Before the servo thread calls correction(): the table to start with
  // (empty: no table, the controller applies BACKLASH).
  void install(CompTable table);
  // While running: hands `table` over; the servo thread takes it at its
  // next cycle with the joint at rest. An earlier offer not yet taken is
  // replaced.
  void offer(CompTable table);
  // Takes back an offer the servo thread has not taken; false when it was
  // taken (or there was none).
  bool withdraw() noexcept;
  bool offer_pending() const noexcept { return handover_.load(std::memory_order_acquire) != kFree; }
  // How many tables the servo thread has switched to (install not counted).
  uint64_t switches() const noexcept { return switches_.load(std::memory_order_acquire); }
  // Entries of the table in use (0: none). Any thread.
  std::size_t entries() const noexcept { return entries_.load(std::memory_order_acquire); }

  // A commanded speed at or below this (units/s) is rest: relabelling a
  // joint when it is homed leaves rounding noise in the velocity.
  static constexpr double kRestVelocity = 1e-9;

  // --- servo thread ---
  bool correction(double pos_cmd, double vel_cmd, double& value) noexcept override;
  // Direction of the last move: 1, -1, or 0 before the first move.
  int direction() const noexcept { return direction_; }

 private:
  static constexpr int kFree = 0, kPending = 1, kSwitching = 2;
  CompTable slots_[2];
  std::atomic<int> active_{0};      // written by the servo thread only (after install)
  std::atomic<int> handover_{kFree};
  std::atomic<uint64_t> switches_{0};
  std::atomic<std::size_t> entries_{0};
  int direction_ = 0;
};

}  // namespace cnc::comp
