// Compensation tables from a fitted error model: the model sampled at the
// reference temperature on evenly spaced nominals, forward trim =
// -deviation moving +, reverse trim = -deviation moving - (machine units),
// and how far linear interpolation of the table strays from the model.
// Offline only.
#pragma once

#include "comp/comp_table.hpp"
#include "comp/error_model.hpp"
#include "comp/measurement.hpp"

namespace cnc::comp {

struct TableOptions {
  double x_min = 0, x_max = 0;      // range (equal: the model's)
  double spacing_mm = 0;            // > 0: this spacing
  int points = 0;                   // > 0 (and no spacing): this many points
  // Neither: the widest spacing whose interpolation stays within
  // `tolerance_um` of the model, at most `max_points` points.
  double tolerance_um = 0.05;
  int max_points = 20000;
  double reference_mm = std::numeric_limits<double>::quiet_NaN();  // mean correction 0 here (NaN: none)
  double um_per_unit = 1000;        // micrometres per machine unit
};

CompTable make_comp_table(const ErrorModel& model, const TableOptions& options);
// Largest |interpolated table - model correction| over the table's range
// (both directions, sampled finely), micrometres.
double interpolation_error_um(const CompTable& table, const ErrorModel& model, double reference_offset_um = 0,
                              double um_per_unit = 1000);
// The correction offset (um) that make_comp_table applies for `options`
// (minus the mean deviation at the reference position, or 0).
double reference_offset_um(const ErrorModel& model, const TableOptions& options);

// The measurement as the compensated machine would show it: every
// deviation plus the table's correction at its target and direction
// (`um_per_unit` micrometres per machine unit).
Measurement predicted_after(const Measurement& m, const CompTable& table, double um_per_unit = 1000);

}  // namespace cnc::comp
