// Commands from the task side to the motion controller (the manual's
// section 3.8) and their answers. They travel through a lock-free queue into
// the servo thread; every command gets exactly one answer, accepted or
// rejected with a reason a person can read. Plain data.
#pragma once

#include <array>
#include <cstdint>

#include "core/tp/planner.hpp"
#include "core/util/fixed_string.hpp"
#include "core/util/pose.hpp"

namespace cnc::motion {

enum class Cmd : uint8_t {
  Abort,
  Free,
  Teleop,
  Coord,
  Enable,
  Disable,
  EnableAmplifier,    // joint
  DisableAmplifier,   // joint
  ActivateJoint,      // joint
  DeactivateJoint,    // joint
  EstopReset,         // clears the E-stop latch; refused while the E-stop chain is open
  Pause,
  Resume,
  Step,
  Scale,              // value[0]: feed override (SCALE)
  RapidScale,         // value[0]
  MaxVelocity,        // value[0]: units/s
  OverrideLimits,     // value[0] != 0: override until the end of the next jog; 0: cancel
  Home,               // joint (-1: all joints with a HOME_SEQUENCE)
  Unhome,             // joint (-1: all, -2: VOLATILE_HOME joints)
  JogCont,            // joint or axis (axis_mode), value[0]: signed velocity
  JogIncr,            // value[0]: velocity, value[1]: signed distance
  JogAbs,             // value[0]: velocity, value[1]: position
  JogStop,            // joint or axis
  SetLine,            // end, segment
  SetCircle,          // end, center, normal, turns, segment
  SetDwell,           // value[0]: seconds, segment
  SetTeleopVector,    // end holds a velocity vector (units/s per axis)
  Probe,              // end, segment; value[0] != 0: stop on contact loss (G38.4/5), value[1] != 0: error if no contact
  ClearProbeFlag,
  SetParameter,       // param: index in the SET_xxx table, joint: joint/axis, value[0]
  SetDigitalOut,      // joint: index, value[0]: 0/1, value[1] != 0: with the next motion (else now)
  SetAnalogOut,       // joint: index, value[0]: value, value[1] as above
  SetSpindle,         // joint: spindle, value[0]: rpm (signed), value[1] != 0: on
  SpindleBrake,       // joint: spindle, value[0] != 0: engage
  SpindleOverride,    // joint: spindle, value[0]
  SpindleOrient,      // joint: spindle, value[0]: angle, value[1]: mode
  FeedOverrideEnable, // value[0]: M50 on/off
  AdaptiveFeedEnable, // value[0]: M52 on/off
  FeedHoldEnable,     // value[0]: M53 on/off
  SwitchKinematics,   // value[0]: kinematics type index (only while stopped)
  SetToolOffset,      // end: tool offset (for motion.tooloffset.* pins)
};

const char* to_string(Cmd c) noexcept;

struct MotionCommand {
  uint64_t serial = 0;
  Cmd type = Cmd::Abort;
  int16_t joint = 0;         // joint, axis, spindle or output index
  bool axis_mode = false;    // jogs: true = axis (teleop), false = joint (free)
  uint16_t param = 0;        // SetParameter: index in the table
  int32_t turns = 0;
  double value[4] = {};
  Pose end;
  std::array<double, 3> center{};
  std::array<double, 3> normal{};
  tp::SegmentParams segment;
};

struct MotionResult {
  uint64_t serial = 0;
  Cmd type = Cmd::Abort;
  bool accepted = false;
  FixedString<200> reason;
};

}  // namespace cnc::motion
