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

#include <string>

#include "comp/error_model.hpp"

namespace cnc::comp {

struct ExportOptions {
  std::string axis = "X";           // axis name (Siemens: machine axis, e.g. X1 or AX1)
  double x_min = 0, x_max = 0;      // range (equal: the model's)
  double spacing_mm = 0;            // 0: each format's default
  double reference_mm = std::numeric_limits<double>::quiet_NaN();  // correction 0 here (NaN: x_min)
  // Fanuc
  int fanuc_axis = 1;               // axis number in the tape (A1, A2...)
  double fanuc_unit_um = 1;         // detection unit
  int fanuc_magnification = 1;      // parameter 3623
  int fanuc_reference_point = 100;  // parameter 3620: number of the point at the reference position
  bool fanuc_bidirectional = true;  // 3605#0 and the negative-direction table (3626, 3627)
};

std::string export_linuxcnc(const ErrorModel& model, const ExportOptions& o, int type, int max_points = 256);
std::string export_siemens_lec(const ErrorModel& model, const ExportOptions& o);
std::string export_heidenhain_com(const ErrorModel& model, const ExportOptions& o);
std::string export_fanuc_pitch(const ErrorModel& model, const ExportOptions& o);

}  // namespace cnc::comp
