// Error codes of CiA 301 (emergency messages, EMCY) and CiA 402 (drive
// faults, object 0x603F): one code space and one table of texts for every
// place that shows a code to a person: the drive layer's fault texts, the
// CANopen and EtherCAT (CoE) EMCY decoders, the operator screen.
// Pure functions over static data: realtime-safe, no allocation.
#pragma once

#include <cstdint>

namespace cnc::cia402 {

// The most specific text known for a code ("following error", "DC-link
// over-voltage"), else the text of its class (error_class_text). Never null.
const char* error_code_text(uint16_t code) noexcept;
// The class of a code by its high bits (CiA 301 table 21): "current,
// device output side", "monitoring: communication", "device specific".
const char* error_class_text(uint16_t code) noexcept;

// Codes the drive layer and the simulated drives name.
namespace err {
inline constexpr uint16_t kNone = 0x0000;
inline constexpr uint16_t kGeneric = 0x1000;
inline constexpr uint16_t kOverCurrent = 0x2310;
inline constexpr uint16_t kShortCircuit = 0x2320;
inline constexpr uint16_t kOverVoltage = 0x3210;
inline constexpr uint16_t kUnderVoltage = 0x3220;
inline constexpr uint16_t kOverTemperature = 0x4210;
inline constexpr uint16_t kParameter = 0x6320;
inline constexpr uint16_t kEncoder = 0x7305;
inline constexpr uint16_t kHeartbeat = 0x8130;
inline constexpr uint16_t kRpdoTimeout = 0x8250;
inline constexpr uint16_t kFollowingError = 0x8611;
inline constexpr uint16_t kReferenceLimit = 0x8612;
// Vendor-specific codes (0xFF00..0xFFFF) of this project's simulated drive
// (sim/cia402); a real drive's vendor codes mean what its manual says.
inline constexpr uint16_t kPositiveLimitSwitch = 0xFF01;
inline constexpr uint16_t kNegativeLimitSwitch = 0xFF02;
inline constexpr uint16_t kSoftwareLimit = 0xFF03;
inline constexpr uint16_t kSyncLost = 0xFF04;
}  // namespace err

}  // namespace cnc::cia402
