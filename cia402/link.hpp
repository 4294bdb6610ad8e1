// What a fieldbus gives the drive layer, independent of the transport
// (CANopen today, EtherCAT CoE next): per drive, where each cyclically
// mapped object lives in the process image, a realtime request/poll path
// for the few objects that are not mapped (mode, touch probe, error code),
// a blocking path for configuration at start-up, and the health of the
// link. Slots are read and written by the servo thread only, between the
// bus's read and write functions; never allocate, never block there.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>

#include "cia402/profile.hpp"

namespace cnc::cia402 {

// One object in a byte image: pointer, bit offset, bit length
// (little-endian, as CANopen PDOs and EtherCAT process data are).
struct Slot {
  uint8_t* bytes = nullptr;
  uint16_t bit_offset = 0;
  uint8_t bit_length = 0;
  explicit operator bool() const noexcept { return bytes != nullptr; }
};

namespace detail {
inline uint64_t load_bits(const Slot& s) noexcept {
  uint64_t v = 0;
  const unsigned n = s.bit_length > 64 ? 64 : s.bit_length;
  if ((s.bit_offset & 7) == 0 && (n & 7) == 0) {
    const uint8_t* p = s.bytes + s.bit_offset / 8;
    for (unsigned i = 0; i < n / 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
    return v;
  }
  for (unsigned i = 0; i < n; ++i) {
    const unsigned b = s.bit_offset + i;
    if ((s.bytes[b / 8] >> (b % 8)) & 1u) v |= uint64_t{1} << i;
  }
  return v;
}
inline void store_bits(const Slot& s, uint64_t v) noexcept {
  const unsigned n = s.bit_length > 64 ? 64 : s.bit_length;
  if ((s.bit_offset & 7) == 0 && (n & 7) == 0) {
    uint8_t* p = s.bytes + s.bit_offset / 8;
    for (unsigned i = 0; i < n / 8; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
    return;
  }
  for (unsigned i = 0; i < n; ++i) {
    const unsigned b = s.bit_offset + i;
    const uint8_t m = static_cast<uint8_t>(1u << (b % 8));
    if ((v >> i) & 1u) s.bytes[b / 8] |= m;
    else s.bytes[b / 8] = static_cast<uint8_t>(s.bytes[b / 8] & ~m);
  }
}
}  // namespace detail

// Integer value of a slot, sign-extended for signed T; 0 when unmapped.
template <class T>
inline T get_slot(const Slot& s) noexcept {
  static_assert(std::is_integral_v<T>);
  if (!s.bytes || s.bit_length == 0) return T{};
  uint64_t v = detail::load_bits(s);
  if constexpr (std::is_signed_v<T>) {
    if (s.bit_length < 64 && ((v >> (s.bit_length - 1)) & 1u)) v |= ~uint64_t{0} << s.bit_length;
  }
  return static_cast<T>(v);
}
template <class T>
inline void put_slot(const Slot& s, T value) noexcept {
  static_assert(std::is_integral_v<T>);
  if (!s.bytes || s.bit_length == 0) return;
  detail::store_bits(s, static_cast<uint64_t>(static_cast<std::conditional_t<std::is_signed_v<T>, int64_t, uint64_t>>(value)));
}

// Health of one drive's link, refreshed by the bus every cycle.
struct LinkHealth {
  bool operational = false;    // the device exchanges process data (CANopen Operational, EtherCAT OP)
  bool inputs_fresh = false;   // this cycle's inputs answered the last cycle (else they are stale)
  bool lost = false;           // heartbeat lost, device reset, or left the cyclic state
  uint16_t emcy_code = 0;      // last emergency code (0 after an error reset)
  uint32_t emcy_count = 0;
};

// Result of an acyclic realtime request.
struct AcyclicResult {
  uint32_t abort_code = 0;  // 0 = done
  uint32_t value = 0;       // reads
};

// Result of a blocking (non-realtime) transfer at start-up.
struct ConfigResult {
  bool ok = false;
  uint32_t abort_code = 0;
  uint64_t value = 0;  // reads, little-endian up to 8 bytes
  std::string text;    // "SDO download 0x6098:00 aborted by the server: 0x06090030 value range exceeded"
};

class DriveLink {
 public:
  virtual ~DriveLink() = default;

  // Name of the bus for messages ("canopen.0").
  virtual const std::string& name() const noexcept = 0;
  // Drive "address" is the node-ID on CANopen, the ring position on EtherCAT.
  virtual bool has_device(int address) const noexcept = 0;

  // --- non-realtime (construction, start-up) ---
  // Where a mapped object lives: outputs are written by the master,
  // inputs read; an empty slot when the object is not mapped.
  virtual Slot output(int address, Object o) const noexcept = 0;
  virtual Slot input(int address, Object o) const noexcept = 0;
  // Blocking transfers for configuration (never from the servo thread).
  virtual ConfigResult read_wait(int address, Object o, unsigned size) = 0;
  virtual ConfigResult write_wait(int address, Object o, uint64_t value, unsigned size) = 0;
  // Cycle period of the bus, ns.
  virtual int64_t cycle_ns() const noexcept = 0;

  // --- realtime (servo thread) ---
  virtual LinkHealth health(int address) const noexcept = 0;
  // Expedited acyclic access (<= 4 bytes): a handle, or -1 when busy.
  virtual int request_read(int address, Object o) noexcept = 0;
  virtual int request_write(int address, Object o, uint32_t value, unsigned size) noexcept = 0;
  // True once, when the request has finished (result in `out`).
  virtual bool poll(int handle, AcyclicResult& out) noexcept = 0;
};

}  // namespace cnc::cia402
