// Compensation tables in the formats of other controls, from a fitted model
// (docs/compensation.md describes each file, its sign convention and what
// to confirm on the control's own manual before loading it):
//  - LinuxCNC COMP_FILE (type 0 or 1), at most 256 entries for LinuxCNC;
//  - Siemens SINUMERIK LEC (measuring-system error compensation) as an
//    `%_N_AX_EEC_INI` part program of $AA_ENC_COMP system variables, with
//    the backlash for MD32450;
//  - Heidenhain nonlinear axis-error table (*.COM: NR, AXISPOS, axis,
//    BACKLASH columns);
//  - Fanuc pitch-error compensation parameters (3620-3627 and the
//    incremental compensation data N10000+) as a parameter tape.
// Offline only.
#pragma once

#include <limits>
#include <string>

#include "comp/error_model.hpp"

namespace cnc::comp {

struct ExportOptions {
  std::string axis = "X";           // axis name (Siemens: machine axis, e.g. X1 or AX1)
  double x_min = 0, x_max = 0;      // range (equal: the model's)
  double spacing_mm = 0;            // 0: each format's default
  double reference_mm = std::numeric_limits<double>::quiet_NaN();  // correction 0 here (NaN: x_min)
  // Fanuc. Compensation point numbers are shared by all axes: each axis
  // needs its own range, or loading one axis's tape overwrites another's.
  int fanuc_axis = 0;               // controlled-axis number in the tape (A1, A2...); 0: X 1, Y 2, Z 3, others refused
  double fanuc_unit_um = 1;         // detection unit, micrometres (> 0)
  int fanuc_magnification = 1;      // parameter 3623, 1..100: the data are in detection units x this
  int fanuc_reference_point = -1;   // parameter 3620: number of the point at the reference position;
                                    // -1: in the axis's block of kFanucPointsPerAxis, (axis - 1) x 256 up
  bool fanuc_bidirectional = true;  // 3605#0 and the negative-direction table (3626, 3627)
};

// Default points per axis: both directions' tables of up to 128 points each.
inline constexpr int kFanucPointsPerAxis = 256;

// The point numbers a Fanuc tape uses (for the user to check they are free).
struct FanucPoints {
  int axis = 0;
  int reference = 0;            // 3620
  int first = 0, last = 0;      // 3621, 3622: the positive-direction table
  int neg_first = -1, neg_last = -1;  // the negative-direction table (bidirectional only)
};

std::string export_linuxcnc(const ErrorModel& model, const ExportOptions& o, int type, int max_points = 256);
std::string export_siemens_lec(const ErrorModel& model, const ExportOptions& o);
std::string export_heidenhain_com(const ErrorModel& model, const ExportOptions& o);
// Throws std::invalid_argument naming the option when the axis number is
// not known (an axis other than X, Y, Z without fanuc_axis), an option is
// out of range, or the table does not fit the reference point given.
std::string export_fanuc_pitch(const ErrorModel& model, const ExportOptions& o, FanucPoints* used = nullptr);

}  // namespace cnc::comp
