#include "fieldbus/can/bus_load.hpp"

#include <algorithm>

#include "fieldbus/can/frame_timing.hpp"

namespace cnc::can {

const char* to_string(FrameClass c) noexcept {
  switch (c) {
    case FrameClass::Synchronous: return "synchronous";
    case FrameClass::Sporadic: return "sporadic";
    case FrameClass::Allowance: return "allowance";
  }
  return "?";
}

uint32_t ScheduledFrame::max_per_cycle(int64_t cycle_ns) const noexcept {
  switch (frame_class()) {
    case FrameClass::Allowance: return per_cycle;
    // Sent at t and again after each interval: ceil(cycle / interval) fit
    // in one cycle.
    case FrameClass::Sporadic: return static_cast<uint32_t>((cycle_ns + period_ns - 1) / period_ns);
    case FrameClass::Synchronous: return 1;
  }
  return 1;
}

double ScheduledFrame::average_per_cycle(int64_t cycle_ns) const noexcept {
  switch (frame_class()) {
    case FrameClass::Allowance: return 0;
    case FrameClass::Sporadic: return static_cast<double>(cycle_ns) / static_cast<double>(period_ns);
    case FrameClass::Synchronous: return every_n_cycles > 0 ? 1.0 / every_n_cycles : 0;
  }
  return 0;
}

namespace {

// Arbitration order: lower is sent first. A standard frame wins against an
// extended one with the same 11-bit base identifier (IDE recessive).
uint64_t priority_key(const ScheduledFrame& f) noexcept {
  if (f.extended) return (static_cast<uint64_t>(f.cob_id & 0x1FFFFFFF) << 1) | 1u;
  return static_cast<uint64_t>(f.cob_id & 0x7FF) << 19;
}

uint64_t gcd(uint64_t a, uint64_t b) noexcept {
  while (b) {
    const uint64_t t = a % b;
    a = b;
    b = t;
  }
  return a;
}

bool in_slot(const ScheduledFrame& f, uint32_t slot, bool phase_known) noexcept {
  if (f.every_n_cycles <= 1 || !phase_known) return true;  // every cycle, or any slot in the worst case
  return slot % f.every_n_cycles == static_cast<uint32_t>(f.slot) % f.every_n_cycles;
}

}  // namespace

BusLoad compute_bus_load(const std::vector<ScheduledFrame>& frames, int64_t cycle_ns, uint32_t bitrate) {
  BusLoad load;
  load.cycle_bits = static_cast<double>(cycle_ns) * 1e-9 * bitrate;
  // The pattern repeats after the lcm of the dividers whose phase is known;
  // a pattern longer than this is planned as if no phase were known.
  constexpr uint64_t kMaxSlots = 5040;
  uint64_t pattern = 1;
  for (const auto& f : frames) {
    if (f.frame_class() != FrameClass::Synchronous || f.slot < 0 || f.every_n_cycles <= 1) continue;
    pattern = pattern / gcd(pattern, f.every_n_cycles) * f.every_n_cycles;
    if (pattern > kMaxSlots) break;
  }
  const bool phases = pattern <= kMaxSlots;
  if (!phases) pattern = 1;
  for (const auto& f : frames) {
    const double per = f.average_per_cycle(cycle_ns);
    load.nominal_bits_per_cycle += per * nominal_frame_bits(f.extended, f.data_bytes);
    load.worst_bits_per_cycle += per * worst_case_frame_bits(f.extended, f.data_bytes);
  }
  for (uint32_t k = 0; k < pattern; ++k) {
    SlotLoad s;
    s.slot = k;
    bool any = false;
    uint64_t lowest = 0;  // the lowest-priority synchronous frame of the slot
    std::vector<int32_t> fifo_groups;  // FIFO controllers with a synchronous frame in this slot
    for (const auto& f : frames) {
      if (f.frame_class() != FrameClass::Synchronous || !in_slot(f, k, phases && f.slot >= 0)) continue;
      s.synchronous_bits += worst_case_frame_bits(f.extended, f.data_bytes);
      s.response_bits = std::max(s.response_bits, static_cast<double>(f.release_ns) * 1e-9 * bitrate);
      lowest = std::max(lowest, priority_key(f));
      any = true;
      if (f.fifo_group >= 0 && std::find(fifo_groups.begin(), fifo_groups.end(), f.fifo_group) == fifo_groups.end()) {
        fifo_groups.push_back(f.fifo_group);
      }
    }
    auto queued_ahead = [&](const ScheduledFrame& f) {
      return f.fifo_group >= 0 && std::find(fifo_groups.begin(), fifo_groups.end(), f.fifo_group) != fifo_groups.end();
    };
    // A FIFO controller's synchronous frame goes only after every frame it
    // queued before, so the slot lasts until the lowest-priority of them won.
    for (const auto& f : frames) {
      if (queued_ahead(f)) lowest = std::max(lowest, priority_key(f));
    }
    for (const auto& f : frames) {
      if (f.frame_class() == FrameClass::Synchronous) continue;
      const double bits = worst_case_frame_bits(f.extended, f.data_bytes);
      if (any && (priority_key(f) < lowest || queued_ahead(f))) {
        s.interference_bits += f.max_per_cycle(cycle_ns) * bits;
      } else {
        s.blocking_bits = std::max(s.blocking_bits, bits);
      }
    }
    load.slots.push_back(s);
    if (s.total() > load.slots[load.worst_slot].total()) load.worst_slot = load.slots.size() - 1;
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
