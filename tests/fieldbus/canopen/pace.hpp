// For harnesses that step a simulated machine faster than real time
// (tests/comp/sim_mill.hpp): the CANopen masters' acyclic threads (SDO,
// NMT, heartbeats) keep the bus's clock but run at the scheduler's pace, so
// a harness can outrun them by seconds of simulated time on a loaded host
// (a mode switch by SDO then times out in the drive layer). The pacer waits,
// after a step, until every master's acyclic side has caught up to within
// `slack_ns` of its bus.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "fieldbus/canopen/components.hpp"
#include "fieldbus/canopen/master.hpp"

namespace cnc::canopen::test {

inline std::function<void()> acyclic_pacer(hal::Hal& hal, int64_t slack_ns = 20'000'000) {
  std::vector<Master*> masters;
  for (int i = 0; i < 16; ++i) {
    if (Master* m = find_master(hal, "canopen." + std::to_string(i))) masters.push_back(m);
  }
  return [masters, slack_ns] {
    for (Master* m : masters) {
      if (!m->thread_running()) continue;
      const int64_t want = m->bus_now_ns() - slack_ns;
      for (int i = 0; i < 20'000 && m->last_poll_ns() < want; ++i) {  // at most ~2 s of wall time
        std::this_thread::sleep_for(std::chrono::microseconds(100));
      }
    }
  };
}

}  // namespace cnc::canopen::test
