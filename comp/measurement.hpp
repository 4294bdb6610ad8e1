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

// Throws ConfigError naming file and line.
Measurement parse_measurement(std::string_view text, const std::string& file_name);
Measurement load_measurement(const std::filesystem::path& path);
std::string format_measurement(const Measurement& m);
// Numbers the runs 1, 2, ... per (target, direction) in the order of the
// points; targets closer than `tolerance` are the same target.
void number_runs(Measurement& m, double tolerance = 1e-6);

}  // namespace cnc::comp
