#include "cia402/profile.hpp"

#include <cctype>
#include <cstdlib>
#include <cstring>

namespace cnc::cia402 {

const char* to_string(State s) noexcept {
  switch (s) {
    case State::NotReadyToSwitchOn: return "not ready to switch on";
    case State::SwitchOnDisabled: return "switch on disabled";
    case State::ReadyToSwitchOn: return "ready to switch on";
    case State::SwitchedOn: return "switched on";
    case State::OperationEnabled: return "operation enabled";
    case State::QuickStopActive: return "quick stop active";
    case State::FaultReactionActive: return "fault reaction active";
    case State::Fault: return "fault";
    case State::Invalid: return "invalid statusword";
  }
  return "?";
}

State decode_state(uint16_t s) noexcept {
  // The profile's table, in an order where each test is unambiguous.
  if ((s & sw::kMaskWide) == 0x0000) return State::NotReadyToSwitchOn;
  if ((s & sw::kMaskWide) == 0x0040) return State::SwitchOnDisabled;
  if ((s & sw::kMaskNarrow) == 0x0021) return State::ReadyToSwitchOn;
  if ((s & sw::kMaskNarrow) == 0x0023) return State::SwitchedOn;
  if ((s & sw::kMaskNarrow) == 0x0027) return State::OperationEnabled;
  if ((s & sw::kMaskNarrow) == 0x0007) return State::QuickStopActive;
  if ((s & sw::kMaskWide) == 0x000F) return State::FaultReactionActive;
  if ((s & sw::kMaskWide) == 0x0008) return State::Fault;
  return State::Invalid;
}

uint16_t state_bits(State s) noexcept {
  switch (s) {
    case State::NotReadyToSwitchOn: return 0x0000;
    case State::SwitchOnDisabled: return 0x0040;
    case State::ReadyToSwitchOn: return 0x0021;
    case State::SwitchedOn: return 0x0023;
    case State::OperationEnabled: return 0x0027;
    case State::QuickStopActive: return 0x0007;
    case State::FaultReactionActive: return 0x000F;
    case State::Fault: return 0x0008;
    case State::Invalid: return 0x004F;
  }
  return 0;
}

Command decode_command(uint16_t c) noexcept {
  // Bits 3,2,1,0 per the profile's command table (bit 7 handled apart).
  if ((c & cw::kEnableVoltage) == 0) return Command::DisableVoltage;          // x x 0 x
  if ((c & cw::kQuickStop) == 0) return Command::QuickStop;                   // x 0 1 x
  if ((c & cw::kSwitchOn) == 0) return Command::Shutdown;                     // x 1 1 0
  if ((c & cw::kEnableOperation) == 0) return Command::SwitchOn;              // 0 1 1 1 (= disable operation)
  return Command::EnableOperation;                                            // 1 1 1 1
}

const char* to_string(Command c) noexcept {
  switch (c) {
    case Command::DisableVoltage: return "disable voltage";
    case Command::QuickStop: return "quick stop";
    case Command::Shutdown: return "shutdown";
    case Command::SwitchOn: return "switch on";
    case Command::EnableOperation: return "enable operation";
    case Command::DisableOperation: return "disable operation";
  }
  return "?";
}

State next_state(State from, Command c, bool quick_stop_stays) noexcept {
  switch (from) {
    case State::SwitchOnDisabled:
      if (c == Command::Shutdown) return State::ReadyToSwitchOn;  // T2
      return from;
    case State::ReadyToSwitchOn:
      if (c == Command::SwitchOn) return State::SwitchedOn;  // T3
      if (c == Command::EnableOperation) return State::OperationEnabled;  // T3 + T4 in one step
      if (c == Command::QuickStop || c == Command::DisableVoltage) return State::SwitchOnDisabled;  // T7
      return from;
    case State::SwitchedOn:
      if (c == Command::EnableOperation) return State::OperationEnabled;  // T4
      if (c == Command::Shutdown) return State::ReadyToSwitchOn;          // T6
      if (c == Command::QuickStop || c == Command::DisableVoltage) return State::SwitchOnDisabled;  // T10
      return from;
    case State::OperationEnabled:
      if (c == Command::SwitchOn || c == Command::DisableOperation) return State::SwitchedOn;  // T5
      if (c == Command::Shutdown) return State::ReadyToSwitchOn;                              // T8
      if (c == Command::DisableVoltage) return State::SwitchOnDisabled;                       // T9
      if (c == Command::QuickStop) return State::QuickStopActive;                             // T11
      return from;
    case State::QuickStopActive:
      if (c == Command::DisableVoltage) return State::SwitchOnDisabled;  // T12
      if (c == Command::EnableOperation && quick_stop_stays) return State::OperationEnabled;  // T16
      return from;
    default:
      return from;
  }
}

const char* to_string(Mode m) noexcept {
  switch (m) {
    case Mode::None: return "none";
    case Mode::ProfilePosition: return "PP";
    case Mode::Velocity: return "VL";
    case Mode::ProfileVelocity: return "PV";
    case Mode::ProfileTorque: return "TQ";
    case Mode::Homing: return "HM";
    case Mode::InterpolatedPosition: return "IP";
    case Mode::CyclicSyncPosition: return "CSP";
    case Mode::CyclicSyncVelocity: return "CSV";
    case Mode::CyclicSyncTorque: return "CST";
  }
  return "vendor";
}

bool parse_mode(const char* text, Mode& out) noexcept {
  if (!text) return false;
  static constexpr Mode kAll[] = {Mode::ProfilePosition, Mode::Velocity, Mode::ProfileVelocity,
                                  Mode::ProfileTorque, Mode::Homing, Mode::InterpolatedPosition,
                                  Mode::CyclicSyncPosition, Mode::CyclicSyncVelocity, Mode::CyclicSyncTorque};
  for (Mode m : kAll) {
    const char* name = to_string(m);
    std::size_t i = 0;
    while (name[i] && text[i] && std::toupper(static_cast<unsigned char>(text[i])) == name[i]) ++i;
    if (!name[i] && !text[i]) {
      out = m;
      return true;
    }
  }
  char* end = nullptr;
  const long v = std::strtol(text, &end, 10);
  if (end && end != text && *end == '\0') {
    for (Mode m : kAll) {
      if (static_cast<long>(m) == v) {
        out = m;
        return true;
      }
    }
  }
  return false;
}

int supported_mode_bit(Mode m) noexcept {
  switch (m) {
    case Mode::ProfilePosition: return 0;
    case Mode::Velocity: return 1;
    case Mode::ProfileVelocity: return 2;
    case Mode::ProfileTorque: return 3;
    case Mode::Homing: return 5;
    case Mode::InterpolatedPosition: return 6;
    case Mode::CyclicSyncPosition: return 7;
    case Mode::CyclicSyncVelocity: return 8;
    case Mode::CyclicSyncTorque: return 9;
    default: return -1;
  }
}

bool is_cyclic(Mode m) noexcept {
  return m == Mode::CyclicSyncPosition || m == Mode::CyclicSyncVelocity || m == Mode::CyclicSyncTorque;
}

HomingStatus decode_homing(uint16_t s) noexcept {
  const bool b13 = (s & sw::kBit13) != 0, b12 = (s & sw::kBit12) != 0, b10 = (s & sw::kTargetReached) != 0;
  if (b13 && b12) return HomingStatus::Reserved;
  if (b13) return b10 ? HomingStatus::ErrorStopped : HomingStatus::ErrorMoving;
  if (b12) return b10 ? HomingStatus::Completed : HomingStatus::AttainedNotReached;
  return b10 ? HomingStatus::Interrupted : HomingStatus::InProgress;
}

uint16_t homing_bits(HomingStatus h) noexcept {
  switch (h) {
    case HomingStatus::InProgress: return 0;
    case HomingStatus::Interrupted: return sw::kTargetReached;
    case HomingStatus::AttainedNotReached: return sw::kBit12;
    case HomingStatus::Completed: return sw::kBit12 | sw::kTargetReached;
    case HomingStatus::ErrorMoving: return sw::kBit13;
    case HomingStatus::ErrorStopped: return sw::kBit13 | sw::kTargetReached;
    case HomingStatus::Reserved: return sw::kBit13 | sw::kBit12;
  }
  return 0;
}

const char* to_string(HomingStatus h) noexcept {
  switch (h) {
    case HomingStatus::InProgress: return "homing in progress";
    case HomingStatus::Interrupted: return "homing interrupted or not started";
    case HomingStatus::AttainedNotReached: return "homing attained, target not reached";
    case HomingStatus::Completed: return "homing completed";
    case HomingStatus::ErrorMoving: return "homing error, velocity not zero";
    case HomingStatus::ErrorStopped: return "homing error, velocity zero";
    case HomingStatus::Reserved: return "reserved homing status";
  }
  return "?";
}

bool is_defined_homing_method(int m) noexcept {
  return m < 0 ? m >= -128 : ((m >= 1 && m <= 14) || (m >= 17 && m <= 30) || (m >= 33 && m <= 35) || m == 37);
}

}  // namespace cnc::cia402
