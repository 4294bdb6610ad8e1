// What every function in a periodic thread is told about the current cycle:
// the nominal period and the one actually measured (ros2_control style), so
// that code integrating over time uses the real elapsed time.
#pragma once

#include <cstdint>

namespace cnc::rt {

struct CycleInfo {
  uint64_t cycle = 0;             // counts from 0 at thread start
  int64_t now_ns = 0;             // CLOCK_MONOTONIC at wake-up
  int64_t period_ns = 0;          // nominal period
  int64_t actual_period_ns = 0;   // since the previous wake-up (nominal on the first cycle)
  int64_t wake_latency_ns = 0;    // wake-up minus scheduled time
};

}  // namespace cnc::rt
