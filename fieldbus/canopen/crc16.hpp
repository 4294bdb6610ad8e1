// CRC-16-CCITT as SDO block transfer uses it (CiA 301 §7.2.4.3.16):
// polynomial x^16 + x^12 + x^5 + 1 (0x1021), initial value 0, no
// reflection, no final XOR. Incremental; realtime-safe.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cnc::canopen {

inline uint16_t crc16_ccitt(uint16_t crc, const uint8_t* data, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    crc = static_cast<uint16_t>(crc ^ (static_cast<uint16_t>(data[i]) << 8));
    for (int b = 0; b < 8; ++b) {
      crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021) : static_cast<uint16_t>(crc << 1);
    }
  }
  return crc;
}

}  // namespace cnc::canopen
