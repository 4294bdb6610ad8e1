// Fits the axis error model (error_model.hpp) to measurements by robust
// nonlinear least squares (Ceres: automatic differentiation, dense QR):
// the B-spline with a second-difference smoothness prior, backlash constant
// or varying linearly along travel, thermal expansion when temperatures
// change during the measurements, and the lead-periodic term. Gross
// outliers are kept from bending the fit by a robust loss scaled to the
// noise the data show. Parameters come with standard uncertainties from
// the covariance of the solution. Offline only (never in the servo thread).
#pragma once

#include <string>
#include <vector>

#include "comp/error_model.hpp"
#include "comp/measurement.hpp"

namespace cnc::comp {

enum class RobustLoss { None, Huber, Cauchy };

struct FitOptions {
  double knot_spacing_mm = 0;        // 0: the ISO target spacing, at least two leads
  double smoothness_um = 2.0;        // prior standard deviation of the spline's second differences
  double lead_mm = 0;                // screw lead for the periodic term (0: no periodic term)
  int harmonics = 1;                 // 1 or 2
  bool backlash_varies = true;       // b1 (backlash changing along travel) fitted
  bool thermal = true;               // fitted when the temperatures vary by at least min_temperature_range_k
  double min_temperature_range_k = 0.3;
  double reference_temperature_c = 20;
  RobustLoss loss = RobustLoss::Cauchy;
  double loss_scale = 3.0;           // in noise standard deviations
  double noise_um = 0;               // 0: estimated from the data (repeatability, then residuals)
  int max_iterations = 100;
  double x_min = 0, x_max = 0;       // spline range; equal: the measured range
};

struct ParameterEstimate {
  std::string name;
  double value = 0;
  double sigma = 0;  // standard uncertainty
  std::string unit;
};

struct FitResult {
  ErrorModel model;
  std::vector<ParameterEstimate> parameters;
  std::vector<double> residuals_um;  // measured - model, per point in input order
  double noise_um = 0;               // noise standard deviation used for the weights
  double residual_rms_um = 0;        // of the points not counted as outliers
  int outliers = 0;                  // |residual| > 5 noise
  int points = 0;
  int reversal_targets = 0;          // targets measured in both directions (0: backlash not fitted, see notes)
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  bool converged = false;
  bool covariance_ok = false;
  double max_geometric_sigma_um = 0; // largest standard uncertainty of S(x) over the range
  std::vector<std::string> notes;    // choices made (terms dropped, spacing used...)
  // Standard uncertainty of the model's deviation at (x, direction), at the
  // reference temperature, from the parameter covariance.
  double deviation_sigma_um(double x, int direction) const;

  // Full covariance of the parameters, in the order of `layout`.
  std::vector<double> covariance;
  struct Layout {
    std::size_t spline = 0, backlash = 0, thermal = 0, periodic = 0, size = 0;
  } layout;
};

// Fits all points of `data` (several measurements may be combined: an ISO
// cycle and dense periodic runs). Throws std::invalid_argument when the
// data cannot support the model (too few points, no travel).
FitResult fit_error_model(const std::vector<Measurement>& data, const FitOptions& options);

}  // namespace cnc::comp
