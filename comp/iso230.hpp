// ISO 230-2 (2014) evaluation of one axis's positioning: per target the
// mean unidirectional deviations, reversal value, estimators of standard
// uncertainty and repeatabilities; for the axis the reversal values B and
// mean B, the repeatabilities R, the systematic deviations E, the mean
// bidirectional deviation range M and the accuracies A (unidirectional and
// bidirectional). Units are those of the measurement (micrometres).
// Non-realtime. The formulas are listed in docs/compensation.md.
#pragma once

#include <string>
#include <vector>

#include "comp/measurement.hpp"

namespace cnc::comp {

struct Iso230Target {
  double position = 0;                 // P_i
  int n_up = 0, n_down = 0;            // runs measured in each direction
  double mean_up = 0, mean_down = 0;   // x̄_i↑, x̄_i↓
  double mean = 0;                     // x̄_i = (x̄_i↑ + x̄_i↓) / 2
  double reversal = 0;                 // B_i = x̄_i↑ - x̄_i↓
  double s_up = 0, s_down = 0;         // s_i↑, s_i↓ (n - 1 in the denominator)
  double r_up = 0, r_down = 0;         // R_i↑ = 4 s_i↑, R_i↓ = 4 s_i↓
  double r = 0;                        // R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)
};

struct Iso230Result {
  std::vector<Iso230Target> targets;   // ascending position
  int min_runs = 0;                    // smallest n over targets and directions
  double B = 0;                        // max |B_i|
  double B_mean = 0;                   // mean of B_i (signed)
  double R_up = 0, R_down = 0, R = 0;  // max R_i↑, max R_i↓, max R_i
  double E_up = 0, E_down = 0, E = 0;  // systematic positional deviation
  double M = 0;                        // mean bidirectional positional deviation range
  double A_up = 0, A_down = 0, A = 0;  // accuracy
  std::vector<std::string> warnings;   // where the data fall short of the standard test
};

// Groups the points by target (positions within `tolerance` are one
// target). Every target needs at least two runs in each direction; throws
// std::invalid_argument saying which target lacks them.
Iso230Result evaluate_iso230(const Measurement& m, double tolerance = 1e-6);

}  // namespace cnc::comp
