// The fitted positioning-error model of one axis (deviation = position
// reached minus commanded, micrometres, at commanded position x in mm,
// approach direction d = +-1, temperature T):
//
//   dev(x, d, T) = S(x)                                    smooth geometric error
//                + d (b0 + b1 (x - x_mid) / L) / 2         backlash, may vary along travel
//                + k (T - T_ref) (x - x_0) 1e-3            thermal expansion, k in ppm/K
//                + sum_h a_h sin(2 pi h x / lead) + c_h cos(2 pi h x / lead)   lead-periodic error
//
// S is a uniform cubic B-spline over [x_min, x_max], held constant outside.
// Plain data and evaluation; the fit (Ceres) is in fit.hpp. Non-realtime.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

namespace cnc::comp {

struct ErrorModel {
  // Geometric error S(x): cubic B-spline, `spline.size() - 3` segments.
  double x_min = 0, x_max = 1;
  std::vector<double> spline;          // coefficients, micrometres
  // Backlash (the reversal B(x) = b0 + b1 (x - x_mid) / L), micrometres.
  double backlash0_um = 0, backlash1_um = 0;
  // False when the data had no target measured in both directions: the
  // backlash terms are 0 by assumption, not measured.
  bool backlash_measured = true;
  // Thermal expansion.
  bool has_thermal = false;
  double thermal_ppm_per_k = 0;
  double reference_temperature_c = 20;
  double thermal_origin_mm = 0;        // where expansion does not move the axis (the screw's fixed bearing)
  // Lead-periodic error.
  double lead_mm = 0;                  // 0: none
  std::vector<double> sin_um, cos_um;  // per harmonic 1, 2, ...

  double length() const noexcept { return x_max - x_min; }
  double middle() const noexcept { return (x_min + x_max) / 2; }
  std::size_t segments() const noexcept { return spline.size() < 4 ? 0 : spline.size() - 3; }

  double geometric_um(double x) const noexcept;
  double backlash_um(double x) const noexcept;  // the reversal value at x
  double periodic_um(double x) const noexcept;
  double thermal_um(double x, double temperature_c) const noexcept;
  // Deviation at direction d (+1/-1); temperature NaN: the reference.
  double deviation_um(double x, int direction,
                      double temperature_c = std::numeric_limits<double>::quiet_NaN()) const noexcept;
};

// Uniform cubic B-spline basis over `segments` segments of [x_min, x_max]:
// the first of the four coefficients x touches and their weights. Outside
// the range x is clamped: S holds its end values, as tables do.
struct SplineBasis {
  std::size_t first = 0;
  double w[4] = {0, 0, 0, 0};
};
SplineBasis spline_basis(double x, double x_min, double x_max, std::size_t segments) noexcept;

}  // namespace cnc::comp
