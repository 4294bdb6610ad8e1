// A synthetic axis with known errors, for tests, benchmarks and
// demonstrations: scale error, a local bump, lead-periodic error, backlash
// varying along travel, thermal expansion while the machine warms up,
// measurement noise and a few gross outliers (interferometer drop-outs).
// It produces measurements as the ISO 230-2 cycle and the dense periodic
// runs would. Seeded, reproducible. Offline only.
#pragma once

#include <cstdint>
#include <vector>

#include "comp/measurement.hpp"

namespace cnc::comp {

struct SyntheticAxis {
  double x_min = 0, x_max = 300;
  double scale_ppm = 15;                       // linear error: the screw is 15 um/m long
  double bump_um = 3, bump_at_mm = 180, bump_width_mm = 40;  // a local wave in the screw
  double lead_mm = 5, periodic_amplitude_um = 1.5, periodic_phase_deg = 30;
  double backlash0_um = 8, backlash1_um = 2;   // reversal b0 + b1 (x - mid) / L
  double thermal_ppm_per_k = 11.5;             // steel
  double reference_c = 20, start_c = 20.2, warmup_k = 2.0, warmup_tau_s = 900;
  double noise_um = 0.1;
  int outliers = 3;
  double outlier_um = 25;
  double seconds_per_point = 4;                // moving, settling, averaging

  // The truth: deviation at x (mm), direction, temperature (C).
  double deviation_um(double x, int direction, double temperature_c) const;
  double geometric_um(double x) const;
  double backlash_um(double x) const;
  double periodic_um(double x) const;
  double temperature_at(double t_s) const;
};

// Measures `positions` in the order of an ISO linear cycle (`runs` times up
// through them, then down), continuing the clock from `start_s`.
// `with_temperature`: the temperature column is filled.
Measurement synthesize_cycle(const SyntheticAxis& axis, const std::vector<double>& positions, int runs, uint64_t seed,
                             bool with_temperature, double start_s = 0);

}  // namespace cnc::comp
