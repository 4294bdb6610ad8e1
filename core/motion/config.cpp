#include "core/motion/config.hpp"

#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::motion {
namespace {

using ini::Range;

void load_joint(const ini::IniFile& ini, int n, JointConfig& j) {
  const std::string s = "JOINT_" + std::to_string(n);
  const std::string type = to_upper(ini.get_string(s, "TYPE", "LINEAR"));
  if (type == "LINEAR") j.type = JointType::Linear;
  else if (type == "ANGULAR") j.type = JointType::Angular;
  else ini.fail(ini.find_entry(s, "TYPE"), "expected LINEAR or ANGULAR, got \"" + type + "\"");
  j.min_limit = ini.get_double(s, "MIN_LIMIT", -1e99);
  j.max_limit = ini.get_double(s, "MAX_LIMIT", 1e99);
  if (j.min_limit >= j.max_limit) ini.fail(ini.find_entry(s, "MAX_LIMIT"), "must be greater than MIN_LIMIT");
  j.max_velocity = ini.get_double(s, "MAX_VELOCITY", 1.0, {1e-9, 1e9});
  j.max_acceleration = ini.get_double(s, "MAX_ACCELERATION", 1.0, {1e-9, 1e12});
  j.max_jerk = ini.get_double(s, "MAX_JERK", 50 * j.max_acceleration, {1e-9, 1e15});
  j.ferror = ini.get_double(s, "FERROR", 1.0, {0, 1e9});
  j.min_ferror = ini.get_double(s, "MIN_FERROR", j.ferror, {0, 1e9});
  if (j.min_ferror > j.ferror) ini.fail(ini.find_entry(s, "MIN_FERROR"), "must not exceed FERROR");
  j.backlash = ini.get_double(s, "BACKLASH", 0.0, {0, 1e3});
  j.amp_ready_timeout_s = ini.get_double(s, "AMP_READY_TIMEOUT", 2.0, {0.001, 3600});
  j.comp_file = ini.get_string(s, "COMP_FILE", "");
  if (!j.comp_file.empty()) j.comp_file = ini.resolve_path(j.comp_file).string();
  j.comp_file_type = static_cast<int>(ini.get_int(s, "COMP_FILE_TYPE", 0, {0, 1}));
  HomingConfig& h = j.homing;
  h.home = ini.get_double(s, "HOME", 0.0);
  h.offset = ini.get_double(s, "HOME_OFFSET", 0.0);
  h.search_vel = ini.get_double(s, "HOME_SEARCH_VEL", 0.0);
  h.latch_vel = ini.get_double(s, "HOME_LATCH_VEL", 0.0);
  h.final_vel = ini.get_double(s, "HOME_FINAL_VEL", -1.0);
  h.use_index = ini.get_bool(s, "HOME_USE_INDEX", false);
  h.ignore_limits = ini.get_bool(s, "HOME_IGNORE_LIMITS", false);
  h.is_shared = ini.get_bool(s, "HOME_IS_SHARED", false);
  h.has_sequence = ini.find_entry(s, "HOME_SEQUENCE") != nullptr;
  h.sequence = static_cast<int>(ini.get_int(s, "HOME_SEQUENCE", 0, {-kMaxJoints, kMaxJoints}));
  h.volatile_home = ini.get_bool(s, "VOLATILE_HOME", false);
  h.locking_indexer = ini.get_bool(s, "LOCKING_INDEXER", false);
  h.absolute_encoder = static_cast<int>(ini.get_int(s, "HOME_ABSOLUTE_ENCODER", 0, {0, 2}));
  const std::string mode = to_upper(ini.get_string(s, "HOME_MODE", "MOTION"));
  if (mode == "MOTION") h.mode = HomeMode::Motion;
  else if (mode == "DRIVE") h.mode = HomeMode::Drive;
  else ini.fail(ini.find_entry(s, "HOME_MODE"), "expected MOTION or DRIVE, got \"" + mode + "\"");
  if (h.search_vel != 0 && h.latch_vel == 0) {
    ini.fail(ini.find_entry(s, "HOME_LATCH_VEL"),
             "HOME_SEARCH_VEL is set, so a non-zero HOME_LATCH_VEL is needed to latch the switch");
  }
  if (std::fabs(h.search_vel) > j.max_velocity || std::fabs(h.latch_vel) > j.max_velocity) {
    ini.fail(ini.find_entry(s, "HOME_SEARCH_VEL"), "homing velocities must not exceed MAX_VELOCITY");
  }
  if (h.home < j.min_limit || h.home > j.max_limit) {
    ini.fail(ini.find_entry(s, "HOME"), "HOME must lie between MIN_LIMIT and MAX_LIMIT");
  }
}

void load_axis(const ini::IniFile& ini, int a, AxisConfig& ax) {
  const std::string s = std::string("AXIS_") + kAxisLetters[a];
  ax.present = ini.has_section(s);
  ax.min_limit = ini.get_double(s, "MIN_LIMIT", -1e99);
  ax.max_limit = ini.get_double(s, "MAX_LIMIT", 1e99);
  if (ax.min_limit >= ax.max_limit) ini.fail(ini.find_entry(s, "MAX_LIMIT"), "must be greater than MIN_LIMIT");
  ax.max_velocity = ini.get_double(s, "MAX_VELOCITY", 1.0, {1e-9, 1e9});
  ax.max_acceleration = ini.get_double(s, "MAX_ACCELERATION", 1.0, {1e-9, 1e12});
  ax.max_jerk = ini.get_double(s, "MAX_JERK", 50 * ax.max_acceleration, {1e-9, 1e15});
}

void load_spindle(const ini::IniFile& ini, int n, SpindleConfig& sp) {
  const std::string s = "SPINDLE_" + std::to_string(n);
  sp.max_forward = ini.get_double(s, "MAX_FORWARD_VELOCITY", 1e99, {0, 1e99});
  sp.min_forward = ini.get_double(s, "MIN_FORWARD_VELOCITY", 0, {0, 1e99});
  sp.max_reverse = ini.get_double(s, "MAX_REVERSE_VELOCITY", sp.max_forward, {0, 1e99});
  sp.min_reverse = ini.get_double(s, "MIN_REVERSE_VELOCITY", sp.min_forward, {0, 1e99});
  sp.at_speed_timeout_s = ini.get_double(s, "AT_SPEED_TIMEOUT", 0, {0, 1e6});
  if (sp.min_forward > sp.max_forward) {
    ini.fail(ini.find_entry(s, "MIN_FORWARD_VELOCITY"), "must not exceed MAX_FORWARD_VELOCITY");
  }
  // MAX_REVERSE_VELOCITY = 0 forbids reverse: the minimum does not matter then.
  if (sp.max_reverse > 0 && sp.min_reverse > sp.max_reverse) {
    const ini::Entry* e = ini.find_entry(s, "MIN_REVERSE_VELOCITY");
    ini.fail(e ? e : ini.find_entry(s, "MAX_REVERSE_VELOCITY"), "MIN_REVERSE_VELOCITY must not exceed MAX_REVERSE_VELOCITY");
  }
}

}  // namespace

