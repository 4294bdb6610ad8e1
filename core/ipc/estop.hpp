// E-stop without a command channel: words of the shared segment's header
// that any client bumps with one atomic operation and that motion, in the
// servo thread, reads every cycle and acknowledges once it has disabled the
// machine. Neither side ever waits for the other, so an E-stop needs no
// free command channel and no running task cycle (docs/architecture.md,
// "E-stop"). Plain atomics: usable from the servo thread.
#pragma once

#include <atomic>
#include <cstdint>

namespace cnc::ipc {

struct EstopWords {
  // (request count << 32) | pid of the last requester. Bumped by clients.
  std::atomic<uint64_t> request{0};
  // The request word motion last acted on (amplifiers off, spindles off,
  // planners flushed, E-stop latched). Written by the servo thread after
  // its outputs are written.
  std::atomic<uint64_t> acknowledged{0};
  // CLOCK_MONOTONIC of motion's last servo cycle and its cycle count: E-stop
  // requests are acted on while these advance.
  std::atomic<int64_t> servo_heartbeat_ns{0};
  std::atomic<uint64_t> servo_cycles{0};
};

constexpr uint32_t estop_count(uint64_t word) noexcept { return static_cast<uint32_t>(word >> 32); }
constexpr int32_t estop_pid(uint64_t word) noexcept { return static_cast<int32_t>(static_cast<uint32_t>(word)); }

// Counts one more request by `pid`: a single compare-exchange, retried only
// when another requester bumped the word at the same moment. Returns the
// word written (the one to wait for).
inline uint64_t bump_estop_request(EstopWords& w, int32_t pid) noexcept {
  uint64_t old = w.request.load(std::memory_order_relaxed);
  uint64_t next = 0;
  do {
    next = (static_cast<uint64_t>(estop_count(old) + 1) << 32) | static_cast<uint32_t>(pid);
  } while (!w.request.compare_exchange_weak(old, next, std::memory_order_acq_rel, std::memory_order_relaxed));
  return next;
}

// True when the acknowledgement covers the request `word` (counts compared
// modulo 2^32).
constexpr bool estop_acknowledges(uint64_t acknowledged, uint64_t word) noexcept {
  return static_cast<int32_t>(estop_count(acknowledged) - estop_count(word)) >= 0;
}

// When a heartbeat counts as stopped. The task cycle: older than 0.5 s or
// ten cycles, whichever is longer ([TASK]CYCLE_TIME). Motion in the servo
// thread: older than 0.25 s or a hundred periods (the drives' own watchdogs
// have stopped them long before; shorter would turn a loaded host's
// scheduling hiccup into an E-stop).
constexpr int64_t task_stall_threshold_ns(int64_t task_cycle_ns) noexcept {
  return task_cycle_ns * 10 > 500'000'000 ? task_cycle_ns * 10 : 500'000'000;
}
constexpr int64_t servo_stall_threshold_ns(int64_t servo_period_ns) noexcept {
  return servo_period_ns * 100 > 250'000'000 ? servo_period_ns * 100 : 250'000'000;
}

// How fresh what a client sees is: the status block is published by the
// task cycle, the servo heartbeat by motion in the servo thread. A stalled
// task cycle leaves the status stale but E-stop working; a stalled servo
// heartbeat means E-stop requests are not acted on by motion (the drives'
// own watchdogs stop them).
struct Liveness {
  int64_t status_age_ns = 0;    // since the task cycle last published the status
  int64_t servo_age_ns = -1;    // since motion's last servo cycle; -1: no motion
  bool task_stalled = false;    // status_age_ns beyond task_stall_threshold_ns
  bool servo_stalled = false;   // servo_age_ns beyond servo_stall_threshold_ns
};

// Judges ages against the thresholds above. Heartbeats are
// CLOCK_MONOTONIC ns; a servo heartbeat of 0 means no motion.
constexpr Liveness assess_liveness(int64_t now_ns, int64_t status_heartbeat_ns, int64_t servo_heartbeat_ns,
                                   int64_t task_cycle_ns, double servo_period_s) noexcept {
  Liveness l;
  l.status_age_ns = now_ns - status_heartbeat_ns;
  l.task_stalled = l.status_age_ns > task_stall_threshold_ns(task_cycle_ns);
  if (servo_heartbeat_ns != 0) {
    l.servo_age_ns = now_ns - servo_heartbeat_ns;
    l.servo_stalled = l.servo_age_ns > servo_stall_threshold_ns(static_cast<int64_t>(servo_period_s * 1e9));
  }
  return l;
}

}  // namespace cnc::ipc
