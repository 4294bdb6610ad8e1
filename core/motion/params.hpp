// The SET_xxx commands as one table (the manual, 3.8.27, asks for exactly
// this): each entry names a parameter, says whether it belongs to a joint,
// an axis or the trajectory, points at the configuration field it sets and
// gives its valid range. The task side looks names up; the servo thread
// applies an entry by index with no per-parameter code.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "core/motion/config.hpp"

namespace cnc::motion {

enum class ParamScope : uint8_t { Joint, Axis, Traj };

struct ParamSpec {
  const char* name;  // e.g. "joint.max-velocity"
  ParamScope scope;
  double JointConfig::*joint_field;
  double AxisConfig::*axis_field;
  double MotionConfig::*traj_field;
  double min, max;
  bool while_stopped_only;  // e.g. limits may not move under a running program
};

// The whole table.
const ParamSpec* param_table(std::size_t& count) noexcept;
// Index of a parameter by name, or nullopt.
std::optional<uint16_t> find_param(std::string_view name) noexcept;

// Reads and writes a parameter of a configuration (realtime-safe). Returns
// a reason when refused, nullptr when done.
const char* set_param(MotionConfig& config, uint16_t index, int joint_or_axis, double value) noexcept;
double get_param(const MotionConfig& config, uint16_t index, int joint_or_axis) noexcept;

}  // namespace cnc::motion
