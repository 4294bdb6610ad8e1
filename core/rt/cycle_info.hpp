// What every function in a periodic thread is told about the current cycle:
// the nominal period and the one actually measured (ros2_control style), so
// that code integrating over time uses the real elapsed time, and how the
// thread has kept its deadlines (overruns, missed cycles), so that the
// motion controller can act on a late servo thread without HAL wiring.
#pragma once

#include <cstdint>

namespace cnc::rt {

struct CycleInfo {
  uint64_t cycle = 0;             // counts from 0 at thread start
  int64_t now_ns = 0;             // CLOCK_MONOTONIC at wake-up
  int64_t period_ns = 0;          // nominal period
  int64_t actual_period_ns = 0;   // since the previous wake-up (nominal on the first cycle)
  int64_t wake_latency_ns = 0;    // wake-up minus scheduled time
  // Set by rt::PeriodicTask: the cycle runs on the thread's own clock. False
  // when a test or a simulation steps the thread by hand
  // (hal::Thread::run_cycle), as fast as it likes: a simulator then does its
  // work inline, deterministically, instead of on a thread of its own.
  bool periodic = false;

  // Deadlines (docs/architecture.md, "The servo cycle"). A cycle overruns
  // when it ends after the next slot of the thread's grid; the slots it ran
  // into get no cycle of their own (they are missed, not caught up).
  uint32_t overrun_streak = 0;    // consecutive overrun cycles up to the previous one (0: it was on time)
  int64_t missed_cycles = 0;      // slots skipped just before this cycle: >= 1 after an overrun, ~2000 after a 2 s stall
  // Set by the HAL thread: the streak, or the slots missed at once, reached
  // its overrun limit ([EMCMOT]OVERRUN_STREAK); stays set until a cycle is
  // on time again.
  bool is_late = false;
};

}  // namespace cnc::rt
