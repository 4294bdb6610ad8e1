#include "sim/machine/part.hpp"

#include <algorithm>
#include <cmath>

#include "core/ini/ini_file.hpp"

namespace cnc::sim {

Part Part::from_ini(const ini::IniFile& ini, const char* section) {
  Part p;
  p.x_min = ini.require_double(section, "X_MIN");
  p.x_max = ini.require_double(section, "X_MAX");
  p.y_min = ini.require_double(section, "Y_MIN");
  p.y_max = ini.require_double(section, "Y_MAX");
  p.z_top = ini.require_double(section, "Z_TOP");
  p.bore_diameter = ini.get_double(section, "BORE_DIAMETER", 0, {0, 1e9});
  p.bore_x = ini.get_double(section, "BORE_X", (p.x_min + p.x_max) / 2);
  p.bore_y = ini.get_double(section, "BORE_Y", (p.y_min + p.y_max) / 2);
  p.tip_diameter = ini.get_double(section, "TIP_DIAMETER", 0, {0, 1e9});
  const std::string s = std::string("[") + section + "]";
  if (p.x_max <= p.x_min) ini.fail(ini.find_entry(section, "X_MAX"), s + "X_MAX must be above X_MIN: the block is empty");
  if (p.y_max <= p.y_min) ini.fail(ini.find_entry(section, "Y_MAX"), s + "Y_MAX must be above Y_MIN: the block is empty");
  if (p.bore_diameter > 0) {
    const double r = p.bore_diameter / 2;
    // The distance to the block's outside ignores the bore: it must not
    // break through a side.
    if (p.bore_x - r <= p.x_min || p.bore_x + r >= p.x_max || p.bore_y - r <= p.y_min || p.bore_y + r >= p.y_max) {
      ini.fail(ini.find_entry(section, "BORE_DIAMETER"),
               s + "BORE_DIAMETER: the bore about BORE_X/BORE_Y must lie inside the block with a wall around it");
    }
  }
  return p;
}

double Part::distance_xy(double x, double y) const noexcept {
  const double dx = std::max({x_min - x, 0.0, x - x_max});
  const double dy = std::max({y_min - y, 0.0, y - y_max});
  if (dx > 0 || dy > 0) return std::hypot(dx, dy);  // outside the block
  if (bore_diameter > 0) {
    const double from_axis = std::hypot(x - bore_x, y - bore_y);
    if (from_axis < bore_diameter / 2) return bore_diameter / 2 - from_axis;  // in the bore
  }
  return 0;
}

double Part::distance(double x, double y, double z) const noexcept {
  const double d = distance_xy(x, y);
  if (z <= z_top) return d;
  // Above the top face: to its nearest point (on an edge when d > 0).
  return std::hypot(d, z - z_top);
}

}  // namespace cnc::sim
