// Emergency messages (CiA 301 §7.2.7): decoding of the 8 bytes, the error
// register as text; the codes' texts come from the one table of
// cia402/error_codes.hpp.
// Realtime-safe: no allocation, texts are static or written into a buffer.
#pragma once

#include <cstddef>
#include <cstdint>

#include "fieldbus/can/frame.hpp"

namespace cnc::canopen {

struct Emcy {
  uint16_t code = 0;            // 0x0000: error reset / no error
  uint8_t error_register = 0;   // object 0x1001
  uint8_t vendor[5] = {};
  bool is_reset() const noexcept { return code == 0; }
};

// False when the frame is not an 8-byte EMCY payload (length below 8 is
// tolerated down to 3 bytes, as some devices send short EMCY).
bool decode_emcy(const can::Frame& f, Emcy& out) noexcept;
can::Frame encode_emcy(unsigned node_id, const Emcy& e) noexcept;

// "generic, current" for the set bits of 0x1001, into buf.
const char* error_register_text(uint8_t reg, char* buf, std::size_t size) noexcept;
// "EMCY 0x8611 following error (error register 0x21: generic, profile; vendor 00 00 00 00 00)"
const char* format_emcy(const Emcy& e, char* buf, std::size_t size) noexcept;

// Error register bits (0x1001).
enum ErrorRegisterBit : uint8_t {
  kErrRegGeneric = 0x01,
  kErrRegCurrent = 0x02,
  kErrRegVoltage = 0x04,
  kErrRegTemperature = 0x08,
  kErrRegCommunication = 0x10,
  kErrRegProfile = 0x20,
  kErrRegManufacturer = 0x80,
};

}  // namespace cnc::canopen
