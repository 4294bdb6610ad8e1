// The CiA 402 drive profile (IEC 61800-7-201) as both sides use it: states
// and their statusword patterns, controlword commands, modes of operation,
// object addresses and option codes (error codes: error_codes.hpp).
// Transport-independent (CANopen and EtherCAT CoE alike); header data and
// pure functions only, realtime-safe, no allocation.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cia402/error_codes.hpp"

namespace cnc::cia402 {

// ---------------------------------------------------------------- states

enum class State : uint8_t {
  NotReadyToSwitchOn = 0,
  SwitchOnDisabled = 1,
  ReadyToSwitchOn = 2,
  SwitchedOn = 3,
  OperationEnabled = 4,
  QuickStopActive = 5,
  FaultReactionActive = 6,
  Fault = 7,
  Invalid = 8,  // a statusword that matches none of the eight patterns
};

const char* to_string(State s) noexcept;

// Statusword bits (0x6041).
namespace sw {
inline constexpr uint16_t kReadyToSwitchOn = 1u << 0;
inline constexpr uint16_t kSwitchedOn = 1u << 1;
inline constexpr uint16_t kOperationEnabled = 1u << 2;
inline constexpr uint16_t kFault = 1u << 3;
inline constexpr uint16_t kVoltageEnabled = 1u << 4;
inline constexpr uint16_t kQuickStop = 1u << 5;  // 0 = quick stop active
inline constexpr uint16_t kSwitchOnDisabled = 1u << 6;
inline constexpr uint16_t kWarning = 1u << 7;
inline constexpr uint16_t kRemote = 1u << 9;
inline constexpr uint16_t kTargetReached = 1u << 10;
inline constexpr uint16_t kInternalLimit = 1u << 11;
inline constexpr uint16_t kBit12 = 1u << 12;  // CSP/CSV/CST: drive follows the command; HM: homing attained
inline constexpr uint16_t kBit13 = 1u << 13;  // CSP: following error; HM: homing error
// The state patterns (mask, value) of the profile's table.
inline constexpr uint16_t kMaskWide = 0x004F;
inline constexpr uint16_t kMaskNarrow = 0x006F;
}  // namespace sw

// Decodes the state; Invalid when no pattern matches (never a default).
State decode_state(uint16_t statusword) noexcept;
// The pattern bits of a state (the drive side composes its statusword
// from these plus voltage, remote, warning and mode bits).
uint16_t state_bits(State s) noexcept;

// Controlword bits (0x6040) and the commands of the profile.
namespace cw {
inline constexpr uint16_t kSwitchOn = 1u << 0;
inline constexpr uint16_t kEnableVoltage = 1u << 1;
inline constexpr uint16_t kQuickStop = 1u << 2;  // 0 = quick stop requested
inline constexpr uint16_t kEnableOperation = 1u << 3;
inline constexpr uint16_t kBit4 = 1u << 4;        // HM: start homing (edge); PP: new set-point
inline constexpr uint16_t kFaultReset = 1u << 7;  // acts on the 0 -> 1 edge
inline constexpr uint16_t kHalt = 1u << 8;
inline constexpr uint16_t kShutdown = 0x0006;
inline constexpr uint16_t kSwitchOnCmd = 0x0007;
inline constexpr uint16_t kDisableOperation = 0x0007;
inline constexpr uint16_t kEnableOperationCmd = 0x000F;
inline constexpr uint16_t kDisableVoltage = 0x0000;
inline constexpr uint16_t kQuickStopCmd = 0x0002;
inline constexpr uint16_t kFaultResetCmd = 0x0080;
}  // namespace cw

// What a controlword asks of the state machine (bits 0-3 and 7; the fault
// reset edge is the caller's to detect).
enum class Command : uint8_t {
  DisableVoltage,
  QuickStop,
  Shutdown,
  SwitchOn,
  EnableOperation,  // also "switch on + enable operation" from RTSO
  DisableOperation,
};
Command decode_command(uint16_t controlword) noexcept;
const char* to_string(Command c) noexcept;

// The next state a drive takes for a command (transitions 2-12, 16 of the
// profile; 0, 1, 13, 14 and 15 are the drive's own). `quick_stop_stays`
// selects option codes 5-8 of 0x605A (QSA -> OE on enable operation).
// Returns `from` when the command causes no transition.
State next_state(State from, Command c, bool quick_stop_stays) noexcept;

// ---------------------------------------------------------------- modes

enum class Mode : int8_t {
  None = 0,
  ProfilePosition = 1,
  Velocity = 2,
  ProfileVelocity = 3,
  ProfileTorque = 4,
  Homing = 6,
  InterpolatedPosition = 7,
  CyclicSyncPosition = 8,
  CyclicSyncVelocity = 9,
  CyclicSyncTorque = 10,
};
const char* to_string(Mode m) noexcept;   // "CSP", "HM", ...
// "CSP"/"csp"/"8" -> mode; false when unknown.
bool parse_mode(const char* text, Mode& out) noexcept;
// Bit of 0x6502 that announces a mode (-1 for None).
int supported_mode_bit(Mode m) noexcept;
bool is_cyclic(Mode m) noexcept;

// ---------------------------------------------------------------- objects

struct Object {
  uint16_t index;
  uint8_t sub;
};

namespace obj {
inline constexpr Object kDeviceType{0x1000, 0};
inline constexpr Object kErrorRegister{0x1001, 0};
inline constexpr Object kAbortConnection{0x6007, 0};
inline constexpr Object kErrorCode{0x603F, 0};
inline constexpr Object kControlword{0x6040, 0};
inline constexpr Object kStatusword{0x6041, 0};
inline constexpr Object kQuickStopOption{0x605A, 0};
inline constexpr Object kShutdownOption{0x605B, 0};
inline constexpr Object kDisableOperationOption{0x605C, 0};
inline constexpr Object kHaltOption{0x605D, 0};
inline constexpr Object kFaultReactionOption{0x605E, 0};
inline constexpr Object kModes{0x6060, 0};
inline constexpr Object kModesDisplay{0x6061, 0};
inline constexpr Object kPositionDemand{0x6062, 0};
inline constexpr Object kPositionActual{0x6064, 0};
inline constexpr Object kFollowingErrorWindow{0x6065, 0};
inline constexpr Object kFollowingErrorTimeout{0x6066, 0};
inline constexpr Object kPositionWindow{0x6067, 0};
inline constexpr Object kPositionWindowTime{0x6068, 0};
inline constexpr Object kVelocityActual{0x606C, 0};
inline constexpr Object kTargetTorque{0x6071, 0};
inline constexpr Object kMaxTorque{0x6072, 0};
inline constexpr Object kRatedTorque{0x6076, 0};
inline constexpr Object kTorqueActual{0x6077, 0};
inline constexpr Object kTargetPosition{0x607A, 0};
inline constexpr Object kHomeOffset{0x607C, 0};
inline constexpr Object kSwLimitMin{0x607D, 1};
inline constexpr Object kSwLimitMax{0x607D, 2};
inline constexpr Object kPolarity{0x607E, 0};
inline constexpr Object kMaxProfileVelocity{0x607F, 0};
inline constexpr Object kMaxMotorSpeed{0x6080, 0};
inline constexpr Object kProfileAcceleration{0x6083, 0};
inline constexpr Object kProfileDeceleration{0x6084, 0};
inline constexpr Object kQuickStopDeceleration{0x6085, 0};
inline constexpr Object kEncoderIncrements{0x608F, 1};
inline constexpr Object kEncoderMotorRevs{0x608F, 2};
inline constexpr Object kGearMotorRevs{0x6091, 1};
inline constexpr Object kGearShaftRevs{0x6091, 2};
inline constexpr Object kFeed{0x6092, 1};
inline constexpr Object kFeedShaftRevs{0x6092, 2};
inline constexpr Object kHomingMethod{0x6098, 0};
inline constexpr Object kHomingSpeedSwitch{0x6099, 1};
inline constexpr Object kHomingSpeedZero{0x6099, 2};
inline constexpr Object kHomingAcceleration{0x609A, 0};
inline constexpr Object kVelocityOffset{0x60B1, 0};
inline constexpr Object kTorqueOffset{0x60B2, 0};
inline constexpr Object kTouchProbeFunction{0x60B8, 0};
inline constexpr Object kTouchProbeStatus{0x60B9, 0};
inline constexpr Object kTouchProbe1Rising{0x60BA, 0};
inline constexpr Object kTouchProbe1Falling{0x60BB, 0};
inline constexpr Object kTouchProbe2Rising{0x60BC, 0};
inline constexpr Object kTouchProbe2Falling{0x60BD, 0};
inline constexpr Object kInterpolationPeriodValue{0x60C2, 1};
inline constexpr Object kInterpolationPeriodIndex{0x60C2, 2};
inline constexpr Object kFollowingErrorActual{0x60F4, 0};
inline constexpr Object kDigitalInputs{0x60FD, 0};
inline constexpr Object kDigitalOutputs{0x60FE, 1};
inline constexpr Object kTargetVelocity{0x60FF, 0};
inline constexpr Object kSupportedModes{0x6502, 0};
}  // namespace obj

// Digital inputs 0x60FD.
namespace din {
inline constexpr uint32_t kNegativeLimit = 1u << 0;
inline constexpr uint32_t kPositiveLimit = 1u << 1;
inline constexpr uint32_t kHomeSwitch = 1u << 2;
inline constexpr uint32_t kInterlock = 1u << 3;
inline constexpr uint32_t kProbeInput = 1u << 16;  // vendor bit: the touch probe input as read now
}  // namespace din

// Touch probe function 0x60B8 and status 0x60B9 (probe 1 low byte, probe 2
// high byte).
namespace tp {
inline constexpr uint16_t kEnable = 1u << 0;
inline constexpr uint16_t kContinuous = 1u << 1;
inline constexpr uint16_t kSourceZeroPulse = 1u << 2;  // bits 2-3 = 01: encoder zero pulse (else probe input)
inline constexpr uint16_t kRising = 1u << 4;
inline constexpr uint16_t kFalling = 1u << 5;
inline constexpr int kProbe2Shift = 8;
inline constexpr uint16_t kStatusEnabled = 1u << 0;
inline constexpr uint16_t kStatusRisingStored = 1u << 1;
inline constexpr uint16_t kStatusFallingStored = 1u << 2;
inline constexpr uint16_t kStatusInputLevel = 1u << 7;  // optional: the probe input now
}  // namespace tp

// Homing statusword (mask 0x3400: bits 13, 12, 10).
enum class HomingStatus : uint8_t {
  InProgress,
  Interrupted,       // or not started
  AttainedNotReached,
  Completed,
  ErrorMoving,
  ErrorStopped,
  Reserved,
};
HomingStatus decode_homing(uint16_t statusword) noexcept;
uint16_t homing_bits(HomingStatus h) noexcept;
const char* to_string(HomingStatus h) noexcept;
// True for the methods the profile defines (1-14, 17-30, 33-35, 37) and
// vendor methods (negative).
bool is_defined_homing_method(int method) noexcept;

// Option codes (0x605A quick stop and friends).
inline constexpr int16_t kQuickStopCoast = 0;
inline constexpr int16_t kQuickStopSlowDown = 1;
inline constexpr int16_t kQuickStopRamp = 2;
inline constexpr int16_t kQuickStopCurrentLimit = 3;
// 0x6007 abort connection: 0 none, 1 fault, 2 disable voltage, 3 quick stop.
inline constexpr int16_t kAbortNone = 0;
inline constexpr int16_t kAbortFault = 1;
inline constexpr int16_t kAbortDisableVoltage = 2;
inline constexpr int16_t kAbortQuickStop = 3;

}  // namespace cnc::cia402
