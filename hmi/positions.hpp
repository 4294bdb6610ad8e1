// Positions the DRO shows, computed from a status snapshot the way the
// task controller converts program to machine coordinates (docs/motion.md,
// core/task): machine = R(program + G92) + G5x + tool offset, with G5x, G92
// and the tool offset in program units and R the XY rotation. Also the
// touch-off arithmetic and the work-offset values of the parameter file.
// No Qt.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <string_view>

#include "core/ipc/status.hpp"

namespace cnc::hmi {

inline bool is_linear_axis(int axis) noexcept { return axis < 3 || axis > 5; }

// Machine units per program unit (program units: status.task.program_units).
double program_to_machine(const ipc::Status& s) noexcept;
bool program_inch(const ipc::Status& s) noexcept;
bool machine_inch(const ipc::Status& s) noexcept;

struct DroPositions {
  Pose work;     // program coordinates, program units
  Pose machine;  // machine coordinates, machine units
  Pose dtg;      // distance to go, program units
  bool valid = true;  // actual position asked for but unknown (not homed)
};

// `actual`: feedback (carte_pos_fb) instead of the commanded position.
DroPositions dro_positions(const ipc::Status& s, bool actual);

// The G5x offsets (program units) that make the current position read
// `value` on `axis` in the active coordinate system, every other axis
// unchanged.
Pose touch_off_offsets(const ipc::Status& s, int axis, double value, bool actual);

// G7 (lathe diameter mode) is active.
bool diameter_mode(const ipc::Status& s) noexcept;

// "G54".."G59.3" for 1..9; "G92" for 0.
std::string work_offset_name(int index);

// Work offsets as the parameter file holds them (LinuxCNC numbering:
// 5221 + 20*(n-1) + axis for G54..G59.3, +9 the XY rotation; 5211.. G92;
// 5220 the active system).
struct WorkOffsets {
  Pose g5x[9];
  double rotation[9] = {};
  Pose g92;
  int active = 1;
  bool loaded = false;
  std::string error;
};
std::map<int, double> parse_parameter_text(std::string_view text);
WorkOffsets work_offsets_from_parameters(const std::map<int, double>& params);
WorkOffsets read_work_offsets(const std::filesystem::path& parameter_file);

}  // namespace cnc::hmi
