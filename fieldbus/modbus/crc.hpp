// The Modbus RTU CRC-16 (polynomial 0xA001 reflected, initial 0xFFFF,
// transmitted low byte first; Modbus over Serial Line V1.02, 6.2.2). Used
// where libmodbus does not frame: the Huanyang protocol's raw frames.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cnc::modbus {

constexpr uint16_t crc16(const uint8_t* data, std::size_t size) noexcept {
  uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 1U) ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : static_cast<uint16_t>(crc >> 1);
  }
  return crc;
}

// True when the last two bytes of a frame are the CRC of the bytes before.
constexpr bool crc_ok(const uint8_t* frame, std::size_t size) noexcept {
  if (size < 3) return false;
  const uint16_t c = crc16(frame, size - 2);
  return frame[size - 2] == (c & 0xFF) && frame[size - 1] == (c >> 8);
}

}  // namespace cnc::modbus
