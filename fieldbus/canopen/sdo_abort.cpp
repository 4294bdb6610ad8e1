#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {

const char* sdo_abort_text(uint32_t code) noexcept {
  using namespace abort_code;
  switch (code) {
    case 0: return "no error";
    case kToggleBit: return "toggle bit not alternated";
    case kTimeout: return "SDO protocol timed out";
    case kCommandSpecifier: return "client/server command specifier not valid or unknown";
    case kBlockSize: return "invalid block size (block mode)";
    case kSequenceNumber: return "invalid sequence number (block mode)";
    case kCrc: return "CRC error (block mode)";
    case kOutOfMemory: return "out of memory";
    case kUnsupportedAccess: return "unsupported access to an object";
    case kWriteOnly: return "attempt to read a write-only object";
    case kReadOnly: return "attempt to write a read-only object";
    case kNoObject: return "object does not exist in the object dictionary";
    case kNotMappable: return "object cannot be mapped to the PDO";
    case kPdoLength: return "the number and length of the objects to be mapped would exceed the PDO length";
    case kParameterIncompatible: return "general parameter incompatibility";
    case kInternalIncompatible: return "general internal incompatibility in the device";
    case kHardware: return "access failed due to a hardware error";
    case kLengthMismatch: return "data type does not match, length of service parameter does not match";
    case kLengthTooHigh: return "data type does not match, length of service parameter too high";
    case kLengthTooLow: return "data type does not match, length of service parameter too low";
    case kNoSubIndex: return "sub-index does not exist";
    case kValueRange: return "value range of parameter exceeded (download only)";
    case kValueTooHigh: return "value of parameter written too high (download only)";
    case kValueTooLow: return "value of parameter written too low (download only)";
    case kMaxLessThanMin: return "maximum value is less than minimum value";
    case kResourceNotAvailable: return "resource not available: SDO connection";
    case kGeneral: return "general error";
    case kCannotStore: return "data cannot be transferred or stored to the application";
    case kLocalControl: return "data cannot be transferred or stored to the application because of local control";
    case kDeviceState: return "data cannot be transferred or stored to the application because of the present device state";
    case kNoDictionary: return "object dictionary dynamic generation failed or no object dictionary is present";
    case kNoData: return "no data available";
    default: return "unknown abort code";
  }
}

}  // namespace cnc::canopen
