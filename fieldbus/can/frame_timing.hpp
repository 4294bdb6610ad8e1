// Bits a classic CAN frame occupies on the wire, from SOF to the end of the
// 3-bit intermission: nominal (no stuff bits), worst case (the stuffing
// bound of Davis et al. 2007) and exact (the frame's real bit stream with
// CRC-15 and stuff bits). Pure functions, realtime-safe.
#pragma once

#include <cstdint>

#include "fieldbus/can/frame.hpp"

namespace cnc::can {

enum class Stuffing : uint8_t { Nominal, WorstCase, Exact };

const char* to_string(Stuffing s) noexcept;

// Classic frames only; `data_bytes` counts 0 for remote frames.
constexpr uint32_t nominal_frame_bits(bool extended, uint32_t data_bytes) noexcept {
  return (extended ? 67u : 47u) + 8u * data_bytes;
}
constexpr uint32_t worst_case_frame_bits(bool extended, uint32_t data_bytes) noexcept {
  const uint32_t stuffable = (extended ? 54u : 34u) + 8u * data_bytes;
  return nominal_frame_bits(extended, data_bytes) + (stuffable - 1u) / 4u;
}
// The CRC-15 of the frame and the number of stuff bits its bit stream needs.
uint16_t frame_crc15(const Frame& f) noexcept;
uint32_t stuff_bits(const Frame& f) noexcept;
uint32_t exact_frame_bits(const Frame& f) noexcept;

uint32_t frame_bits(const Frame& f, Stuffing model) noexcept;

// Bits of an error frame with its delimiter and intermission, as charged by
// the virtual bus: 6 flag + 6 superposed flag + 8 delimiter + 3 intermission.
inline constexpr uint32_t kErrorFrameBits = 23;
// Bus idle needed for bus-off recovery: 128 occurrences of 11 recessive bits.
inline constexpr uint32_t kBusOffRecoveryBits = 128 * 11;

}  // namespace cnc::can
