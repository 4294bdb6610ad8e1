// The simulated part of configs/sim for probing (sim_part, docs/hmi.md
// "Probe page"): a rectangular block standing on the table with a round
// bore through it, and a ball-ended probe tip. Positions are physical axis
// positions (the drives' table-position pins, mm): the tip centre at
// (x, y, z) relative to the part, each axis' + direction as the machine's.
// The block is the prism [x_min, x_max] x [y_min, y_max] below z_top
// (extending down without end), less the cylinder of bore_diameter about
// (bore_x, bore_y). Pure geometry: no HAL, no allocation.
#pragma once

namespace cnc::ini {
class IniFile;
}

namespace cnc::sim {

struct Part {
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
  double z_top = 0;
  double bore_x = 0, bore_y = 0, bore_diameter = 0;  // 0: no bore
  double tip_diameter = 0;                           // the probe's ball (0: a point)

  // Reads `section` ([SIM_PART]: X_MIN, X_MAX, Y_MIN, Y_MAX, Z_TOP
  // required; BORE_X, BORE_Y, BORE_DIAMETER, TIP_DIAMETER); throws
  // ConfigError naming file, line and key for an empty block or a bore that
  // does not lie inside the block with a wall left around it.
  static Part from_ini(const ini::IniFile& ini, const char* section);

  // Horizontal distance from (x, y) to the block's cross-section (0 on or
  // inside the material).
  double distance_xy(double x, double y) const noexcept;
  // Distance from the tip centre to the material (0 inside it).
  double distance(double x, double y, double z) const noexcept;
  // The ball touches (or is pressed into) the material.
  bool touches(double x, double y, double z) const noexcept { return distance(x, y, z) <= tip_diameter / 2; }
};

}  // namespace cnc::sim
