// Where one object lives in a fieldbus process image (CANopen PDO bytes,
// the EtherCAT frame's process data): a pointer to the image, a bit offset
// and a bit length, little-endian as both buses pack them. The one slot
// type of the project: bus masters hand their slots out (object pins, the
// drive layer's link) and never convert them. Read and written by the
// servo thread between the bus's read and write functions: no allocation,
// no locks.
#pragma once

#include <bit>
#include <cstdint>
#include <type_traits>

namespace cnc {

struct ProcessSlot {
  uint8_t* bytes = nullptr;
  uint16_t bit_offset = 0;
  uint8_t bit_length = 0;
  explicit operator bool() const noexcept { return bytes != nullptr; }
};

namespace detail {
inline uint64_t load_bits(const ProcessSlot& s) noexcept {
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
inline void store_bits(const ProcessSlot& s, uint64_t v) noexcept {
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

// The slot's value: integers sign-extended for signed T; floating point
// from a 32-bit (REAL32) or 64-bit (REAL64) object. T{} when unmapped.
template <class T>
inline T read_slot(const ProcessSlot& s) noexcept {
  static_assert(std::is_arithmetic_v<T>);
  if (!s.bytes || s.bit_length == 0) return T{};
  uint64_t v = detail::load_bits(s);
  if constexpr (std::is_floating_point_v<T>) {
    if (s.bit_length == 32) return static_cast<T>(std::bit_cast<float>(static_cast<uint32_t>(v)));
    return static_cast<T>(std::bit_cast<double>(v));
  } else {
    if constexpr (std::is_signed_v<T>) {
      if (s.bit_length < 64 && ((v >> (s.bit_length - 1)) & 1u)) v |= ~uint64_t{0} << s.bit_length;
    }
    return static_cast<T>(v);
  }
}

// Writes `value` into the slot (the low bit_length bits; floating point as
// REAL32 or REAL64 by the slot's length). Nothing when unmapped.
template <class T>
inline void write_slot(const ProcessSlot& s, T value) noexcept {
  static_assert(std::is_arithmetic_v<T>);
  if (!s.bytes || s.bit_length == 0) return;
  if constexpr (std::is_floating_point_v<T>) {
    if (s.bit_length == 32) detail::store_bits(s, std::bit_cast<uint32_t>(static_cast<float>(value)));
    else detail::store_bits(s, std::bit_cast<uint64_t>(static_cast<double>(value)));
  } else {
    detail::store_bits(s, static_cast<uint64_t>(static_cast<std::conditional_t<std::is_signed_v<T>, int64_t, uint64_t>>(value)));
  }
}

}  // namespace cnc
