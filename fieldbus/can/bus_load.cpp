#include "fieldbus/can/bus_load.hpp"

#include "fieldbus/can/frame_timing.hpp"

namespace cnc::can {

BusLoad compute_bus_load(const std::vector<ScheduledFrame>& frames, int64_t cycle_ns, uint32_t bitrate) {
  BusLoad load;
  load.cycle_bits = static_cast<double>(cycle_ns) * 1e-9 * bitrate;
  for (const auto& f : frames) {
    double per_cycle = 0;
    if (f.period_ns > 0) {
      per_cycle = static_cast<double>(cycle_ns) / static_cast<double>(f.period_ns);
    } else if (f.every_n_cycles > 0) {
      per_cycle = 1.0 / f.every_n_cycles;
    }
    load.nominal_bits_per_cycle += per_cycle * nominal_frame_bits(f.extended, f.data_bytes);
    load.worst_bits_per_cycle += per_cycle * worst_case_frame_bits(f.extended, f.data_bytes);
  }
  return load;
}

AxisBits axis_bits(const std::vector<uint32_t>& rpdo_bytes, const std::vector<uint32_t>& tpdo_bytes) {
  AxisBits b;
  for (const auto* list : {&rpdo_bytes, &tpdo_bytes}) {
    for (uint32_t n : *list) {
      b.nominal += nominal_frame_bits(false, n);
      b.worst_case += worst_case_frame_bits(false, n);
    }
  }
  return b;
}

double axes_per_bus(uint32_t bits_per_axis, uint32_t sync_bits, int64_t cycle_ns, uint32_t bitrate, double budget) {
  if (bits_per_axis == 0) return 0;
  const double cycle_bits = static_cast<double>(cycle_ns) * 1e-9 * bitrate;
  const double available = cycle_bits * budget - sync_bits;
  return available > 0 ? available / bits_per_axis : 0;
}

}  // namespace cnc::can
