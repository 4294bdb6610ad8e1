// Step 1, the bus, for devices that have no node-ID yet: LSS (CiA 305)
// fastscan finds each device without node-ID by its identity, gives it the
// next free node-ID and has it store it, after which it boots under that
// ID and the SDO scan (scan.hpp) sees it. Non-realtime.
#pragma once

#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/lss.hpp"

namespace cnc::commission {

struct LssAssignment {
  canopen::lss::Address address;
  int node_id = 0;
};

struct LssOptions {
  int first = 1;                  // the first node-ID given
  std::set<int> taken;            // node-IDs in use (those a scan found)
  uint32_t bitrate = 0;           // also configure this bit rate (0: leave it)
  int64_t timeout_ns = 50'000'000;   // per confirmed answer
  int64_t window_ns = 10'000'000;    // per fastscan step
  int max_devices = 127;
};

struct LssResult {
  std::vector<LssAssignment> assigned;
  std::vector<std::string> problems;
  bool ok() const noexcept { return problems.empty(); }
};

// Gives every device without node-ID on `bus` a node-ID from
// options.first upwards, skipping options.taken. A device that refuses a
// node-ID or cannot store it, or node-IDs running out, is a problem naming
// the device (its LSS address).
LssResult assign_node_ids(can::Transport& bus, const LssOptions& options);

// Whether any device without node-ID answers (one fastscan request).
bool unconfigured_devices_present(can::Transport& bus, int64_t window_ns = 10'000'000);

std::string describe(const LssAssignment& a);

}  // namespace cnc::commission
