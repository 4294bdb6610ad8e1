// Bus load of a cyclic CAN schedule, computed before anything is sent,
// from every frame the configuration lets onto the bus at its highest rate:
//
//  - synchronous frames (SYNC, RPDOs, synchronous TPDOs) go in every n-th
//    cycle, in a known slot of the n cycles or, when nothing fixes the
//    phase, in any slot (then the plan puts them in every slot);
//  - sporadic frames (heartbeats, event-driven TPDOs) go at most once per
//    `min_interval_ns` (the heartbeat period, the PDO's inhibit time or a
//    declared budget), at any moment;
//  - allowances (EMCY, SDO) are a declared number of frames in any cycle.
//
// Two figures come out: the average load (synchronous frames at 1/n,
// sporadic ones at cycle / interval) and, per cycle slot, the bits that
// must pass between the start of a cycle and the last synchronous frame of
// that slot, by CAN's arbitration (lower identifier first, no pre-emption):
// the slot's synchronous frames, every sporadic frame or allowance with a
// higher priority than the slot's lowest-priority synchronous frame as
// often as it can occur in one cycle, and one lower-priority frame already
// on the wire (the longest). A node whose controller sends in queue order
// (one FIFO instead of priority-ordered mailboxes) breaks that order: its
// synchronous TPDO may wait behind every frame the node queued before it,
// each of which competes at its own, lower, priority. For such a node the
// slot counts the node's own sporadic frames as interference, and every
// other sporadic frame or allowance that outranks the node's lowest-priority
// frame (Davis et al., "CAN with FIFO queues", as a bound). Frame lengths are the worst case of bit
// stuffing (frame_timing.hpp: 47 + 8 n bits for a standard frame including
// the 3-bit intermission, plus at most (34 + 8 n - 1) / 4 stuff bits).
// Configuration tools refuse plans above a budget with it. Non-realtime.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cnc::can {

enum class FrameClass : uint8_t { Synchronous, Sporadic, Allowance };

const char* to_string(FrameClass c) noexcept;

struct ScheduledFrame {
  std::string label;          // "SYNC", "node 3 RPDO1", ...
  uint32_t data_bytes = 0;
  bool extended = false;
  uint32_t every_n_cycles = 1;  // synchronous: sent every n-th cycle
  int64_t period_ns = 0;        // > 0: sporadic, at most once per this interval (heartbeat, inhibit time)
  int32_t slot = -1;            // synchronous with a known phase: its slot 0..n-1; -1: any slot
  uint32_t per_cycle = 0;       // > 0: an allowance of this many frames in any cycle (EMCY, SDO)
  uint32_t cob_id = 0x7FF;      // identifier, for the arbitration order
  int32_t fifo_group = -1;      // >= 0: sent by a controller with one FIFO queue (same group, same queue)
  int64_t release_ns = 0;       // synchronous: queued this long after the SYNC (the device's response time)

  FrameClass frame_class() const noexcept {
    if (per_cycle > 0) return FrameClass::Allowance;
    return period_ns > 0 ? FrameClass::Sporadic : FrameClass::Synchronous;
  }
  // At most this many of the frame within one cycle (worst case).
  uint32_t max_per_cycle(int64_t cycle_ns) const noexcept;
  // On average per cycle (allowances: 0, they are a reserve, not traffic).
  double average_per_cycle(int64_t cycle_ns) const noexcept;
};

// One slot of the cycle pattern, worst-case stuffing.
struct SlotLoad {
  uint32_t slot = 0;
  double synchronous_bits = 0;   // the slot's synchronous frames
  double interference_bits = 0;  // sporadic frames and allowances that win arbitration against them
  double blocking_bits = 0;      // one lower-priority frame already on the wire
  double response_bits = 0;      // the slowest device's SYNC response time, in bit times
  double total() const noexcept { return synchronous_bits + interference_bits + blocking_bits + response_bits; }
};

struct BusLoad {
  double nominal_bits_per_cycle = 0;  // average, no stuff bits
  double worst_bits_per_cycle = 0;    // average, worst-case stuffing
  double cycle_bits = 0;              // bit times in one cycle
  std::vector<SlotLoad> slots;        // the cycle pattern (lcm of the known phases' dividers)
  std::size_t worst_slot = 0;         // index into slots
  double nominal() const noexcept { return cycle_bits > 0 ? nominal_bits_per_cycle / cycle_bits : 0; }
  double worst_case() const noexcept { return cycle_bits > 0 ? worst_bits_per_cycle / cycle_bits : 0; }
  // The busiest slot, as a share of the cycle.
  double worst_cycle() const noexcept {
    return cycle_bits > 0 && !slots.empty() ? slots[worst_slot].total() / cycle_bits : 0;
  }
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
