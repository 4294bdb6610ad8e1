// Bus load of a cyclic CAN schedule, computed before anything is sent: the
// frames each cycle carries (or carries every n-th cycle), the frames sent
// on their own period (heartbeats), the cycle time and the bit rate give the
// share of the bus used, nominally and in the worst case of bit stuffing.
// Configuration tools refuse plans above a budget with it. Non-realtime.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cnc::can {

struct ScheduledFrame {
  std::string label;          // "SYNC", "node 3 RPDO1", ...
  uint32_t data_bytes = 0;
  bool extended = false;
  uint32_t every_n_cycles = 1;  // sent every n-th cycle (ignored when period_ns > 0)
  int64_t period_ns = 0;        // sent on its own period instead (heartbeat)
};

struct BusLoad {
  double nominal_bits_per_cycle = 0;
  double worst_bits_per_cycle = 0;
  double cycle_bits = 0;        // bit times in one cycle
  double nominal() const noexcept { return cycle_bits > 0 ? nominal_bits_per_cycle / cycle_bits : 0; }
  double worst_case() const noexcept { return cycle_bits > 0 ? worst_bits_per_cycle / cycle_bits : 0; }
};

BusLoad compute_bus_load(const std::vector<ScheduledFrame>& frames, int64_t cycle_ns, uint32_t bitrate);

// Bits one axis costs per cycle for the given PDO lengths (both directions).
struct AxisBits {
  uint32_t nominal = 0;
  uint32_t worst_case = 0;
};
AxisBits axis_bits(const std::vector<uint32_t>& rpdo_bytes, const std::vector<uint32_t>& tpdo_bytes);

// How many such axes fit in `budget` (0..1) of the bus at this cycle time,
// after the SYNC frame (0 or 1 data byte): the reference's capacity table.
// Fractional; take the floor for a plan.
double axes_per_bus(uint32_t bits_per_axis, uint32_t sync_bits, int64_t cycle_ns, uint32_t bitrate, double budget);

}  // namespace cnc::can
