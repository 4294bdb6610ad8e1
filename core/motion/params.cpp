#include "core/motion/params.hpp"

#include <cmath>
#include <iterator>

namespace cnc::motion {
namespace {

constexpr double kBig = 1e99;

const ParamSpec kTable[] = {
    {"joint.max-velocity", ParamScope::Joint, &JointConfig::max_velocity, nullptr, nullptr, 1e-9, kBig, false},
    {"joint.max-acceleration", ParamScope::Joint, &JointConfig::max_acceleration, nullptr, nullptr, 1e-9, kBig, false},
    {"joint.max-jerk", ParamScope::Joint, &JointConfig::max_jerk, nullptr, nullptr, 1e-9, kBig, false},
    {"joint.min-limit", ParamScope::Joint, &JointConfig::min_limit, nullptr, nullptr, -kBig, kBig, true},
    {"joint.max-limit", ParamScope::Joint, &JointConfig::max_limit, nullptr, nullptr, -kBig, kBig, true},
    {"joint.ferror", ParamScope::Joint, &JointConfig::ferror, nullptr, nullptr, 0, kBig, false},
    {"joint.min-ferror", ParamScope::Joint, &JointConfig::min_ferror, nullptr, nullptr, 0, kBig, false},
    {"joint.backlash", ParamScope::Joint, &JointConfig::backlash, nullptr, nullptr, 0, 1e3, true},
    {"axis.max-velocity", ParamScope::Axis, nullptr, &AxisConfig::max_velocity, nullptr, 1e-9, kBig, false},
    {"axis.max-acceleration", ParamScope::Axis, nullptr, &AxisConfig::max_acceleration, nullptr, 1e-9, kBig, false},
    {"axis.max-jerk", ParamScope::Axis, nullptr, &AxisConfig::max_jerk, nullptr, 1e-9, kBig, false},
    {"axis.min-limit", ParamScope::Axis, nullptr, &AxisConfig::min_limit, nullptr, -kBig, kBig, true},
    {"axis.max-limit", ParamScope::Axis, nullptr, &AxisConfig::max_limit, nullptr, -kBig, kBig, true},
    {"traj.max-velocity", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_velocity, 1e-9, kBig, false},
    {"traj.max-acceleration", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_acceleration, 1e-9, kBig, false},
    {"traj.max-jerk", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_linear_jerk, 1e-9, kBig, false},
    {"traj.default-velocity", ParamScope::Traj, nullptr, nullptr, &MotionConfig::default_linear_velocity, 0, kBig, false},
    {"traj.max-angular-velocity", ParamScope::Traj, nullptr, nullptr, &MotionConfig::max_angular_velocity, 1e-9, kBig, false},
};

bool names_equal(const char* a, std::string_view b) noexcept { return std::string_view(a) == b; }

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

const char* set_param(MotionConfig& c, uint16_t index, int n, double value) noexcept {
  if (index >= std::size(kTable)) return "unknown parameter";
  const ParamSpec& p = kTable[index];
  if (!std::isfinite(value) || value < p.min || value > p.max) return "value out of range";
  switch (p.scope) {
    case ParamScope::Joint: {
      if (n < 0 || n >= c.num_joints) return "no such joint";
      JointConfig& j = c.joints[static_cast<std::size_t>(n)];
      JointConfig trial = j;
      trial.*(p.joint_field) = value;
      if (trial.min_limit >= trial.max_limit) return "the minimum limit must stay below the maximum";
      if (trial.min_ferror > trial.ferror) return "MIN_FERROR must not exceed FERROR";
      j = trial;
      return nullptr;
    }
    case ParamScope::Axis: {
      if (n < 0 || n >= kNumAxes || !c.axes[static_cast<std::size_t>(n)].present) return "no such axis";
      AxisConfig& a = c.axes[static_cast<std::size_t>(n)];
      AxisConfig trial = a;
      trial.*(p.axis_field) = value;
      if (trial.min_limit >= trial.max_limit) return "the minimum limit must stay below the maximum";
      a = trial;
      return nullptr;
    }
    case ParamScope::Traj:
      c.*(p.traj_field) = value;
      return nullptr;
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
  }
  return 0;
}

}  // namespace cnc::motion
