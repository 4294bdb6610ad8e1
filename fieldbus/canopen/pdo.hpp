// PDO descriptions shared by the master and the slave stack (CiA 301 §7.2.2):
// mapping entries (index << 16 | sub << 8 | bits), communication parameters
// and little-endian bit packing of mapped values into PDO bytes.
// Bit copies are realtime-safe.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

struct PdoMapEntry {
  uint16_t index = 0;
  uint8_t sub = 0;
  uint8_t bits = 0;
  uint32_t encode() const noexcept {
    return (static_cast<uint32_t>(index) << 16) | (static_cast<uint32_t>(sub) << 8) | bits;
  }
  static PdoMapEntry decode(uint32_t v) noexcept {
    return PdoMapEntry{static_cast<uint16_t>(v >> 16), static_cast<uint8_t>(v >> 8), static_cast<uint8_t>(v)};
  }
  // Dummy entries (gaps) name a data type index 0x0001-0x0007.
  bool is_dummy() const noexcept { return index >= 0x0001 && index <= 0x0007; }
  friend bool operator==(const PdoMapEntry&, const PdoMapEntry&) = default;
};

// Transmission types (0x1400:2 / 0x1800:2).
inline constexpr uint8_t kTransmissionSyncAcyclic = 0;
inline constexpr uint8_t kTransmissionSyncMax = 240;
inline constexpr uint8_t kTransmissionRtrSync = 252;
inline constexpr uint8_t kTransmissionRtrEvent = 253;
inline constexpr uint8_t kTransmissionEventVendor = 254;
inline constexpr uint8_t kTransmissionEventProfile = 255;
inline bool is_sync_transmission(uint8_t t) noexcept { return t <= kTransmissionSyncMax; }
inline bool is_valid_transmission(uint8_t t, bool tpdo) noexcept {
  if (t <= kTransmissionSyncMax) return true;
  if (t == kTransmissionRtrSync || t == kTransmissionRtrEvent) return tpdo;
  return t == kTransmissionEventVendor || t == kTransmissionEventProfile;
}

// Communication and mapping parameters of one PDO as the master configures it.
struct PdoConfig {
  uint16_t number = 1;            // 1-based: RPDO1 is 0x1400/0x1600
  uint32_t cob_id = 0;            // 0: the predefined COB-ID for the node
  uint8_t transmission = 1;       // every SYNC
  uint16_t inhibit_100us = 0;     // TPDO only
  uint16_t event_ms = 0;          // TPDO: send period; RPDO: reception deadline
  uint8_t sync_start = 0;         // TPDO only
  // Event-driven TPDO, for the bus-load plan only (not sent to the device):
  // the shortest interval between two transmissions the application
  // guarantees, when it is longer than the inhibit time. 0: none declared.
  uint32_t plan_interval_us = 0;
  std::vector<PdoMapEntry> map;
  uint32_t total_bits() const noexcept;
  uint32_t bytes() const noexcept { return (total_bits() + 7) / 8; }
};

// Parameter objects of PDO `number` (1-based).
inline constexpr uint16_t rpdo_comm_index(unsigned number) noexcept { return static_cast<uint16_t>(0x1400 + number - 1); }
inline constexpr uint16_t rpdo_map_index(unsigned number) noexcept { return static_cast<uint16_t>(0x1600 + number - 1); }
inline constexpr uint16_t tpdo_comm_index(unsigned number) noexcept { return static_cast<uint16_t>(0x1800 + number - 1); }
inline constexpr uint16_t tpdo_map_index(unsigned number) noexcept { return static_cast<uint16_t>(0x1A00 + number - 1); }
// The predefined COB-ID of PDO 1-4 for a node; 0 for higher numbers.
inline constexpr uint32_t default_pdo_cob(bool tpdo, unsigned number, unsigned node) noexcept {
  return number >= 1 && number <= 4 ? (tpdo ? cob::tpdo(number, node) : cob::rpdo(number, node)) : 0;
}

// Copies `nbits` bits, least significant first (PDO bit order).
inline void copy_bits(const uint8_t* src, unsigned src_bit, uint8_t* dst, unsigned dst_bit, unsigned nbits) noexcept {
  if (((src_bit | dst_bit | nbits) & 7) == 0) {
    for (unsigned i = 0; i < nbits / 8; ++i) dst[dst_bit / 8 + i] = src[src_bit / 8 + i];
    return;
  }
  for (unsigned i = 0; i < nbits; ++i) {
    const unsigned s = src_bit + i, d = dst_bit + i;
    const uint8_t bit = static_cast<uint8_t>((src[s / 8] >> (s % 8)) & 1u);
    dst[d / 8] = static_cast<uint8_t>((dst[d / 8] & ~(1u << (d % 8))) | (bit << (d % 8)));
  }
}

// "0x60400010" style text of a mapping list, for messages.
std::string describe_mapping(const std::vector<PdoMapEntry>& map);

}  // namespace cnc::canopen
