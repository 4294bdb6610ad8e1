#include "fieldbus/canopen/emcy.hpp"

#include <cstdio>

#include "cia402/error_codes.hpp"
#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

bool decode_emcy(const can::Frame& f, Emcy& out) noexcept {
  if (f.is_remote() || f.is_error() || f.len < 3) return false;
  out = Emcy{};
  out.code = get_le<uint16_t>(&f.data[0]);
  out.error_register = f.data[2];
  for (std::size_t i = 0; i < 5 && 3 + i < f.len; ++i) out.vendor[i] = f.data[3 + i];
  return true;
}

can::Frame encode_emcy(unsigned node_id, const Emcy& e) noexcept {
  can::Frame f = can::Frame::make(cob::emcy(node_id), {0, 0, 0, 0, 0, 0, 0, 0});
  put_le<uint16_t>(&f.data[0], e.code);
  f.data[2] = e.error_register;
  for (std::size_t i = 0; i < 5; ++i) f.data[3 + i] = e.vendor[i];
  return f;
}

const char* error_register_text(uint8_t reg, char* buf, std::size_t size) noexcept {
  if (size == 0) return buf;
  buf[0] = '\0';
  std::size_t n = 0;
  static const char* const names[8] = {"generic", "current", "voltage", "temperature",
                                       "communication", "profile", "reserved", "manufacturer"};
  for (int bit = 0; bit < 8; ++bit) {
    if (!(reg & (1u << bit)) || n >= size) continue;
    const int w = std::snprintf(buf + n, size - n, "%s%s", n ? ", " : "", names[bit]);
    if (w > 0) n += static_cast<std::size_t>(w);
  }
  if (n == 0) std::snprintf(buf, size, "none");
  return buf;
}

const char* format_emcy(const Emcy& e, char* buf, std::size_t size) noexcept {
  char reg[96];
  std::snprintf(buf, size, "EMCY 0x%04X %s (error register 0x%02X: %s; vendor %02X %02X %02X %02X %02X)", e.code,
                cia402::error_code_text(e.code), e.error_register, error_register_text(e.error_register, reg, sizeof reg),
                e.vendor[0], e.vendor[1], e.vendor[2], e.vendor[3], e.vendor[4]);
  return buf;
}

}  // namespace cnc::canopen
