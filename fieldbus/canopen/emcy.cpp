#include "fieldbus/canopen/emcy.hpp"

#include <cstdio>

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

const char* emcy_class_text(uint16_t code) noexcept {
  if (code == 0) return "error reset or no error";
  switch (code >> 12) {
    case 0x1: return "generic error";
    case 0x2:
      switch (code & 0xFF00) {
        case 0x2100: return "current, device input side";
        case 0x2200: return "current inside the device";
        case 0x2300: return "current, device output side";
        default: return "current";
      }
    case 0x3:
      switch (code & 0xFF00) {
        case 0x3100: return "mains voltage";
        case 0x3200: return "voltage inside the device";
        case 0x3300: return "output voltage";
        default: return "voltage";
      }
    case 0x4:
      switch (code & 0xFF00) {
        case 0x4100: return "ambient temperature";
        case 0x4200: return "device temperature";
        default: return "temperature";
      }
    case 0x5: return "device hardware";
    case 0x6:
      switch (code & 0xFF00) {
        case 0x6100: return "internal software";
        case 0x6200: return "user software";
        case 0x6300: return "data set";
        default: return "device software";
      }
    case 0x7: return "additional modules";
    case 0x8:
      switch (code & 0xFF00) {
        case 0x8100: return "monitoring: communication";
        case 0x8200: return "monitoring: protocol error";
        default: return "monitoring";
      }
    case 0x9: return "external error";
    case 0xF: return (code & 0xFF00) == 0xFF00 ? "device specific" : "additional functions";
    default: return "unknown error class";
  }
}

const char* emcy_code_text(uint16_t code) noexcept {
  switch (code) {
    case 0x0000: return "error reset or no error";
    case 0x1000: return "generic error";
    // CiA 402 drive codes
    case 0x2310: return "continuous over-current";
    case 0x2320: return "short circuit";
    case 0x3210: return "DC-link over-voltage";
    case 0x3220: return "DC-link under-voltage";
    case 0x4210: return "device over-temperature";
    case 0x6320: return "parameter error";
    case 0x7305: return "incremental encoder 1";
    case 0x8400: return "velocity controller";
    case 0x8500: return "position controller";
    case 0x8600: return "positioning controller";
    case 0x8611: return "following error";
    case 0x8612: return "reference limit";
    // CiA 301 communication codes
    case 0x8110: return "CAN overrun (objects lost)";
    case 0x8120: return "CAN in error-passive mode";
    case 0x8130: return "life guard or heartbeat error";
    case 0x8140: return "recovered from bus-off";
    case 0x8150: return "CAN-ID collision";
    case 0x8210: return "PDO not processed due to length error";
    case 0x8220: return "PDO length exceeded";
    case 0x8230: return "DAM MPDO not processed, destination object not available";
    case 0x8240: return "unexpected SYNC data length";
    case 0x8250: return "RPDO timeout";
    default: return emcy_class_text(code);
  }
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
                emcy_code_text(e.code), e.error_register, error_register_text(e.error_register, reg, sizeof reg),
                e.vendor[0], e.vendor[1], e.vendor[2], e.vendor[3], e.vendor[4]);
  return buf;
}

}  // namespace cnc::canopen
