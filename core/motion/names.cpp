#include "core/motion/command.hpp"

namespace cnc::motion {

const char* to_string(Cmd c) noexcept {
  switch (c) {
    case Cmd::Abort: return "ABORT";
    case Cmd::Free: return "FREE";
    case Cmd::Teleop: return "TELEOP";
    case Cmd::Coord: return "COORD";
    case Cmd::Enable: return "ENABLE";
    case Cmd::Disable: return "DISABLE";
    case Cmd::EnableAmplifier: return "ENABLE_AMPLIFIER";
    case Cmd::DisableAmplifier: return "DISABLE_AMPLIFIER";
    case Cmd::ActivateJoint: return "ACTIVATE_JOINT";
    case Cmd::DeactivateJoint: return "DEACTIVATE_JOINT";
    case Cmd::EstopReset: return "ESTOP_RESET";
    case Cmd::Pause: return "PAUSE";
    case Cmd::Resume: return "RESUME";
    case Cmd::Step: return "STEP";
    case Cmd::Scale: return "SCALE";
    case Cmd::RapidScale: return "RAPID_SCALE";
    case Cmd::MaxVelocity: return "SET_MAX_VELOCITY";
    case Cmd::OverrideLimits: return "OVERRIDE_LIMITS";
    case Cmd::Home: return "HOME";
    case Cmd::Unhome: return "UNHOME";
    case Cmd::JogCont: return "JOG_CONT";
    case Cmd::JogIncr: return "JOG_INCR";
    case Cmd::JogAbs: return "JOG_ABS";
    case Cmd::JogStop: return "JOG_STOP";
    case Cmd::SetLine: return "SET_LINE";
    case Cmd::SetCircle: return "SET_CIRCLE";
    case Cmd::SetDwell: return "SET_DWELL";
    case Cmd::SetTeleopVector: return "SET_TELEOP_VECTOR";
    case Cmd::Probe: return "PROBE";
    case Cmd::ClearProbeFlag: return "CLEAR_PROBE_FLAG";
    case Cmd::SetParameter: return "SET_PARAMETER";
    case Cmd::SetDigitalOut: return "SET_DOUT";
    case Cmd::SetAnalogOut: return "SET_AOUT";
    case Cmd::SetSpindle: return "SET_SPINDLE";
    case Cmd::SpindleBrake: return "SPINDLE_BRAKE";
    case Cmd::SpindleOverride: return "SPINDLE_SCALE";
    case Cmd::SpindleOrient: return "SPINDLE_ORIENT";
    case Cmd::FeedOverrideEnable: return "FEED_OVERRIDE_ENABLE";
    case Cmd::AdaptiveFeedEnable: return "ADAPTIVE_FEED_ENABLE";
    case Cmd::FeedHoldEnable: return "FEED_HOLD_ENABLE";
    case Cmd::SwitchKinematics: return "SWITCH_KINEMATICS";
    case Cmd::SetToolOffset: return "SET_TOOL_OFFSET";
  }
  return "?";
}

}  // namespace cnc::motion

