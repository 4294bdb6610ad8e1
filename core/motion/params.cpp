#include "core/motion/params.hpp"

#include <cmath>
#include <cstdio>
#include <iterator>

namespace cnc::motion {
namespace {

constexpr double kBig = 1e99;
using B = IniBound;

const ParamSpec kTable[] = {
    {"joint.max-velocity", "MAX_VELOCITY", ParamScope::Joint, &JointConfig::max_velocity, nullptr, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"joint.max-acceleration", "MAX_ACCELERATION", ParamScope::Joint, &JointConfig::max_acceleration, nullptr, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"joint.max-jerk", "MAX_JERK", ParamScope::Joint, &JointConfig::max_jerk, nullptr, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"joint.min-limit", "MIN_LIMIT", ParamScope::Joint, &JointConfig::min_limit, nullptr, nullptr, nullptr, -kBig, kBig, B::AtLeast, true},
    {"joint.max-limit", "MAX_LIMIT", ParamScope::Joint, &JointConfig::max_limit, nullptr, nullptr, nullptr, -kBig, kBig, B::AtMost, true},
    {"joint.ferror", "FERROR", ParamScope::Joint, &JointConfig::ferror, nullptr, nullptr, nullptr, 0, kBig, B::AtMost, false},
    {"joint.min-ferror", "MIN_FERROR", ParamScope::Joint, &JointConfig::min_ferror, nullptr, nullptr, nullptr, 0, kBig, B::AtMost, false},
    {"joint.backlash", "BACKLASH", ParamScope::Joint, &JointConfig::backlash, nullptr, nullptr, nullptr, 0, 1e3, B::None, true},
    {"axis.max-velocity", "MAX_VELOCITY", ParamScope::Axis, nullptr, &AxisConfig::max_velocity, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"axis.max-acceleration", "MAX_ACCELERATION", ParamScope::Axis, nullptr, &AxisConfig::max_acceleration, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"axis.max-jerk", "MAX_JERK", ParamScope::Axis, nullptr, &AxisConfig::max_jerk, nullptr, nullptr, 1e-9, kBig, B::AtMost, true},
    {"axis.min-limit", "MIN_LIMIT", ParamScope::Axis, nullptr, &AxisConfig::min_limit, nullptr, nullptr, -kBig, kBig, B::AtLeast, true},
    {"axis.max-limit", "MAX_LIMIT", ParamScope::Axis, nullptr, &AxisConfig::max_limit, nullptr, nullptr, -kBig, kBig, B::AtMost, true},
    {"traj.max-velocity", "MAX_LINEAR_VELOCITY", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_velocity, nullptr, 1e-9, kBig, B::AtMost, true},
    {"traj.max-acceleration", "MAX_LINEAR_ACCELERATION", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_acceleration, nullptr, 1e-9, kBig, B::AtMost, true},
    {"traj.max-jerk", "MAX_LINEAR_JERK", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_jerk, nullptr, 1e-9, kBig, B::AtMost, true},
    {"traj.default-velocity", "DEFAULT_LINEAR_VELOCITY", ParamScope::Traj, nullptr, nullptr, &MotionConfig::default_linear_velocity, nullptr, 0, kBig, B::None, false},
    {"traj.max-angular-velocity", "MAX_ANGULAR_VELOCITY", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_angular_velocity, nullptr, 1e-9, kBig, B::AtMost, false},
    {"spindle.max-forward-velocity", "MAX_FORWARD_VELOCITY", ParamScope::Spindle, nullptr, nullptr, nullptr, &SpindleConfig::max_forward, 0, kBig, B::AtMost, false},
    {"spindle.min-forward-velocity", "MIN_FORWARD_VELOCITY", ParamScope::Spindle, nullptr, nullptr, nullptr, &SpindleConfig::min_forward, 0, kBig, B::AtLeast, false},
    {"spindle.max-reverse-velocity", "MAX_REVERSE_VELOCITY", ParamScope::Spindle, nullptr, nullptr, nullptr, &SpindleConfig::max_reverse, 0, kBig, B::AtMost, false},
    {"spindle.min-reverse-velocity", "MIN_REVERSE_VELOCITY", ParamScope::Spindle, nullptr, nullptr, nullptr, &SpindleConfig::min_reverse, 0, kBig, B::AtLeast, false},
};

bool names_equal(const char* a, std::string_view b) noexcept { return std::string_view(a) == b; }

// Whether `value` keeps to the INI's `ini` value under `bound`.
bool within_ini(IniBound bound, double value, double ini) noexcept {
  switch (bound) {
    case IniBound::None: return true;
    case IniBound::AtMost: return value <= ini;
    case IniBound::AtLeast: return value >= ini;
  }
  return true;
}

}  // namespace

const ParamSpec* param_table(std::size_t& count) noexcept {
  count = std::size(kTable);
  return kTable;
}

std::optional<uint16_t> find_param(std::string_view name) noexcept {
  for (std::size_t i = 0; i < std::size(kTable); ++i) {
    if (names_equal(kTable[i].name, name)) return static_cast<uint16_t>(i);
  }
  return std::nullopt;
}

const char* set_param(MotionConfig& c, const MotionConfig& ini, uint16_t index, int n, double value,
                      double* ini_value) noexcept {
  if (index >= std::size(kTable)) return "unknown parameter";
  const ParamSpec& p = kTable[index];
  if (!std::isfinite(value) || value < p.min || value > p.max) return "value out of range";
  auto beyond_ini = [&](double ini_v) {
    if (within_ini(p.bound, value, ini_v)) return false;
    if (ini_value) *ini_value = ini_v;
    return true;
  };
  const char* const kAbove = "above the INI file's value, the machine's limit";
  const char* const kBelow = "below the INI file's value, the machine's limit";
  const char* const kBeyond = p.bound == IniBound::AtMost ? kAbove : kBelow;
  switch (p.scope) {
    case ParamScope::Joint: {
      if (n < 0 || n >= c.num_joints) return "no such joint";
      const auto k = static_cast<std::size_t>(n);
      if (beyond_ini(ini.joints[k].*(p.joint_field))) return kBeyond;
      JointConfig trial = c.joints[k];
      trial.*(p.joint_field) = value;
      if (trial.min_limit >= trial.max_limit) return "the minimum limit must stay below the maximum";
      if (trial.min_ferror > trial.ferror) return "MIN_FERROR must not exceed FERROR";
      c.joints[k] = trial;
      return nullptr;
    }
    case ParamScope::Axis: {
      if (n < 0 || n >= kNumAxes || !c.axes[static_cast<std::size_t>(n)].present) return "no such axis";
      const auto k = static_cast<std::size_t>(n);
      if (beyond_ini(ini.axes[k].*(p.axis_field))) return kBeyond;
      AxisConfig trial = c.axes[k];
      trial.*(p.axis_field) = value;
      if (trial.min_limit >= trial.max_limit) return "the minimum limit must stay below the maximum";
      c.axes[k] = trial;
      return nullptr;
    }
    case ParamScope::Traj:
      if (beyond_ini(ini.*(p.traj_field))) return kBeyond;
      c.*(p.traj_field) = value;
      return nullptr;
    case ParamScope::Spindle: {
      if (n < 0 || n >= c.spindles) return "no such spindle";
      const auto k = static_cast<std::size_t>(n);
      if (beyond_ini(ini.spindle[k].*(p.spindle_field))) return kBeyond;
      SpindleConfig trial = c.spindle[k];
      trial.*(p.spindle_field) = value;
      if (trial.min_forward > trial.max_forward) return "the minimum forward speed must not exceed the maximum";
      if (trial.max_reverse > 0 && trial.min_reverse > trial.max_reverse) {
        return "the minimum reverse speed must not exceed the maximum";
      }
      c.spindle[k] = trial;
      return nullptr;
    }
  }
  return "unknown parameter";
}

double get_param(const MotionConfig& c, uint16_t index, int n) noexcept {
  if (index >= std::size(kTable)) return 0;
  const ParamSpec& p = kTable[index];
  switch (p.scope) {
    case ParamScope::Joint: return n >= 0 && n < kMaxJoints ? c.joints[static_cast<std::size_t>(n)].*(p.joint_field) : 0;
    case ParamScope::Axis: return n >= 0 && n < kNumAxes ? c.axes[static_cast<std::size_t>(n)].*(p.axis_field) : 0;
    case ParamScope::Traj: return c.*(p.traj_field);
    case ParamScope::Spindle:
      return n >= 0 && n < kMaxSpindles ? c.spindle[static_cast<std::size_t>(n)].*(p.spindle_field) : 0;
  }
  return 0;
}

void param_ini_name(uint16_t index, int n, char* out, std::size_t size) noexcept {
  if (size == 0) return;
  out[0] = '\0';
  if (index >= std::size(kTable)) return;
  const ParamSpec& p = kTable[index];
  switch (p.scope) {
    case ParamScope::Joint: std::snprintf(out, size, "[JOINT_%d]%s", n, p.ini_key); break;
    case ParamScope::Axis:
      std::snprintf(out, size, "[AXIS_%c]%s", n >= 0 && n < kNumAxes ? kAxisLetters[n] : '?', p.ini_key);
      break;
    case ParamScope::Traj: std::snprintf(out, size, "[TRAJ]%s", p.ini_key); break;
    case ParamScope::Spindle: std::snprintf(out, size, "[SPINDLE_%d]%s", n, p.ini_key); break;
  }
}

}  // namespace cnc::motion
