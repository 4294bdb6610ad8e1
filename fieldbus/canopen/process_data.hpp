// Where one mapped object lives in a node's cyclic process data: a pointer
// to the PDO's bytes, a bit offset and a bit length. Read and written by the
// servo thread only (between the master's read and write functions), with
// little-endian bit packing and sign extension. No allocation, no locks.
// The same shape fits any fieldbus whose process data is a byte image.
#pragma once

#include <cstdint>
#include <cstring>
#include <type_traits>

#include "fieldbus/canopen/pdo.hpp"

namespace cnc::canopen {

struct PdoSlot {
  uint8_t* bytes = nullptr;
  uint16_t bit_offset = 0;
  uint8_t bit_length = 0;
  explicit operator bool() const noexcept { return bytes != nullptr; }
};

template <class T>
inline T read_slot(const PdoSlot& s) noexcept {
  static_assert(std::is_arithmetic_v<T>);
  uint8_t buf[8] = {};
  if (!s.bytes) return T{};
  const unsigned bits = s.bit_length > 64 ? 64 : s.bit_length;
  copy_bits(s.bytes, s.bit_offset, buf, 0, bits);
  if constexpr (std::is_floating_point_v<T>) {
    if (bits == 32) return static_cast<T>(get_le<float>(buf));
    return static_cast<T>(get_le<double>(buf));
  } else {
    uint64_t v = get_le<uint64_t>(buf);
    if constexpr (std::is_signed_v<T>) {
      if (bits > 0 && bits < 64 && (v >> (bits - 1)) & 1u) v |= ~uint64_t{0} << bits;
    }
    return static_cast<T>(v);
  }
}

template <class T>
inline void write_slot(const PdoSlot& s, T value) noexcept {
  static_assert(std::is_arithmetic_v<T>);
  if (!s.bytes) return;
  uint8_t buf[8] = {};
  const unsigned bits = s.bit_length > 64 ? 64 : s.bit_length;
  if constexpr (std::is_floating_point_v<T>) {
    if (bits == 32) put_le<float>(buf, static_cast<float>(value));
    else put_le<double>(buf, static_cast<double>(value));
  } else {
    put_le<uint64_t>(buf, static_cast<uint64_t>(static_cast<std::conditional_t<std::is_signed_v<T>, int64_t, uint64_t>>(value)));
  }
  copy_bits(buf, 0, s.bytes, s.bit_offset, bits);
}

}  // namespace cnc::canopen
