#include "fieldbus/modbus/huanyang.hpp"

#include "fieldbus/modbus/crc.hpp"

namespace cnc::modbus::hy {

Frame make_request(uint8_t slave, uint8_t function, const uint8_t* data, uint8_t length) noexcept {
  Frame f;
  if (frame_size(length) > f.bytes.size()) return f;
  f.bytes[0] = slave;
  f.bytes[1] = function;
  f.bytes[2] = length;
  for (uint8_t i = 0; i < length; ++i) f.bytes[3U + i] = data[i];
  const std::size_t n = 3U + length;
  const uint16_t c = crc16(f.bytes.data(), n);
  f.bytes[n] = static_cast<uint8_t>(c & 0xFF);
  f.bytes[n + 1] = static_cast<uint8_t>(c >> 8);
  f.size = n + 2;
  return f;
}

Frame control(uint8_t slave, uint8_t control_data) noexcept { return make_request(slave, kWriteControlData, &control_data, 1); }

Frame set_frequency(uint8_t slave, uint16_t centi_hz) noexcept {
  const uint8_t d[2] = {static_cast<uint8_t>(centi_hz >> 8), static_cast<uint8_t>(centi_hz & 0xFF)};
  return make_request(slave, kWriteFrequency, d, 2);
}

// The monitor number followed by two padding bytes, as the manual's
// examples send it.
Frame read_status(uint8_t slave, uint8_t monitor) noexcept {
  const uint8_t d[3] = {monitor, 0, 0};
  return make_request(slave, kReadControlStatus, d, 3);
}

const char* to_string(ParseError e) noexcept {
  switch (e) {
    case ParseError::None: return "ok";
    case ParseError::Short: return "reply too short";
    case ParseError::BadCrc: return "CRC error";
    case ParseError::WrongSlave: return "reply from another slave";
    case ParseError::WrongFunction: return "reply to another function";
    case ParseError::BadLength: return "length byte does not match the frame";
  }
  return "?";
}

Reply parse_reply(const uint8_t* frame, std::size_t size, uint8_t slave, uint8_t function) noexcept {
  Reply r;
  if (size < 5) {
    r.error = ParseError::Short;
    return r;
  }
  if (frame_size(frame[2]) != size || frame[2] > r.data.size()) {
    r.error = ParseError::BadLength;
    return r;
  }
  if (!crc_ok(frame, size)) {
    r.error = ParseError::BadCrc;
    return r;
  }
  if (frame[0] != slave) {
    r.error = ParseError::WrongSlave;
    return r;
  }
  if (frame[1] != function) {
    r.error = ParseError::WrongFunction;
    return r;
  }
  r.function = frame[1];
  r.length = frame[2];
  for (uint8_t i = 0; i < r.length; ++i) r.data[i] = frame[3U + i];
  return r;
}

std::optional<uint16_t> monitor_value(const Reply& r, uint8_t monitor) noexcept {
  if (r.error != ParseError::None || r.length < 3 || r.data[0] != monitor) return std::nullopt;
  return static_cast<uint16_t>((r.data[1] << 8) | r.data[2]);
}

}  // namespace cnc::modbus::hy
