// The SET_xxx commands as one table (the manual, 3.8.27, asks for exactly
// this): each entry names a parameter, says whether it belongs to a joint,
// an axis, the trajectory or a spindle, points at the configuration field
// it sets, gives its valid range, how a run-time value may relate to the
// INI file's (the machine's limit) and when it may change. The task side
// looks names up; the servo thread checks and applies an entry by index
// with no per-parameter code (docs/architecture.md, "Parameters").
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "core/motion/config.hpp"

namespace cnc::motion {

enum class ParamScope : uint8_t { Joint, Axis, Traj, Spindle };

// How a run-time value may relate to the value the INI file gave: the INI
// describes what the machine can do, run-time changes may only be stricter.
enum class IniBound : uint8_t {
  None,     // anything in [min, max]
  AtMost,   // not above the INI value (a maximum velocity, a following-error limit)
  AtLeast,  // not below the INI value (a minimum soft limit, a minimum spindle speed)
};

struct ParamSpec {
  const char* name;     // e.g. "joint.max-velocity"
  const char* ini_key;  // the INI key it starts from, e.g. "MAX_VELOCITY"
  ParamScope scope;
  double JointConfig::*joint_field;
  double AxisConfig::*axis_field;
  double MotionConfig::*traj_field;
  double SpindleConfig::*spindle_field;
  double min, max;
  IniBound bound;
  // Limits the planners have planned with may not move under running
  // motion: such a change is refused until the machine is at rest.
  bool while_stopped_only;
};

// The whole table.
const ParamSpec* param_table(std::size_t& count) noexcept;
// Index of a parameter by name, or nullopt.
std::optional<uint16_t> find_param(std::string_view name) noexcept;

// Writes a parameter of a configuration (realtime-safe): checks the index,
// the range, the INI bound against `ini` (the configuration as loaded) and
// the consistency with the other parameters. Returns a reason when
// refused (a static text; `ini_value` gets the INI's value when the INI
// bound refused it), nullptr when done.
const char* set_param(MotionConfig& config, const MotionConfig& ini, uint16_t index, int index_in_scope, double value,
                      double* ini_value = nullptr) noexcept;
double get_param(const MotionConfig& config, uint16_t index, int index_in_scope) noexcept;
// "[AXIS_X]MAX_VELOCITY" for an entry and an index (realtime-safe).
void param_ini_name(uint16_t index, int index_in_scope, char* out, std::size_t size) noexcept;

}  // namespace cnc::motion
