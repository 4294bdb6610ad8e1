// Positioning measurements of one axis (ISO 230-2: targets, runs, approach
// direction, deviation) and their CSV file, documented in
// docs/compensation.md:
//
//   # comment lines start with '#'; "# axis: X" names the axis
//   target,run,direction,deviation_um[,temperature_c][,time_s]
//   25.000,1,+,1.234,20.51,12.0
//
// target in machine units (mm), direction + (approached moving +) or -,
// deviation = position reached minus target, in micrometres. Non-realtime.
#pragma once

#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::comp {

struct MeasurementPoint {
  double target = 0;       // P_i, machine units
  int run = 1;             // j = 1..n, counted per target and direction
  int direction = 1;       // +1: approached moving +, -1: moving -
  double deviation_um = 0; // x_ij = reached - target
  double temperature_c = std::numeric_limits<double>::quiet_NaN();
  double time_s = std::numeric_limits<double>::quiet_NaN();
};

struct Measurement {
  std::string axis;                  // from "# axis: X", may be empty
  std::vector<MeasurementPoint> points;
  std::vector<std::string> notes;    // other comment lines, in order

  bool has_temperature() const noexcept;
  bool has_time() const noexcept;
};

// What a measurement file may hold. Values outside are refused as a unit
// mistake (nanometres or millimetres for micrometres, kelvin for Celsius)
// or a broken file, not read as numbers that a fit would turn into trims.
struct MeasurementLimits {
  // |deviation_um|: 1 mm, also screwcomp's default max_correction. An axis
  // with a larger error needs mechanical work, or this raised knowingly.
  double max_abs_deviation_um = 1000;
  double max_abs_target = 1e6;                   // machine units
  double min_temperature_c = -50, max_temperature_c = 150;
  double max_abs_time_s = 1e9;
};

// Throws ConfigError naming file and line: malformed lines, values outside
// `limits`, and a (target, direction, run) that appears twice (a copied
// block would otherwise count as extra runs).
Measurement parse_measurement(std::string_view text, const std::string& file_name,
                              const MeasurementLimits& limits = {});
Measurement load_measurement(const std::filesystem::path& path, const MeasurementLimits& limits = {});
std::string format_measurement(const Measurement& m);
// Numbers the runs 1, 2, ... per (target, direction) in the order of the
// points; targets closer than `tolerance` are the same target.
void number_runs(Measurement& m, double tolerance = 1e-6);

}  // namespace cnc::comp
