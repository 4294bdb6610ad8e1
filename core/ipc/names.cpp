#include "core/ipc/command.hpp"
#include "core/ipc/status.hpp"

namespace cnc::ipc {

const char* to_string(CommandType t) noexcept {
  switch (t) {
    case CommandType::None: return "none";
    case CommandType::Ping: return "ping";
    case CommandType::Shutdown: return "shutdown";
    case CommandType::OperatorError: return "operator-error";
    case CommandType::OperatorText: return "operator-text";
    case CommandType::OperatorDisplay: return "operator-display";
    case CommandType::AlarmAcknowledge: return "alarm-acknowledge";
    case CommandType::TaskSetState: return "task-set-state";
    case CommandType::TaskSetMode: return "task-set-mode";
    case CommandType::TaskAbort: return "task-abort";
    case CommandType::TaskPlanOpen: return "program-open";
    case CommandType::TaskPlanRun: return "program-run";
    case CommandType::TaskPlanPause: return "program-pause";
    case CommandType::TaskPlanResume: return "program-resume";
    case CommandType::TaskPlanStep: return "program-step";
    case CommandType::TaskPlanExecute: return "mdi";
    case CommandType::TaskPlanInit: return "interpreter-reset";
    case CommandType::TaskPlanSynch: return "interpreter-synch";
    case CommandType::TaskPlanSetOptionalStop: return "set-optional-stop";
    case CommandType::TaskPlanSetBlockDelete: return "set-block-delete";
    case CommandType::TaskPlanClose: return "program-close";
    case CommandType::TaskPlanRunPreview: return "run-from-line-preview";
    case CommandType::TrajSetScale: return "feed-override";
    case CommandType::TrajSetRapidScale: return "rapid-override";
    case CommandType::TrajSetMaxVelocity: return "max-velocity";
    case CommandType::TrajSetTeleopEnable: return "teleop-enable";
    case CommandType::TrajSetFeedHoldEnable: return "feed-hold-enable";
    case CommandType::TrajSetFeedOverrideEnable: return "feed-override-enable";
    case CommandType::TrajSetAdaptiveFeedEnable: return "adaptive-feed-enable";
    case CommandType::TrajClearProbeTripped: return "clear-probe-tripped";
    case CommandType::MotionSetDigitalOutput: return "set-digital-output";
    case CommandType::MotionSetAnalogOutput: return "set-analog-output";
    case CommandType::JogCont: return "jog-continuous";
    case CommandType::JogIncr: return "jog-increment";
    case CommandType::JogAbs: return "jog-absolute";
    case CommandType::JogStop: return "jog-stop";
    case CommandType::JointHome: return "home";
    case CommandType::JointUnhome: return "unhome";
    case CommandType::JointOverrideLimits: return "override-limits";
    case CommandType::JointActivate: return "joint-activate";
    case CommandType::JointDeactivate: return "joint-deactivate";
    case CommandType::JointLoadComp: return "load-compensation";
    case CommandType::SetParameter: return "set-parameter";
    case CommandType::MotionEnable: return "motion-enable";
    case CommandType::MotionDisable: return "motion-disable";
    case CommandType::SpindleOn: return "spindle-on";
    case CommandType::SpindleOff: return "spindle-off";
    case CommandType::SpindleIncrease: return "spindle-increase";
    case CommandType::SpindleDecrease: return "spindle-decrease";
    case CommandType::SpindleConstant: return "spindle-constant";
    case CommandType::SpindleBrakeRelease: return "spindle-brake-release";
    case CommandType::SpindleBrakeEngage: return "spindle-brake-engage";
    case CommandType::SpindleOrient: return "spindle-orient";
    case CommandType::SpindleOverride: return "spindle-override";
    case CommandType::CoolantMistOn: return "mist-on";
    case CommandType::CoolantMistOff: return "mist-off";
    case CommandType::CoolantFloodOn: return "flood-on";
    case CommandType::CoolantFloodOff: return "flood-off";
    case CommandType::LubeOn: return "lube-on";
    case CommandType::LubeOff: return "lube-off";
    case CommandType::ToolLoadTable: return "tool-load-table";
    case CommandType::ToolSetOffset: return "tool-set-offset";
    case CommandType::ToolSetNumber: return "tool-set-number";
    case CommandType::ToolDelete: return "tool-delete";
    case CommandType::AuxEstopOn: return "estop";
    case CommandType::AuxEstopReset: return "estop-reset";
    case CommandType::SetWorkOffset: return "set-work-offset";
    case CommandType::SimInject: return "sim-inject";
  }
  return "unknown";
}

const char* to_string(CommandState s) noexcept {
  switch (s) {
    case CommandState::None: return "none";
    case CommandState::Received: return "received";
    case CommandState::Executing: return "executing";
    case CommandState::Done: return "done";
    case CommandState::Rejected: return "rejected";
  }
  return "?";
}

const char* to_string(TaskState s) noexcept {
  switch (s) {
    case TaskState::Estop: return "ESTOP";
    case TaskState::EstopReset: return "ESTOP_RESET";
    case TaskState::Off: return "OFF";
    case TaskState::On: return "ON";
  }
  return "?";
}

const char* to_string(TaskMode m) noexcept {
  switch (m) {
    case TaskMode::Manual: return "MANUAL";
    case TaskMode::Auto: return "AUTO";
    case TaskMode::Mdi: return "MDI";
  }
  return "?";
}

const char* to_string(InterpState s) noexcept {
  switch (s) {
    case InterpState::Idle: return "IDLE";
    case InterpState::Reading: return "READING";
    case InterpState::Paused: return "PAUSED";
    case InterpState::Waiting: return "WAITING";
  }
  return "?";
}

const char* to_string(ExecState s) noexcept {
  switch (s) {
    case ExecState::Error: return "ERROR";
    case ExecState::Done: return "DONE";
    case ExecState::WaitingForMotion: return "WAITING_FOR_MOTION";
    case ExecState::WaitingForMotionQueue: return "WAITING_FOR_MOTION_QUEUE";
    case ExecState::WaitingForIo: return "WAITING_FOR_IO";
    case ExecState::WaitingForMotionAndIo: return "WAITING_FOR_MOTION_AND_IO";
    case ExecState::WaitingForDelay: return "WAITING_FOR_DELAY";
    case ExecState::WaitingForSystemCmd: return "WAITING_FOR_SYSTEM_CMD";
    case ExecState::WaitingForSpindleOriented: return "WAITING_FOR_SPINDLE_ORIENTED";
  }
  return "?";
}

const char* to_string(MotionMode m) noexcept {
  switch (m) {
    case MotionMode::Free: return "FREE";
    case MotionMode::Coord: return "COORD";
    case MotionMode::Teleop: return "TELEOP";
  }
  return "?";
}

const char* to_string(EstopCause c) noexcept {
  switch (c) {
    case EstopCause::None: return "none";
    case EstopCause::Request: return "request";
    case EstopCause::ChainOpen: return "chain open";
  }
  return "?";
}

}  // namespace cnc::ipc
