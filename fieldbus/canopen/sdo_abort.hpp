// SDO abort codes (CiA 301 §7.2.4.3.17) and their meaning as text.
#pragma once

#include <cstdint>

namespace cnc::canopen {

namespace abort_code {
inline constexpr uint32_t kToggleBit = 0x05030000;
inline constexpr uint32_t kTimeout = 0x05040000;
inline constexpr uint32_t kCommandSpecifier = 0x05040001;
inline constexpr uint32_t kBlockSize = 0x05040002;
inline constexpr uint32_t kSequenceNumber = 0x05040003;
inline constexpr uint32_t kCrc = 0x05040004;
inline constexpr uint32_t kOutOfMemory = 0x05040005;
inline constexpr uint32_t kUnsupportedAccess = 0x06010000;
inline constexpr uint32_t kWriteOnly = 0x06010001;
inline constexpr uint32_t kReadOnly = 0x06010002;
inline constexpr uint32_t kNoObject = 0x06020000;
inline constexpr uint32_t kNotMappable = 0x06040041;
inline constexpr uint32_t kPdoLength = 0x06040042;
inline constexpr uint32_t kParameterIncompatible = 0x06040043;
inline constexpr uint32_t kInternalIncompatible = 0x06040047;
inline constexpr uint32_t kHardware = 0x06060000;
inline constexpr uint32_t kLengthMismatch = 0x06070010;
inline constexpr uint32_t kLengthTooHigh = 0x06070012;
inline constexpr uint32_t kLengthTooLow = 0x06070013;
inline constexpr uint32_t kNoSubIndex = 0x06090011;
inline constexpr uint32_t kValueRange = 0x06090030;
inline constexpr uint32_t kValueTooHigh = 0x06090031;
inline constexpr uint32_t kValueTooLow = 0x06090032;
inline constexpr uint32_t kMaxLessThanMin = 0x06090036;
inline constexpr uint32_t kResourceNotAvailable = 0x060A0023;
inline constexpr uint32_t kGeneral = 0x08000000;
inline constexpr uint32_t kCannotStore = 0x08000020;
inline constexpr uint32_t kLocalControl = 0x08000021;
inline constexpr uint32_t kDeviceState = 0x08000022;
inline constexpr uint32_t kNoDictionary = 0x08000023;
inline constexpr uint32_t kNoData = 0x08000024;
}  // namespace abort_code

// "toggle bit not alternated", ...; "unknown abort code" for others.
const char* sdo_abort_text(uint32_t code) noexcept;

}  // namespace cnc::canopen
