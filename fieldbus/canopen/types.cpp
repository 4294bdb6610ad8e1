#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

const char* to_string(NmtState s) noexcept {
  switch (s) {
    case NmtState::Initialising: return "initialising";
    case NmtState::Stopped: return "stopped";
    case NmtState::Operational: return "operational";
    case NmtState::PreOperational: return "pre-operational";
    case NmtState::Unknown: return "unknown";
  }
  return "invalid";
}

NmtState nmt_state_from_byte(uint8_t b) noexcept {
  switch (b & 0x7F) {
    case 0x00: return NmtState::Initialising;
    case 0x04: return NmtState::Stopped;
    case 0x05: return NmtState::Operational;
    case 0x7F: return NmtState::PreOperational;
    default: return NmtState::Unknown;
  }
}

const char* to_string(NmtCommand c) noexcept {
  switch (c) {
    case NmtCommand::Start: return "start";
    case NmtCommand::Stop: return "stop";
    case NmtCommand::EnterPreOperational: return "enter pre-operational";
    case NmtCommand::ResetNode: return "reset node";
    case NmtCommand::ResetCommunication: return "reset communication";
  }
  return "?";
}

std::size_t data_type_size(DataType t) noexcept {
  switch (t) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Unsigned8: return 1;
    case DataType::Integer16:
    case DataType::Unsigned16: return 2;
    case DataType::Integer24:
    case DataType::Unsigned24: return 3;
    case DataType::Integer32:
    case DataType::Unsigned32:
    case DataType::Real32: return 4;
    case DataType::Integer64:
    case DataType::Unsigned64:
    case DataType::Real64: return 8;
    default: return 0;
  }
}

bool is_signed(DataType t) noexcept {
  switch (t) {
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer24:
    case DataType::Integer32:
    case DataType::Integer64: return true;
    default: return false;
  }
}

bool is_fixed_size(DataType t) noexcept { return data_type_size(t) != 0; }

const char* to_string(DataType t) noexcept {
  switch (t) {
    case DataType::Boolean: return "BOOLEAN";
    case DataType::Integer8: return "INTEGER8";
    case DataType::Integer16: return "INTEGER16";
    case DataType::Integer24: return "INTEGER24";
    case DataType::Integer32: return "INTEGER32";
    case DataType::Integer64: return "INTEGER64";
    case DataType::Unsigned8: return "UNSIGNED8";
    case DataType::Unsigned16: return "UNSIGNED16";
    case DataType::Unsigned24: return "UNSIGNED24";
    case DataType::Unsigned32: return "UNSIGNED32";
    case DataType::Unsigned64: return "UNSIGNED64";
    case DataType::Real32: return "REAL32";
    case DataType::Real64: return "REAL64";
    case DataType::VisibleString: return "VISIBLE_STRING";
    case DataType::OctetString: return "OCTET_STRING";
    case DataType::UnicodeString: return "UNICODE_STRING";
    case DataType::Domain: return "DOMAIN";
  }
  return "?";
}

bool is_known_data_type(uint16_t code) noexcept {
  switch (static_cast<DataType>(code)) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer24:
    case DataType::Integer32:
    case DataType::Integer64:
    case DataType::Unsigned8:
    case DataType::Unsigned16:
    case DataType::Unsigned24:
    case DataType::Unsigned32:
    case DataType::Unsigned64:
    case DataType::Real32:
    case DataType::Real64:
    case DataType::VisibleString:
    case DataType::OctetString:
    case DataType::UnicodeString:
    case DataType::Domain: return true;
  }
  return false;
}

}  // namespace cnc::canopen
