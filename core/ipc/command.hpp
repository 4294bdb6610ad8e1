// Commands that clients (CLI, HMI, halcmd's sibling tools) send to the
// controller through the shared segment, modelled on the NML message groups
// of the manual's chapter 4. Every command carries a serial number; the
// controller answers each one (done, or rejected with a reason) on the
// command-result channel. Plain data, fixed size.
#pragma once

#include <cstdint>

#include "core/util/fixed_string.hpp"

namespace cnc::ipc {

enum class CommandType : uint16_t {
  None = 0,
  // --- controller ---
  Ping = 1,            // answered Done at once: proves the channel works
  Shutdown = 2,        // orderly stop: drives to a safe state, then exit
  // --- OPERATOR (4.1): a client posts to the error channel ---
  OperatorError = 10,  // text
  OperatorText = 11,   // text
  OperatorDisplay = 12,  // text
  AlarmAcknowledge = 13, // i[0]: alarm id (status alarms), 0: all active alarms
  // --- TASK (4.7) ---
  TaskSetState = 20,     // i[0]: TaskState
  TaskSetMode = 21,      // i[0]: TaskMode
  TaskAbort = 22,
  TaskPlanOpen = 23,     // text: program path
  TaskPlanRun = 24,      // i[0]: start line (0: beginning; >0: run from line)
  TaskPlanPause = 25,
  TaskPlanResume = 26,
  TaskPlanStep = 27,
  TaskPlanExecute = 28,  // text: one MDI line; i[0] >= 0: [MDI_COMMAND_LIST] macro index instead
  TaskPlanInit = 29,     // reset the interpreter
  TaskPlanSynch = 30,
  TaskPlanSetOptionalStop = 31,  // i[0]: 0/1
  TaskPlanSetBlockDelete = 32,   // i[0]: 0/1
  TaskPlanClose = 33,
  TaskPlanRunPreview = 34,       // i[0]: line: report the run-from-line approach without moving
  // --- TRAJ / MOTION (4.5, 4.6) ---
  TrajSetScale = 40,          // d[0]: feed override (1.0 = 100 %)
  TrajSetRapidScale = 41,     // d[0]
  TrajSetMaxVelocity = 42,    // d[0]: units/s
  TrajSetTeleopEnable = 43,   // i[0]: 0/1
  TrajSetFeedHoldEnable = 44, // i[0]: 0/1 (M53)
  TrajSetFeedOverrideEnable = 45,  // i[0]: 0/1 (M50)
  TrajSetAdaptiveFeedEnable = 46,  // i[0]: 0/1 (M52)
  TrajClearProbeTripped = 47,
  MotionSetDigitalOutput = 48,  // i[0]: index, i[1]: value, i[2]: 1 = now, 0 = with next motion
  MotionSetAnalogOutput = 49,   // i[0]: index, d[0]: value, i[2] as above
  // --- JOG (4.4) ---  i[0]: joint or axis index, i[1]: 1 = joint (free), 0 = axis (teleop)
  JogCont = 60,   // d[0]: signed velocity, units/s
  JogIncr = 61,   // d[0]: velocity (>0), d[1]: signed distance
  JogAbs = 62,    // d[0]: velocity (>0), d[1]: target position
  JogStop = 63,
  // --- JOINT (4.2) ---  i[0]: joint index (-1: all where it applies)
  JointHome = 70,
  JointUnhome = 71,            // i[0] = -1: all; -2: volatile-home joints only
  JointOverrideLimits = 72,
  JointActivate = 73,
  JointDeactivate = 74,
  JointLoadComp = 75,          // text: compensation file; i[1]: COMP_FILE_TYPE
  SetParameter = 76,           // text: parameter name (SET_xxx table), i[0]: joint/axis index, d[0]: value
  MotionEnable = 77,           // ENABLE / DISABLE of the manual's 3.8.5-6 (task does this on machine on/off)
  MotionDisable = 78,
  // --- SPINDLE (4.10) ---  i[0]: spindle index
  SpindleOn = 80,              // d[0]: speed rpm (sign: direction)
  SpindleOff = 81,
  SpindleIncrease = 82,
  SpindleDecrease = 83,
  SpindleConstant = 84,
  SpindleBrakeRelease = 85,
  SpindleBrakeEngage = 86,
  SpindleOrient = 87,          // d[0]: angle, i[1]: mode
  SpindleOverride = 88,        // d[0]: scale
  // --- COOLANT, LUBE (4.11, 4.12) ---
  CoolantMistOn = 90,
  CoolantMistOff = 91,
  CoolantFloodOn = 92,
  CoolantFloodOff = 93,
  LubeOn = 94,
  LubeOff = 95,
  // --- TOOL (4.8) ---
  ToolLoadTable = 100,         // re-read the tool table file
  ToolSetOffset = 101,         // i[0]: tool, i[1]: pocket (-1 keep), d[0..8]: offsets X..W, d[9]: diameter,
                               // d[10]: front angle, d[11]: back angle, i[2]: orientation, text: comment
  ToolSetNumber = 102,         // i[0]: tool now in the spindle (M61)
  ToolDelete = 103,            // i[0]: tool
  // --- AUX (4.9) ---
  AuxEstopOn = 110,
  AuxEstopReset = 111,
  // --- work offsets (through the interpreter, never by writing files) ---
  SetWorkOffset = 120,         // i[0]: 1..9 = G54..G59.3, 0 = G92; d[0..8]: offsets; d[9]: XY rotation (G5x only)
  // --- simulation and fault injection (simulated machines only) ---
  SimInject = 130,             // text: what (e.g. "drive 1 overcurrent"), d[0]: value
};

const char* to_string(CommandType t) noexcept;

struct Command {
  uint32_t serial = 0;
  CommandType type = CommandType::None;
  int32_t client_pid = 0;
  int64_t time_ns = 0;
  int32_t i[4] = {};
  double d[12] = {};
  FixedString<1024> text;
};

enum class CommandState : uint8_t {
  None = 0,
  Received = 1,   // taken from the channel
  Executing = 2,  // accepted, still running (a home, a program, a tool change)
  Done = 3,
  Rejected = 4,   // refused or failed; the reason says why
};

const char* to_string(CommandState s) noexcept;

struct CommandResult {
  uint32_t serial = 0;
  CommandType type = CommandType::None;
  CommandState state = CommandState::None;
  int64_t time_ns = 0;
  FixedString<240> reason;
};

}  // namespace cnc::ipc
