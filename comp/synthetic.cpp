#include "comp/synthetic.hpp"

#include <cmath>
#include <numbers>
#include <random>

namespace cnc::comp {

double SyntheticAxis::geometric_um(double x) const {
  const double u = (x - bump_at_mm) / bump_width_mm;
  return scale_ppm * (x - x_min) * 1e-3 + bump_um * std::exp(-u * u);
}

double SyntheticAxis::backlash_um(double x) const {
  const double L = x_max - x_min;
  return backlash0_um + backlash1_um * (x - (x_min + x_max) / 2) / L;
}

double SyntheticAxis::periodic_um(double x) const {
  if (!(lead_mm > 0)) return 0;
  return periodic_amplitude_um * std::sin(2 * std::numbers::pi * x / lead_mm + periodic_phase_deg * std::numbers::pi / 180);
}

double SyntheticAxis::temperature_at(double t_s) const {
  return start_c + warmup_k * (1 - std::exp(-t_s / warmup_tau_s));
}

double SyntheticAxis::deviation_um(double x, int direction, double temperature_c) const {
  return geometric_um(x) + (direction > 0 ? 0.5 : -0.5) * backlash_um(x) + periodic_um(x) +
         thermal_ppm_per_k * (temperature_c - reference_c) * (x - x_min) * 1e-3;
}

Measurement synthesize_cycle(const SyntheticAxis& axis, const std::vector<double>& positions, int runs, uint64_t seed,
                             bool with_temperature, double start_s) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, axis.noise_um);
  Measurement m;
  m.axis = "X";
  m.notes.push_back("synthetic axis, seed " + std::to_string(seed));
  double t = start_s;
  for (int run = 1; run <= runs; ++run) {
    for (int dir : {1, -1}) {
      for (std::size_t k = 0; k < positions.size(); ++k) {
        const double x = dir > 0 ? positions[k] : positions[positions.size() - 1 - k];
        t += axis.seconds_per_point;
        const double T = axis.temperature_at(t);
        MeasurementPoint p;
        p.target = x;
        p.run = run;
        p.direction = dir;
        p.deviation_um = axis.deviation_um(x, dir, T) + noise(rng);
        if (with_temperature) p.temperature_c = std::round(T * 1000) / 1000;
        p.time_s = t;
        m.points.push_back(p);
      }
    }
  }
  // Gross outliers at random points (a beam interrupted, a bumped reflector).
  std::uniform_int_distribution<std::size_t> pick(0, m.points.size() - 1);
  std::uniform_int_distribution<int> sign(0, 1);
  for (int i = 0; i < axis.outliers; ++i) {
    m.points[pick(rng)].deviation_um += (sign(rng) ? 1 : -1) * axis.outlier_um;
  }
  return m;
}

}  // namespace cnc::comp
