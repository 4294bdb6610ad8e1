// CANopen basics shared by the master and the slave stack (CiA 301): node
// states, NMT commands, the predefined connection set's COB-IDs, data types
// and little-endian access. Header-only, realtime-safe.
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <type_traits>

namespace cnc::canopen {

inline constexpr uint8_t kMaxNodeId = 127;
inline bool is_valid_node_id(unsigned id) noexcept { return id >= 1 && id <= kMaxNodeId; }

// The state a node reports in its heartbeat (and boot-up = 0).
enum class NmtState : uint8_t {
  Initialising = 0x00,
  Stopped = 0x04,
  Operational = 0x05,
  PreOperational = 0x7F,
  Unknown = 0xFF,  // not a wire value: nothing heard yet
};
const char* to_string(NmtState s) noexcept;
NmtState nmt_state_from_byte(uint8_t b) noexcept;

enum class NmtCommand : uint8_t {
  Start = 0x01,
  Stop = 0x02,
  EnterPreOperational = 0x80,
  ResetNode = 0x81,
  ResetCommunication = 0x82,
};
const char* to_string(NmtCommand c) noexcept;

// Predefined connection set (11-bit identifiers).
namespace cob {
inline constexpr uint32_t kNmt = 0x000;
inline constexpr uint32_t kSync = 0x080;
inline constexpr uint32_t kEmcyBase = 0x080;
inline constexpr uint32_t kTime = 0x100;
inline constexpr uint32_t kSdoTxBase = 0x580;  // server -> client
inline constexpr uint32_t kSdoRxBase = 0x600;  // client -> server
inline constexpr uint32_t kHeartbeatBase = 0x700;
inline constexpr uint32_t emcy(unsigned node) noexcept { return kEmcyBase + node; }
// n = 1..4
inline constexpr uint32_t tpdo(unsigned n, unsigned node) noexcept { return 0x080 + 0x100 * n + node; }
inline constexpr uint32_t rpdo(unsigned n, unsigned node) noexcept { return 0x100 + 0x100 * n + node; }
inline constexpr uint32_t sdo_response(unsigned node) noexcept { return kSdoTxBase + node; }
inline constexpr uint32_t sdo_request(unsigned node) noexcept { return kSdoRxBase + node; }
inline constexpr uint32_t heartbeat(unsigned node) noexcept { return kHeartbeatBase + node; }
// PDO COB-ID entry bits (0x1400:1, 0x1800:1).
inline constexpr uint32_t kPdoInvalid = 0x80000000u;
inline constexpr uint32_t kPdoNoRtr = 0x40000000u;
inline constexpr uint32_t kPdoExtended = 0x20000000u;
// SYNC COB-ID bit 30: this node produces SYNC (0x1005).
inline constexpr uint32_t kSyncProducer = 0x40000000u;
}  // namespace cob

// CiA 301 data types (object 0x0001..), as used in EDS DataType keys.
enum class DataType : uint16_t {
  Boolean = 0x0001,
  Integer8 = 0x0002,
  Integer16 = 0x0003,
  Integer32 = 0x0004,
  Unsigned8 = 0x0005,
  Unsigned16 = 0x0006,
  Unsigned32 = 0x0007,
  Real32 = 0x0008,
  VisibleString = 0x0009,
  OctetString = 0x000A,
  UnicodeString = 0x000B,
  Domain = 0x000F,
  Integer24 = 0x0010,
  Real64 = 0x0011,
  Integer64 = 0x0015,
  Unsigned24 = 0x0016,
  Unsigned64 = 0x001B,
};
// Size in bytes of a fixed-size type, 0 for strings and domains (or unknown).
std::size_t data_type_size(DataType t) noexcept;
bool is_signed(DataType t) noexcept;
bool is_fixed_size(DataType t) noexcept;
const char* to_string(DataType t) noexcept;
bool is_known_data_type(uint16_t code) noexcept;

enum class Access : uint8_t { ReadOnly, WriteOnly, ReadWrite, Const };
inline bool is_readable(Access a) noexcept { return a != Access::WriteOnly; }
inline bool is_writable(Access a) noexcept { return a == Access::WriteOnly || a == Access::ReadWrite; }

struct ObjectAddress {
  uint16_t index = 0;
  uint8_t sub = 0;
  friend bool operator==(const ObjectAddress&, const ObjectAddress&) = default;
  friend auto operator<=>(const ObjectAddress&, const ObjectAddress&) = default;
};
// "0x6040:00" into buf (at least 10 bytes).
inline const char* format(ObjectAddress a, char* buf, std::size_t size) noexcept {
  std::snprintf(buf, size, "0x%04X:%02X", a.index, a.sub);
  return buf;
}

// Little-endian access to wire bytes.
template <class T>
inline T get_le(const uint8_t* p) noexcept {
  static_assert(std::is_trivially_copyable_v<T>);
  using U = std::conditional_t<sizeof(T) == 1, uint8_t,
            std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;
  U u = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) u = static_cast<U>(u | (static_cast<U>(p[i]) << (8 * i)));
  T out;
  std::memcpy(&out, &u, sizeof(T));
  return out;
}
template <class T>
inline void put_le(uint8_t* p, T value) noexcept {
  static_assert(std::is_trivially_copyable_v<T>);
  using U = std::conditional_t<sizeof(T) == 1, uint8_t,
            std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>>;
  U u;
  std::memcpy(&u, &value, sizeof(T));
  for (std::size_t i = 0; i < sizeof(T); ++i) p[i] = static_cast<uint8_t>(u >> (8 * i));
}

}  // namespace cnc::canopen
