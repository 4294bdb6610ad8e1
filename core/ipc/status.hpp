// The status block of the shared segment: everything a client (CLI, HMI,
// halcmd) may show, mirroring what LinuxCNC's STAT messages and its Python
// `linuxcnc.stat` carry. Plain data of fixed size, copied whole under a
// sequence lock; the controller writes it every task cycle.
#pragma once

#include <cstdint>

#include "core/ipc/command.hpp"
#include "core/util/fixed_string.hpp"
#include "core/util/pose.hpp"

namespace cnc::ipc {

// Values of LinuxCNC's STATE_*, MODE_*, INTERP_*, EXEC_*, TRAJ_MODE_*.
enum class TaskState : uint8_t { Estop = 1, EstopReset = 2, Off = 3, On = 4 };
enum class TaskMode : uint8_t { Manual = 1, Auto = 2, Mdi = 3 };
enum class InterpState : uint8_t { Idle = 1, Reading = 2, Paused = 3, Waiting = 4 };
enum class ExecState : uint8_t {
  Error = 1,
  Done = 2,
  WaitingForMotion = 3,
  WaitingForMotionQueue = 4,
  WaitingForIo = 5,
  WaitingForMotionAndIo = 7,
  WaitingForDelay = 8,
  WaitingForSystemCmd = 9,
  WaitingForSpindleOriented = 10,
};
enum class MotionMode : uint8_t { Free = 1, Coord = 2, Teleop = 3 };
// Why motion latched an E-stop (docs/motion.md, "E-stop").
enum class EstopCause : uint8_t { None = 0, Request = 1, ChainOpen = 2 };

const char* to_string(TaskState s) noexcept;
const char* to_string(TaskMode m) noexcept;
const char* to_string(InterpState s) noexcept;
const char* to_string(ExecState s) noexcept;
const char* to_string(MotionMode m) noexcept;
const char* to_string(EstopCause c) noexcept;

inline constexpr int kMaxSpindles = 8;
inline constexpr int kMaxThreads = 4;
inline constexpr int kMaxSimulators = 2;

struct HealthStatus {
  uint64_t heartbeat = 0;        // +1 per publication
  int64_t time_ns = 0;           // CLOCK_REALTIME of this publication
  int64_t started_ns = 0;        // when the controller started
  int32_t pid = 0;
  bool realtime_memory_locked = false;
  bool realtime_fifo = false;
  FixedString<256> realtime_note;  // why realtime was not granted
  FixedString<256> ini_file;
  FixedString<64> machine;         // [EMC]MACHINE
  uint64_t messages_dropped = 0;   // error-channel entries lost in the controller
  int64_t task_cycle_ns = 0;       // [TASK]CYCLE_TIME: how often this block is published
  bool shutting_down = false;
};

struct CommandEcho {
  uint32_t serial = 0;           // last serial received (echo_serial_number)
  CommandState state = CommandState::None;
  CommandType type = CommandType::None;
};

struct TaskStatus {
  TaskState state = TaskState::Estop;
  TaskMode mode = TaskMode::Manual;
  InterpState interp_state = InterpState::Idle;
  ExecState exec_state = ExecState::Done;
  bool paused = false;
  bool block_delete = false;
  bool optional_stop = false;
  bool available = false;        // a task controller is running in this build
  FixedString<512> file;         // open program
  FixedString<256> command;      // MDI line being executed
  int32_t current_line = 0;      // line being executed (motion's)
  int32_t read_line = 0;         // line the interpreter has read up to
  int32_t total_lines = 0;
  int32_t g5x_index = 1;         // 1..9 = G54..G59.3
  Pose g5x_offset;
  Pose g92_offset;
  double rotation_xy = 0;
  Pose tool_offset;
  int32_t program_units = 2;     // 1 inch, 2 mm
  int32_t active_gcodes[17] = {};
  int32_t active_mcodes[10] = {};
  double active_settings[5] = {};  // sequence, F, S, G64 P, G64 Q
  double delay_left = 0;
  int32_t queued_mdi = 0;
  int64_t program_started_ns = 0;
  int64_t program_elapsed_ns = 0;
  int64_t blocks_executed = 0;
  int32_t errors_since_start = 0;
  int32_t run_from_line_pending = 0;  // run-from-line approach shown, waiting for confirmation
  Pose run_from_line_start;
};

struct TrajStatus {
  MotionMode mode = MotionMode::Free;
  bool enabled = false;
  bool inpos = true;
  bool paused = false;
  bool queue_full = false;
  bool probing = false;
  bool probe_tripped = false;
  bool probe_latch_pending = false;  // tripped, a drive's touch-probe latch not yet in (at most 0.1 s)
  bool probe_input = false;
  bool carte_fb_valid = false;   // forward kinematics usable: actual_position is meaningful
  bool watchdog_enabled = false;
  bool feed_override_enabled = true;
  bool adaptive_feed_enabled = false;
  bool feed_hold_enabled = true;
  bool teleop_enabled = false;
  int32_t queue = 0;
  int32_t motion_line = 0;
  uint32_t motion_id = 0;
  uint32_t axis_mask = 0;
  int32_t joints = 0;
  int32_t spindles = 0;
  uint8_t kinematics_type = 0;
  Pose position;                 // commanded, machine coordinates (carte_pos_cmd)
  Pose actual_position;          // carte_pos_fb
  Pose dtg;                      // distance to go
  Pose probed_position;
  double current_vel = 0;
  double distance_to_go = 0;
  double feed_scale = 1;
  double rapid_scale = 1;
  double max_velocity = 0;       // the max-velocity override (MAX_VELOCITY command)
  // Path limits in force ([TRAJ]MAX_LINEAR_*, as changed at run time; 1e99: none).
  double max_linear_velocity = 0;
  double max_linear_acceleration = 0;
  double max_linear_jerk = 0;
  double linear_units = 1;       // machine units per mm
  double angular_units = 1;      // per degree
  double cycle_time_s = 0.001;
  uint64_t servo_cycles = 0;
  // The path holds the start of a feed move until this spindle's
  // spindle.N.at-speed (-1: not waiting), waiting for spindle_wait_s so far.
  int32_t spindle_wait = -1;
  double spindle_wait_s = 0;
  // E-stop latched in the servo thread (a request through the segment, or
  // the E-stop chain open); cleared only by E-stop reset with the chain closed.
  bool estop_latched = false;
  EstopCause estop_cause = EstopCause::None;
  int32_t estop_pid = 0;         // the requesting process (cause Request)
  // motion-controller no longer runs (delf, or its thread stalls): the
  // values above are its last; nothing is commanded to move.
  bool servo_stalled = false;
};

struct JointStatus {
  uint8_t type = 0;              // 0 linear, 1 angular
  bool active = false;
  bool enabled = false;
  bool homing = false;
  bool homed = false;
  bool fault = false;
  bool inpos = true;
  bool min_soft_limit = false;
  bool max_soft_limit = false;
  bool min_hard_limit = false;
  bool max_hard_limit = false;
  bool override_limits = false;
  int8_t axis = -1;              // axis this joint moves, -1 when coupled
  double pos_cmd = 0;
  double pos_fb = 0;
  double motor_pos_cmd = 0;
  double motor_pos_fb = 0;
  double velocity = 0;
  double ferror_current = 0;
  double ferror_highmark = 0;
  double ferror_limit = 0;
  double min_position_limit = 0;
  double max_position_limit = 0;
  // Limits in force ([JOINT_n], as changed at run time), and the velocity
  // jogs and homing use (less the share kept for compensation).
  double max_velocity = 0;
  double max_acceleration = 0;
  double max_jerk = 0;
  double velocity_limit = 0;
  double ferror = 0;             // FERROR: following-error limit at full speed
  double min_ferror = 0;         // MIN_FERROR: at rest
  double backlash = 0;
  double home_offset = 0;
  double compensation = 0;       // backlash + screw correction applied now
};

struct AxisStatus {
  double min_position_limit = 0;
  double max_position_limit = 0;
  double velocity = 0;
  // Limits in force ([AXIS_L], as changed at run time) ...
  double max_velocity = 0;
  double max_acceleration = 0;
  double max_jerk = 0;
  // ... and what coordinated moves and axis jogs use: these and the limits
  // of every joint that moves this axis alone.
  double velocity_limit = 0;
  double acceleration_limit = 0;
};

struct SpindleStatus {
  double speed = 0;              // commanded rpm
  double speed_out = 0;          // rpm sent to the spindle: command x override within the limits below
  bool speed_limited = false;    // command x override is outside the limits: speed_out is the limit
  // [SPINDLE_n] limits in force, rpm (reverse ones as magnitudes; 1e99: none).
  double max_forward = 0;
  double min_forward = 0;
  double max_reverse = 0;
  double min_reverse = 0;
  double speed_feedback = 0;
  double override_scale = 1;
  int32_t direction = 0;         // -1, 0, 1
  bool enabled = false;
  bool brake = true;
  bool at_speed = false;
  bool override_enabled = true;
  int32_t orient_state = 0;
  int32_t orient_fault = 0;
  bool amp_fault = false;        // spindle.N.amp-fault-in disabled motion
};

struct IoStatus {
  int32_t tool_in_spindle = 0;
  double tool_diameter = 0;      // of the tool in the spindle (tool table D), 0 when empty
  int32_t pocket_prepped = -1;
  int32_t tool_prepped = 0;
  bool tool_change_in_progress = false;
  bool flood = false;
  bool mist = false;
  bool lube = false;
  bool lube_level_ok = true;
  bool estop_chain_ok = false;   // iocontrol.0.emc-enable-in
};

// One CiA-402 drive behind a joint (or the spindle), for the drive panel.
struct DriveStatus {
  bool present = false;
  int8_t joint = -1;
  uint8_t state = 0;             // cia402 state machine state
  uint8_t mode = 0;              // 0x6061
  uint16_t statusword = 0;
  uint16_t controlword = 0;
  uint16_t error_code = 0;       // 0x603F
  double following_error = 0;    // machine units
  double torque_percent = 0;
  double velocity = 0;
  FixedString<48> name;
  FixedString<96> fault_text;
};

struct ThreadStatus {
  FixedString<32> name;
  bool fifo = false;
  int64_t period_ns = 0;
  uint64_t cycles = 0;
  uint64_t overruns = 0;              // cycles that ended after their deadline
  uint64_t missed_cycles = 0;         // periods that got no cycle (a 2 s stall at 1 ms: ~2000)
  uint32_t overrun_streak = 0;        // consecutive overruns now
  uint32_t longest_streak = 0;
  int64_t longest_gap = 0;            // most periods missed at once
  uint64_t late_wakes = 0;            // overruns blamed on waking late (host, scheduler), not on a function
  FixedString<48> overrun_function;   // the function blamed for the most overruns ("" none)
  uint32_t overrun_function_count = 0;
  int64_t overrun_function_max_ns = 0;  // its longest run in a cycle it was blamed for
  int64_t latency_min_ns = 0;
  int64_t latency_p50_ns = 0;
  int64_t latency_p99_ns = 0;
  int64_t latency_p999_ns = 0;
  int64_t latency_max_ns = 0;
  int64_t period_min_ns = 0;
  int64_t period_max_ns = 0;
  int64_t exec_last_ns = 0;
  int64_t exec_max_ns = 0;
  // exec split: the product's functions, and the simulators' (sim/) that
  // run in this thread; each with its longest cycle since the start.
  int64_t product_exec_last_ns = 0;
  int64_t product_exec_max_ns = 0;
  int64_t sim_exec_last_ns = 0;
  int64_t sim_exec_max_ns = 0;
};

// A simulator that does its work on a thread of its own, in step with a
// HAL thread (cia402_sim's stepper): its time, apart from that thread's.
struct SimulatorStatus {
  FixedString<32> name;          // "cia402-sim"; empty: no simulator
  uint64_t steps = 0;            // periods simulated
  uint64_t late_steps = 0;       // periods asked for before the previous one was simulated (answers late)
  uint64_t helped_steps = 0;     // of them, simulated by the HAL thread itself: the simulator had not started
  uint64_t wakes = 0;            // requests that had to wake the simulator's thread (a system call in the HAL thread)
  int64_t exec_last_ns = 0;      // one period's simulation, every bus of the simulator
  int64_t exec_max_ns = 0;
};

// Alarms kept by the controller (core/ipc/alarms.hpp): the error messages
// de-duplicated per cause, with their acknowledgement, so that every screen
// and the CLI show the same alarms and a screen started later does not show
// old acknowledged ones as active.
inline constexpr int kMaxAlarms = 16;

struct AlarmEntry {
  uint32_t id = 0;               // 0: unused slot; ids grow, never reused
  uint32_t count = 0;            // messages merged into this alarm
  int64_t first_ns = 0;          // CLOCK_REALTIME of the first and the last message
  int64_t last_ns = 0;
  bool acknowledged = false;
  int64_t acknowledged_ns = 0;
  FixedString<48> source;        // of the message whose text is shown
  FixedString<48> cause;         // what it is about: "joint 1", "spindle 0", or the message itself
  FixedString<256> text;         // the most explicit message of the cause
};

struct AlarmStatus {
  bool available = false;        // this controller keeps alarms (screens then do not raise their own from messages)
  uint32_t revision = 0;         // +1 on every change
  uint32_t active = 0;           // unacknowledged alarms
  uint32_t dropped = 0;          // alarms pushed out of the table by newer ones
  AlarmEntry list[kMaxAlarms];   // oldest first
};

struct Status {
  HealthStatus health;
  CommandEcho echo;
  TaskStatus task;
  TrajStatus motion;
  JointStatus joints[kMaxJoints];
  AxisStatus axes[kNumAxes];
  SpindleStatus spindles[kMaxSpindles];
  IoStatus io;
  DriveStatus drives[kMaxJoints + 1];
  ThreadStatus threads[kMaxThreads];
  SimulatorStatus simulators[kMaxSimulators];
  AlarmStatus alarms;
};

}  // namespace cnc::ipc