const char* to_string(OverrunAction a) noexcept {
  switch (a) {
    case OverrunAction::Warn: return "WARN";
    case OverrunAction::Hold: return "HOLD";
    case OverrunAction::Stop: return "STOP";
  }
  return "?";
}

MotionConfig load_motion_config(const ini::IniFile& ini, int num_joints) {
  MotionConfig c;
  if (num_joints < 1 || num_joints > kMaxJoints) {
    ini.fail(ini.find_entry("KINS", "JOINTS"), "expected 1 to 16 joints, got " + std::to_string(num_joints));
  }
  c.num_joints = num_joints;
  c.servo_period_s = static_cast<double>(ini.get_int("EMCMOT", "SERVO_PERIOD", 1'000'000, {10'000, 1e9})) * 1e-9;
  if (const ini::Entry* e = ini.find_entry("EMCMOT", "SERVO_PERIOD")) {
    c.servo_period_key = e->file + ":" + std::to_string(e->line) + ": [EMCMOT]SERVO_PERIOD";
  }
  c.comm_timeout_s = ini.get_double("EMCMOT", "COMM_TIMEOUT", 1.0, {0.001, 3600});
  c.max_linear_velocity = ini.get_double("TRAJ", "MAX_LINEAR_VELOCITY", ini.get_double("TRAJ", "MAX_VELOCITY", 1e99), {1e-9, 1e99});
  c.max_linear_acceleration = ini.get_double("TRAJ", "MAX_LINEAR_ACCELERATION", ini.get_double("TRAJ", "MAX_ACCELERATION", 1e99), {1e-9, 1e99});
  c.max_linear_jerk = ini.get_double("TRAJ", "MAX_LINEAR_JERK", 1e99, {1e-9, 1e99});
  c.default_linear_velocity = ini.get_double("TRAJ", "DEFAULT_LINEAR_VELOCITY", 0.0, {0, 1e99});
  c.max_angular_velocity = ini.get_double("TRAJ", "MAX_ANGULAR_VELOCITY", 1e99, {1e-9, 1e99});
  c.lookahead_segments = static_cast<int>(ini.get_int("TRAJ", "LOOKAHEAD_SEGMENTS", 1000, {1, 1'000'000}));
  c.blend_span_segments = static_cast<int>(ini.get_int("TRAJ", "BLEND_SPAN_SEGMENTS", 8, {1, 32}));
  c.max_blend_half_width = ini.get_double("TRAJ", "MAX_BLEND_HALF_WIDTH", 5.0, {1e-6, 1e6});
  const std::string lu = to_lower(ini.get_string("TRAJ", "LINEAR_UNITS", "mm"));
  if (lu == "mm" || lu == "metric" || lu == "1") c.linear_units_per_mm = 1;
  else if (lu == "inch" || lu == "imperial" || lu == "in") c.linear_units_per_mm = 1 / 25.4;
  else ini.fail(ini.find_entry("TRAJ", "LINEAR_UNITS"), "expected mm or inch, got \"" + lu + "\"");
  const std::string au = to_lower(ini.get_string("TRAJ", "ANGULAR_UNITS", "degree"));
  if (au == "degree" || au == "deg") c.angular_units_per_degree = 1;
  else if (au == "radian" || au == "rad") c.angular_units_per_degree = M_PI / 180;
  else if (au == "grad" || au == "gon") c.angular_units_per_degree = 400.0 / 360.0;
  else ini.fail(ini.find_entry("TRAJ", "ANGULAR_UNITS"), "expected degree, radian or grad, got \"" + au + "\"");
  c.no_force_homing = ini.get_bool("TRAJ", "NO_FORCE_HOMING", false);
  c.spindles = static_cast<int>(ini.get_int("TRAJ", "SPINDLES", 1, {0, 8}));
  // The backlash and screw-table correction moves only within this share of
  // the joint limits: 0 (or a share so small that a reversal takes seconds)
  // would leave the correction standing while the pins show it.
  c.comp_reserve = ini.get_double("EMCMOT", "COMP_RESERVE", 0.05, {0, 0.5});
  if (c.comp_reserve < 0.01) {
    ini.fail(ini.find_entry("EMCMOT", "COMP_RESERVE"),
             "expected a number between 0.01 and 0.5, got \"" + ini.get_string("EMCMOT", "COMP_RESERVE", "") +
                 "\": below 1 % the backlash and screw-table correction has no room in the joint limits to be "
                 "applied (joints without BACKLASH or COMP_FILE reserve nothing anyway)");
  }
  c.overrun_streak = static_cast<int>(ini.get_int("EMCMOT", "OVERRUN_STREAK", 3, {1, 1'000'000}));
  const std::string action = to_upper(ini.get_string("EMCMOT", "OVERRUN_ACTION", "WARN"));
  if (action == "WARN") c.overrun_action = OverrunAction::Warn;
  else if (action == "HOLD") c.overrun_action = OverrunAction::Hold;
  else if (action == "STOP") c.overrun_action = OverrunAction::Stop;
  else ini.fail(ini.find_entry("EMCMOT", "OVERRUN_ACTION"), "expected WARN, HOLD or STOP, got \"" + action + "\"");
  for (int j = 0; j < num_joints; ++j) load_joint(ini, j, c.joints[static_cast<std::size_t>(j)]);
  for (int a = 0; a < kNumAxes; ++a) load_axis(ini, a, c.axes[static_cast<std::size_t>(a)]);
  for (int s = 0; s < kMaxSpindles; ++s) load_spindle(ini, s, c.spindle[static_cast<std::size_t>(s)]);
  return c;
}

}  // namespace cnc::motion
