// EtherCAT protocol constants shared by the master and the slave simulator:
// commands, ESC register addresses, AL states and status codes, SM/FMMU
// entries, mailbox and CoE headers (ETG.1000; facts from the project's
// reference/ethercat.md). Pure data and pure functions; realtime-safe.
#pragma once

#include <cstdint>
#include <cstring>

namespace cnc::ethercat {

inline constexpr uint16_t kEtherType = 0x88A4;
inline constexpr std::size_t kEthHeader = 14;
inline constexpr std::size_t kEcatHeader = 2;
inline constexpr std::size_t kDatagramHeader = 10;
inline constexpr std::size_t kWkcSize = 2;
inline constexpr std::size_t kMaxFrame = 1514;  // without FCS
inline constexpr std::size_t kMinFrame = 60;    // padded (64 with FCS)
inline constexpr std::size_t kMaxDatagramData = kMaxFrame - kEthHeader - kEcatHeader - kDatagramHeader - kWkcSize;

enum class Command : uint8_t {
  NOP = 0, APRD = 1, APWR = 2, APRW = 3, FPRD = 4, FPWR = 5, FPRW = 6, BRD = 7, BWR = 8, BRW = 9,
  LRD = 10, LWR = 11, LRW = 12, ARMW = 13, FRMW = 14,
};
const char* command_name(Command c) noexcept;

// Little-endian helpers.
inline uint16_t get16(const uint8_t* p) noexcept { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
inline uint32_t get32(const uint8_t* p) noexcept {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
inline uint64_t get64(const uint8_t* p) noexcept { return get32(p) | (static_cast<uint64_t>(get32(p + 4)) << 32); }
inline void put16(uint8_t* p, uint16_t v) noexcept {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
inline void put32(uint8_t* p, uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
inline void put64(uint8_t* p, uint64_t v) noexcept {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

// Position addressing: the slave at ring position p (0-based) is ADP = -p.
inline uint16_t auto_increment_address(unsigned position) noexcept {
  return static_cast<uint16_t>(0x10000u - position);
}
inline uint32_t physical_address(uint16_t adp, uint16_t ado) noexcept {
  return static_cast<uint32_t>(adp) | (static_cast<uint32_t>(ado) << 16);
}

namespace reg {
inline constexpr uint16_t kType = 0x0000;
inline constexpr uint16_t kFmmuCount = 0x0004;
inline constexpr uint16_t kSmCount = 0x0005;
inline constexpr uint16_t kPortDescriptor = 0x0007;
inline constexpr uint16_t kFeatures = 0x0008;
inline constexpr uint16_t kStationAddress = 0x0010;
inline constexpr uint16_t kStationAlias = 0x0012;
inline constexpr uint16_t kDlControl = 0x0100;
inline constexpr uint16_t kDlStatus = 0x0110;
inline constexpr uint16_t kAlControl = 0x0120;
inline constexpr uint16_t kAlStatus = 0x0130;
inline constexpr uint16_t kAlStatusCode = 0x0134;
inline constexpr uint16_t kPdiControl = 0x0140;
inline constexpr uint16_t kEventMask = 0x0200;
inline constexpr uint16_t kRxErrors = 0x0300;
inline constexpr uint16_t kWatchdogDivider = 0x0400;
inline constexpr uint16_t kWatchdogPd = 0x0420;
inline constexpr uint16_t kWatchdogStatus = 0x0440;
inline constexpr uint16_t kWatchdogCounter = 0x0442;
inline constexpr uint16_t kSiiOwner = 0x0500;
inline constexpr uint16_t kSiiControl = 0x0502;
inline constexpr uint16_t kSiiAddress = 0x0504;
inline constexpr uint16_t kSiiData = 0x0508;
inline constexpr uint16_t kFmmu0 = 0x0600;
inline constexpr uint16_t kSm0 = 0x0800;
inline constexpr uint16_t kDcPortTime0 = 0x0900;
inline constexpr uint16_t kDcSystemTime = 0x0910;
inline constexpr uint16_t kDcReceiveTimePu = 0x0918;
inline constexpr uint16_t kDcSystemOffset = 0x0920;
inline constexpr uint16_t kDcSystemDelay = 0x0928;
inline constexpr uint16_t kDcSystemDiff = 0x092C;
inline constexpr uint16_t kDcSpeedStart = 0x0930;
inline constexpr uint16_t kDcFilterDepth = 0x0934;
inline constexpr uint16_t kDcCyclicControl = 0x0980;
inline constexpr uint16_t kDcActivation = 0x0981;
inline constexpr uint16_t kDcSync0Status = 0x098E;
inline constexpr uint16_t kDcStartTime = 0x0990;
inline constexpr uint16_t kDcSync0Cycle = 0x09A0;
inline constexpr uint16_t kDcSync1Cycle = 0x09A4;
inline constexpr uint16_t kProcessRam = 0x1000;
}  // namespace reg

// SII control/status bits (0x0502).
namespace sii {
inline constexpr uint16_t kRead = 0x0100;
inline constexpr uint16_t kWrite = 0x0200;
inline constexpr uint16_t kReload = 0x0400;
inline constexpr uint16_t kRead8 = 0x0040;
inline constexpr uint16_t kChecksumError = 0x0800;
inline constexpr uint16_t kError = 0x2000;
inline constexpr uint16_t kBusy = 0x8000;
}  // namespace sii

enum class AlState : uint8_t { None = 0, Init = 1, PreOp = 2, Boot = 3, SafeOp = 4, Op = 8 };
inline constexpr uint16_t kAlErrorFlag = 0x10;  // AL status error indication / AL control acknowledge
const char* al_state_name(uint8_t state) noexcept;  // "INIT", "PREOP", ..., "unknown"
// AL status code as text: "SM watchdog", "invalid mailbox configuration (PREOP)", ...
const char* al_status_text(uint16_t code) noexcept;

namespace al {
inline constexpr uint16_t kNoError = 0x0000;
inline constexpr uint16_t kUnspecified = 0x0001;
inline constexpr uint16_t kInvalidStateChange = 0x0011;
inline constexpr uint16_t kUnknownState = 0x0012;
inline constexpr uint16_t kBootNotSupported = 0x0013;
inline constexpr uint16_t kInvalidMailboxPreop = 0x0016;
inline constexpr uint16_t kInvalidSmConfig = 0x0017;
inline constexpr uint16_t kNoValidOutputs = 0x0019;
inline constexpr uint16_t kSyncError = 0x001A;
inline constexpr uint16_t kSmWatchdog = 0x001B;
inline constexpr uint16_t kInvalidOutputConfig = 0x001D;
inline constexpr uint16_t kInvalidInputConfig = 0x001E;
inline constexpr uint16_t kInvalidInputMapping = 0x0024;
inline constexpr uint16_t kInvalidOutputMapping = 0x0025;
inline constexpr uint16_t kInvalidDcSync = 0x0030;
inline constexpr uint16_t kInvalidDcCycle = 0x0035;
}  // namespace al

// One sync manager entry (0x0800 + 8 n).
struct SmEntry {
  uint16_t start = 0, length = 0;
  uint8_t control = 0, status = 0, activate = 0, pdi_control = 0;
  void encode(uint8_t* p) const noexcept {
    put16(p, start);
    put16(p + 2, length);
    p[4] = control;
    p[5] = status;
    p[6] = activate;
    p[7] = pdi_control;
  }
  static SmEntry decode(const uint8_t* p) noexcept {
    return SmEntry{get16(p), get16(p + 2), p[4], p[5], p[6], p[7]};
  }
  bool enabled() const noexcept { return (activate & 1) != 0; }
  bool is_mailbox() const noexcept { return (control & 0x03) == 0x02; }
  bool master_writes() const noexcept { return (control & 0x0C) == 0x04; }
};
namespace sm {
inline constexpr uint8_t kMailboxOut = 0x26;  // master -> slave, mailbox, ECAT + AL IRQ
inline constexpr uint8_t kMailboxIn = 0x22;
inline constexpr uint8_t kOutputs = 0x64;     // buffered, written by master, watchdog trigger
inline constexpr uint8_t kInputs = 0x20;
inline constexpr uint8_t kStatusFull = 0x08;
inline constexpr uint8_t kWatchdogTrigger = 0x40;  // control bit 6: writes retrigger the process-data watchdog
}  // namespace sm
// Watchdog divider 2498: (2498 + 2) x 40 ns = 100 us per unit of 0x0420.
inline constexpr uint16_t kWatchdogDivider100us = 2498;
inline constexpr int64_t watchdog_ns(uint16_t divider, uint16_t time) noexcept {
  return (int64_t{divider} + 2) * 40 * time;
}

// One FMMU entry (0x0600 + 16 n).
struct FmmuEntry {
  uint32_t logical_start = 0;
  uint16_t length = 0;
  uint8_t logical_start_bit = 0, logical_stop_bit = 7;
  uint16_t physical_start = 0;
  uint8_t physical_start_bit = 0, type = 0, activate = 0;
  void encode(uint8_t* p) const noexcept {
    std::memset(p, 0, 16);
    put32(p, logical_start);
    put16(p + 4, length);
    p[6] = logical_start_bit;
    p[7] = logical_stop_bit;
    put16(p + 8, physical_start);
    p[10] = physical_start_bit;
    p[11] = type;
    p[12] = activate;
  }
  static FmmuEntry decode(const uint8_t* p) noexcept {
    FmmuEntry f;
    f.logical_start = get32(p);
    f.length = get16(p + 4);
    f.logical_start_bit = p[6];
    f.logical_stop_bit = p[7];
    f.physical_start = get16(p + 8);
    f.physical_start_bit = p[10];
    f.type = p[11];
    f.activate = p[12];
    return f;
  }
};

// Mailbox (6 B header) and CoE (2 B header).
inline constexpr std::size_t kMailboxHeader = 6;
enum class MailboxType : uint8_t { Error = 0, AoE = 1, EoE = 2, CoE = 3, FoE = 4, SoE = 5, VoE = 15 };
enum class CoeService : uint8_t {
  Emergency = 1, SdoRequest = 2, SdoResponse = 3, TxPdo = 4, RxPdo = 5, SdoInfo = 8,
};
struct MailboxHeader {
  uint16_t length = 0;  // bytes after the header
  uint16_t address = 0;
  uint8_t channel = 0, priority = 0;
  MailboxType type = MailboxType::CoE;
  uint8_t counter = 0;  // 1..7, 0 = unused
  void encode(uint8_t* p) const noexcept {
    put16(p, length);
    put16(p + 2, address);
    p[4] = static_cast<uint8_t>((channel & 0x3F) | (priority << 6));
    p[5] = static_cast<uint8_t>((static_cast<uint8_t>(type) & 0x0F) | ((counter & 7) << 4));
  }
  static MailboxHeader decode(const uint8_t* p) noexcept {
    MailboxHeader h;
    h.length = get16(p);
    h.address = get16(p + 2);
    h.channel = p[4] & 0x3F;
    h.priority = static_cast<uint8_t>(p[4] >> 6);
    h.type = static_cast<MailboxType>(p[5] & 0x0F);
    h.counter = static_cast<uint8_t>((p[5] >> 4) & 7);
    return h;
  }
};
inline uint16_t coe_header(CoeService s, uint16_t number = 0) noexcept {
  return static_cast<uint16_t>((number & 0x1FF) | (static_cast<uint16_t>(s) << 12));
}
inline CoeService coe_service(uint16_t header) noexcept { return static_cast<CoeService>(header >> 12); }
const char* mailbox_error_text(uint16_t detail) noexcept;

// CRC-8 of the SII configuration area (poly 0x07, init 0xFF, words 0-6).
uint8_t sii_crc8(const uint8_t* bytes, std::size_t n) noexcept;

}  // namespace cnc::ethercat
