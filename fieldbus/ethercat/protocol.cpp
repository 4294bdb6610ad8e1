#include "fieldbus/ethercat/protocol.hpp"

namespace cnc::ethercat {

const char* command_name(Command c) noexcept {
  switch (c) {
    case Command::NOP: return "NOP";
    case Command::APRD: return "APRD";
    case Command::APWR: return "APWR";
    case Command::APRW: return "APRW";
    case Command::FPRD: return "FPRD";
    case Command::FPWR: return "FPWR";
    case Command::FPRW: return "FPRW";
    case Command::BRD: return "BRD";
    case Command::BWR: return "BWR";
    case Command::BRW: return "BRW";
    case Command::LRD: return "LRD";
    case Command::LWR: return "LWR";
    case Command::LRW: return "LRW";
    case Command::ARMW: return "ARMW";
    case Command::FRMW: return "FRMW";
  }
  return "unknown";
}

const char* al_state_name(uint8_t state) noexcept {
  switch (state & 0x0F) {
    case 1: return "INIT";
    case 2: return "PREOP";
    case 3: return "BOOT";
    case 4: return "SAFEOP";
    case 8: return "OP";
    default: return "unknown state";
  }
}

const char* al_status_text(uint16_t code) noexcept {
  switch (code) {
    case 0x0000: return "no error";
    case 0x0001: return "unspecified error";
    case 0x0002: return "no memory";
    case 0x0003: return "invalid device setup";
    case 0x0006: return "SII does not match firmware";
    case 0x0007: return "firmware update failed";
    case 0x000E: return "licence error";
    case 0x0011: return "invalid requested state change";
    case 0x0012: return "unknown requested state";
    case 0x0013: return "bootstrap not supported";
    case 0x0014: return "no valid firmware";
    case 0x0015: return "invalid mailbox configuration (BOOT)";
    case 0x0016: return "invalid mailbox configuration (PREOP)";
    case 0x0017: return "invalid sync manager configuration";
    case 0x0018: return "no valid inputs available";
    case 0x0019: return "no valid outputs";
    case 0x001A: return "synchronisation error";
    case 0x001B: return "sync manager watchdog";
    case 0x001C: return "invalid sync manager types";
    case 0x001D: return "invalid output configuration";
    case 0x001E: return "invalid input configuration";
    case 0x001F: return "invalid watchdog configuration";
    case 0x0020: return "slave needs cold start";
    case 0x0021: return "slave needs INIT";
    case 0x0022: return "slave needs PREOP";
    case 0x0023: return "slave needs SAFEOP";
    case 0x0024: return "invalid input mapping";
    case 0x0025: return "invalid output mapping";
    case 0x0026: return "inconsistent settings";
    case 0x0027: return "free-run not supported";
    case 0x0028: return "synchronisation mode not supported";
    case 0x0029: return "free-run needs 3-buffer mode";
    case 0x002A: return "background watchdog";
    case 0x002B: return "no valid inputs and outputs";
    case 0x002C: return "fatal sync error";
    case 0x002D: return "no sync error";
    case 0x002E: return "cycle time too small";
    case 0x0030: return "invalid DC SYNC configuration";
    case 0x0031: return "invalid DC latch configuration";
    case 0x0032: return "PLL error";
    case 0x0033: return "DC sync I/O error";
    case 0x0034: return "DC sync timeout";
    case 0x0035: return "invalid DC sync cycle time";
    case 0x0036: return "invalid SYNC0 cycle time";
    case 0x0037: return "invalid SYNC1 cycle time";
    case 0x0041: return "mailbox AoE error";
    case 0x0042: return "mailbox EoE error";
    case 0x0043: return "mailbox CoE error";
    case 0x0044: return "mailbox FoE error";
    case 0x0045: return "mailbox SoE error";
    case 0x004F: return "mailbox VoE error";
    case 0x0050: return "EEPROM no access";
    case 0x0051: return "EEPROM error";
    case 0x0060: return "slave restarted locally";
    case 0x0061: return "device identification value updated";
    case 0x00F0: return "application controller available";
    default: return code >= 0x8000 ? "vendor-specific error" : "unknown AL status code";
  }
}

const char* mailbox_error_text(uint16_t detail) noexcept {
  switch (detail) {
    case 1: return "syntax error";
    case 2: return "unsupported protocol";
    case 3: return "invalid channel";
    case 4: return "service not supported";
    case 5: return "invalid mailbox header";
    case 6: return "data too short";
    case 7: return "no more memory";
    case 8: return "inconsistent length";
    default: return "unknown mailbox error";
  }
}

uint8_t sii_crc8(const uint8_t* bytes, std::size_t n) noexcept {
  uint8_t crc = 0xFF;
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= bytes[i];
    for (int b = 0; b < 8; ++b) crc = static_cast<uint8_t>((crc & 0x80) ? (crc << 1) ^ 0x07 : crc << 1);
  }
  return crc;
}

}  // namespace cnc::ethercat
