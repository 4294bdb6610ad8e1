// The Huanyang HY VFD protocol: RS-485 RTU framing with its own function
// codes (slave, function, length, data[length], CRC), not Modbus registers.
// Pure frame building and parsing, testable byte by byte; the link sends
// the frames with libmodbus's raw request API and reads the answers itself.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace cnc::modbus::hy {

// Function codes (Huanyang manual, communication chapter).
enum Function : uint8_t {
  kReadFunctionData = 0x01,   // PDxxx parameter read
  kWriteFunctionData = 0x02,  // PDxxx parameter write
  kWriteControlData = 0x03,   // run / stop / direction
  kReadControlStatus = 0x04,  // the monitor values below
  kWriteFrequency = 0x05,     // frequency reference, 0.01 Hz
};

// Control data (function 0x03).
inline constexpr uint8_t kControlRunForward = 0x01;
inline constexpr uint8_t kControlRunReverse = 0x11;
inline constexpr uint8_t kControlStop = 0x08;

// Control status byte answered to function 0x03.
inline constexpr uint8_t kStatusRunning = 0x08;  // bit 3: running
inline constexpr uint8_t kStatusReverse = 0x20;  // bit 5: running in reverse

// Monitor values of function 0x04.
enum Monitor : uint8_t {
  kSetFrequency = 0x00,     // 0.01 Hz
  kOutputFrequency = 0x01,  // 0.01 Hz
  kOutputCurrent = 0x02,    // 0.1 A
  kRotation = 0x03,         // rpm
  kDcVoltage = 0x04,        // 0.1 V
  kAcVoltage = 0x05,        // 0.1 V
  kTemperature = 0x07,      // degrees C
};

struct Frame {
  std::array<uint8_t, 16> bytes{};
  std::size_t size = 0;
};

// A complete request frame, CRC included (what goes on the wire).
Frame make_request(uint8_t slave, uint8_t function, const uint8_t* data, uint8_t length) noexcept;
Frame control(uint8_t slave, uint8_t control_data) noexcept;
Frame set_frequency(uint8_t slave, uint16_t centi_hz) noexcept;
Frame read_status(uint8_t slave, uint8_t monitor) noexcept;

// Length of a frame whose first three bytes (slave, function, length) are
// known: 3 + length + 2.
constexpr std::size_t frame_size(uint8_t length) noexcept { return 3U + length + 2U; }

enum class ParseError { None, Short, BadCrc, WrongSlave, WrongFunction, BadLength };
const char* to_string(ParseError e) noexcept;

struct Reply {
  ParseError error = ParseError::None;
  uint8_t function = 0;
  uint8_t length = 0;
  std::array<uint8_t, 8> data{};
};

// Checks a reply to `function` from `slave`: size, CRC, slave, function.
Reply parse_reply(const uint8_t* frame, std::size_t size, uint8_t slave, uint8_t function) noexcept;

// The 16-bit value of a monitor reply (data: monitor, high, low).
std::optional<uint16_t> monitor_value(const Reply& r, uint8_t monitor) noexcept;

}  // namespace cnc::modbus::hy
