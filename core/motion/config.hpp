// The motion controller's configuration: [KINS], [TRAJ], [EMCMOT],
// [JOINT_n], [AXIS_L] and [SPINDLE_n] of the INI file, with LinuxCNC's keys
// and defaults, validated on load (errors name file, line and key). Motion
// owns these machine parameters (docs/architecture.md, "Parameters"): they
// are read here once, the servo thread keeps the copy in force and changes
// it only through the table-driven SET_xxx command (params.hpp), and the
// status block publishes it. Plain data.
#pragma once

#include <array>
#include <string>

#include "core/motion/io.hpp"
#include "core/util/pose.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::motion {

enum class JointType : uint8_t { Linear = 0, Angular = 1 };
enum class HomeMode : uint8_t { Motion = 0, Drive = 1 };  // drive: CiA-402 homing through the drive

struct HomingConfig {
  double home = 0;            // HOME: where the joint goes after homing
  double offset = 0;          // HOME_OFFSET: joint position of the switch/index
  double search_vel = 0;      // HOME_SEARCH_VEL (sign: direction)
  double latch_vel = 0;       // HOME_LATCH_VEL (same sign: latch on approach; opposite: on release)
  double final_vel = -1;      // HOME_FINAL_VEL (< 0: the joint's maximum velocity)
  bool use_index = false;     // HOME_USE_INDEX
  bool ignore_limits = false; // HOME_IGNORE_LIMITS
  bool is_shared = false;     // HOME_IS_SHARED
  bool has_sequence = false;  // HOME_SEQUENCE given (joints without one are not homed by "home all")
  int sequence = 0;           // HOME_SEQUENCE (negative: synchronised group, e.g. gantry)
  bool volatile_home = false; // VOLATILE_HOME
  bool locking_indexer = false;  // LOCKING_INDEXER
  int absolute_encoder = 0;   // HOME_ABSOLUTE_ENCODER 0/1/2
  HomeMode mode = HomeMode::Motion;  // HOME_MODE = MOTION | DRIVE
};

// What motion does when the servo thread is late (OVERRUN_STREAK
// consecutive overruns, or that many periods missed at once).
enum class OverrunAction : uint8_t {
  Warn,  // the thread's message only
  Hold,  // coordinated motion pauses (feed hold) until the operator resumes
  Stop,  // motion is disabled with the reason (the machine goes off)
};
const char* to_string(OverrunAction a) noexcept;

struct JointConfig {
  JointType type = JointType::Linear;
  double min_limit = -1e99, max_limit = 1e99;
  double max_velocity = 1, max_acceleration = 1, max_jerk = 50;
  double ferror = 1, min_ferror = 1;
  double backlash = 0;
  double amp_ready_timeout_s = 2.0;  // [JOINT_n]AMP_READY_TIMEOUT: enable -> amp-ready-in
  std::string comp_file;
  int comp_file_type = 0;
  HomingConfig homing;
};

struct AxisConfig {
  bool present = false;
  double min_limit = -1e99, max_limit = 1e99;
  double max_velocity = 1, max_acceleration = 1, max_jerk = 50;
};

// [SPINDLE_n] speed limits in rpm (LinuxCNC's keys and defaults). The
// speed sent to the spindle (command x override) is clamped into them: a
// non-zero speed below the minimum is raised to it, one above the maximum
// lowered to it; reverse limits are magnitudes, and a maximum reverse
// speed of 0 forbids reverse.
struct SpindleConfig {
  double max_forward = 1e99;  // MAX_FORWARD_VELOCITY
  double min_forward = 0;     // MIN_FORWARD_VELOCITY
  double max_reverse = 1e99;  // MAX_REVERSE_VELOCITY (default: MAX_FORWARD_VELOCITY)
  double min_reverse = 0;     // MIN_REVERSE_VELOCITY (default: MIN_FORWARD_VELOCITY)
  // AT_SPEED_TIMEOUT: seconds a feed move may wait for spindle.N.at-speed
  // before the program is aborted; 0 waits for ever (LinuxCNC).
  double at_speed_timeout_s = 0;
};

struct MotionConfig {
  int num_joints = 3;
  std::array<JointConfig, kMaxJoints> joints{};
  std::array<AxisConfig, kNumAxes> axes{};
  std::array<SpindleConfig, kMaxSpindles> spindle{};
  // The servo period: [EMCMOT]SERVO_PERIOD (ns in the INI) until motmod's
  // on_ready, then the period of the HAL thread that runs
  // motion-controller (a SERVO_PERIOD that differs from it is refused).
  double servo_period_s = 0.001;
  std::string servo_period_key;       // "file:line: [EMCMOT]SERVO_PERIOD" when given, else empty
  double comm_timeout_s = 1.0;        // [EMCMOT]COMM_TIMEOUT
  double max_linear_velocity = 1e99;  // [TRAJ]MAX_LINEAR_VELOCITY
  double max_linear_acceleration = 1e99;
  double max_linear_jerk = 1e99;
  double default_linear_velocity = 0;
  double max_angular_velocity = 1e99;
  // Coordinated planner (docs/tp.md): [TRAJ]LOOKAHEAD_SEGMENTS,
  // BLEND_SPAN_SEGMENTS, MAX_BLEND_HALF_WIDTH (machine units).
  int lookahead_segments = 1000;
  int blend_span_segments = 8;
  double max_blend_half_width = 5.0;
  double linear_units_per_mm = 1;     // [TRAJ]LINEAR_UNITS: mm -> 1, inch -> 1/25.4
  double angular_units_per_degree = 1;
  bool no_force_homing = false;       // [TRAJ]NO_FORCE_HOMING
  int spindles = 1;                   // [TRAJ]SPINDLES
  int num_dio = 4, num_aio = 4;       // motmod num_dio= / num_aio=
  // Fraction of each joint's velocity and acceleration kept free for
  // backlash and screw compensation (the planners use the rest).
  double comp_reserve = 0.05;
  // [EMCMOT]OVERRUN_STREAK, OVERRUN_ACTION (docs/configuration.md).
  int overrun_streak = 3;
  OverrunAction overrun_action = OverrunAction::Warn;
};

// Reads the configuration for `num_joints` joints. Throws ConfigError.
MotionConfig load_motion_config(const ini::IniFile& ini, int num_joints);

}  // namespace cnc::motion
