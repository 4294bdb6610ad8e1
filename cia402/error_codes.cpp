#include "cia402/error_codes.hpp"

namespace cnc::cia402 {

const char* error_class_text(uint16_t code) noexcept {
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

const char* error_code_text(uint16_t code) noexcept {
  struct Known {
    uint16_t code;
    const char* text;
  };
  // CiA 301 (communication, 0x81xx/0x82xx) and CiA 402 (drive) codes a
  // machine builder meets most often, in code order.
  static constexpr Known kKnown[] = {
      {0x0000, "error reset or no error"},
      {0x1000, "generic error"},
      {0x2110, "short circuit / earth leakage (input)"},
      {0x2200, "internal current"},
      {0x2220, "continuous over-current (device)"},
      {0x2300, "current on the device output side"},
      {0x2310, "continuous over-current"},
      {0x2320, "short circuit / earth leakage (motor)"},
      {0x2330, "earth leakage"},
      {0x3110, "mains over-voltage"},
      {0x3120, "mains under-voltage"},
      {0x3130, "phase failure"},
      {0x3210, "DC-link over-voltage"},
      {0x3220, "DC-link under-voltage"},
      {0x4110, "excess ambient temperature"},
      {0x4210, "device over-temperature"},
      {0x4310, "drive over-temperature"},
      {0x4410, "supply over-temperature"},
      {0x5112, "supply low voltage (24 V)"},
      {0x5400, "power section"},
      {0x5441, "enable input (safe torque off) missing"},
      {0x5530, "data storage (EEPROM)"},
      {0x6010, "software reset (watchdog)"},
      {0x6320, "parameter error"},
      {0x7121, "motor blocked"},
      {0x7300, "sensor"},
      {0x7305, "incremental encoder 1 broken"},
      {0x7306, "incremental encoder 2 broken"},
      {0x7310, "speed feedback"},
      {0x7320, "position feedback"},
      {0x7500, "communication"},
      {0x8110, "CAN overrun (objects lost)"},
      {0x8120, "CAN in error passive mode"},
      {0x8130, "life guard or heartbeat error"},
      {0x8140, "recovered from bus off"},
      {0x8150, "CAN-ID collision"},
      {0x8210, "PDO not processed due to length error"},
      {0x8220, "PDO length exceeded"},
      {0x8230, "DAM MPDO not processed, destination object not available"},
      {0x8240, "unexpected SYNC data length"},
      {0x8250, "RPDO timeout"},
      {0x8311, "excess torque"},
      {0x8400, "velocity speed controller"},
      {0x8500, "position controller"},
      {0x8600, "positioning controller"},
      {0x8611, "following error"},
      {0x8612, "reference limit"},
      {0x8700, "sync controller"},
      {0x9000, "external error"},
      {err::kPositiveLimitSwitch, "positive travel limit switch"},
      {err::kNegativeLimitSwitch, "negative travel limit switch"},
      {err::kSoftwareLimit, "software position limit"},
      {err::kSyncLost, "SYNC lost (cyclic set-points stopped)"},
  };
  for (const Known& k : kKnown) {
    if (k.code == code) return k.text;
  }
  return error_class_text(code);
}

}  // namespace cnc::cia402
