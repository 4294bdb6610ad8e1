#include "comp/error_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace cnc::comp {

SplineBasis spline_basis(double x, double x_min, double x_max, std::size_t segments) noexcept {
  SplineBasis b;
  if (segments == 0 || !(x_max > x_min)) return b;
  const double h = (x_max - x_min) / static_cast<double>(segments);
  const double u = (std::clamp(x, x_min, x_max) - x_min) / h;
  std::size_t k = static_cast<std::size_t>(std::floor(u));
  if (k >= segments) k = segments - 1;
  const double t = u - static_cast<double>(k);
  const double t2 = t * t, t3 = t2 * t;
  b.first = k;
  b.w[0] = (1 - 3 * t + 3 * t2 - t3) / 6;
  b.w[1] = (4 - 6 * t2 + 3 * t3) / 6;
  b.w[2] = (1 + 3 * t + 3 * t2 - 3 * t3) / 6;
  b.w[3] = t3 / 6;
  return b;
}

double ErrorModel::geometric_um(double x) const noexcept {
  const SplineBasis b = spline_basis(x, x_min, x_max, segments());
  if (segments() == 0) return 0;
  double s = 0;
  for (int i = 0; i < 4; ++i) s += b.w[i] * spline[b.first + static_cast<std::size_t>(i)];
  return s;
}

double ErrorModel::backlash_um(double x) const noexcept {
  const double L = length() > 0 ? length() : 1;
  return backlash0_um + backlash1_um * (x - middle()) / L;
}

double ErrorModel::periodic_um(double x) const noexcept {
  if (!(lead_mm > 0)) return 0;
  double s = 0;
  for (std::size_t h = 0; h < sin_um.size(); ++h) {
    const double ph = 2 * std::numbers::pi * static_cast<double>(h + 1) * x / lead_mm;
    s += sin_um[h] * std::sin(ph) + cos_um[h] * std::cos(ph);
  }
  return s;
}

double ErrorModel::thermal_um(double x, double temperature_c) const noexcept {
  if (!has_thermal || !std::isfinite(temperature_c)) return 0;
  return thermal_ppm_per_k * (temperature_c - reference_temperature_c) * (x - thermal_origin_mm) * 1e-3;
}

double ErrorModel::deviation_um(double x, int direction, double temperature_c) const noexcept {
  return geometric_um(x) + (direction > 0 ? 0.5 : -0.5) * backlash_um(x) + periodic_um(x) +
         thermal_um(x, temperature_c);
}

}  // namespace cnc::comp
