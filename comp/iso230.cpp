#include "comp/iso230.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace cnc::comp {
namespace {

struct Group {
  double position = 0;
  std::vector<double> up, down;
};

double mean_of(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// Estimator of the standard uncertainty over the runs (n - 1).
double sigma_of(const std::vector<double>& v, double mean) {
  double s = 0;
  for (double x : v) s += (x - mean) * (x - mean);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

std::string where(double p) {
  char b[64];
  std::snprintf(b, sizeof b, "target %g", p);
  return b;
}

}  // namespace

Iso230Result evaluate_iso230(const Measurement& m, double tolerance) {
  std::vector<Group> groups;
  double largest = 0;
  for (const MeasurementPoint& p : m.points) {
    if (!std::isfinite(p.target) || !std::isfinite(p.deviation_um)) {
      throw std::invalid_argument(where(p.target) + ": a deviation or target that is not a finite number");
    }
    largest = std::max(largest, std::fabs(p.deviation_um));
    auto it = std::find_if(groups.begin(), groups.end(),
                           [&](const Group& g) { return std::fabs(g.position - p.target) <= tolerance; });
    if (it == groups.end()) {
      groups.push_back(Group{p.target, {}, {}});
      it = groups.end() - 1;
    }
    (p.direction > 0 ? it->up : it->down).push_back(p.deviation_um);
  }
  if (groups.empty()) throw std::invalid_argument("no measured points");
  std::sort(groups.begin(), groups.end(), [](const Group& a, const Group& b) { return a.position < b.position; });

  Iso230Result r;
  r.min_runs = 1 << 30;
  for (const Group& g : groups) {
    if (g.up.size() < 2 || g.down.size() < 2) {
      throw std::invalid_argument(where(g.position) + ": ISO 230-2 needs at least two runs in each direction (found " +
                                  std::to_string(g.up.size()) + " moving + and " + std::to_string(g.down.size()) +
                                  " moving -)");
    }
    Iso230Target t;
    t.position = g.position;
    t.n_up = static_cast<int>(g.up.size());
    t.n_down = static_cast<int>(g.down.size());
    t.mean_up = mean_of(g.up);
    t.mean_down = mean_of(g.down);
    t.mean = (t.mean_up + t.mean_down) / 2;
    t.reversal = t.mean_up - t.mean_down;
    t.s_up = sigma_of(g.up, t.mean_up);
    t.s_down = sigma_of(g.down, t.mean_down);
    t.r_up = 4 * t.s_up;
    t.r_down = 4 * t.s_down;
    t.r = std::max({2 * t.s_up + 2 * t.s_down + std::fabs(t.reversal), t.r_up, t.r_down});
    r.min_runs = std::min({r.min_runs, t.n_up, t.n_down});
    r.targets.push_back(t);
  }

  double up_max = -1e300, up_min = 1e300, down_max = -1e300, down_min = 1e300;
  double mean_max = -1e300, mean_min = 1e300;
  double aup_max = -1e300, aup_min = 1e300, adown_max = -1e300, adown_min = 1e300;
  double b_sum = 0;
  for (const Iso230Target& t : r.targets) {
    r.B = std::max(r.B, std::fabs(t.reversal));
    b_sum += t.reversal;
    r.R_up = std::max(r.R_up, t.r_up);
    r.R_down = std::max(r.R_down, t.r_down);
    r.R = std::max(r.R, t.r);
    up_max = std::max(up_max, t.mean_up);
    up_min = std::min(up_min, t.mean_up);
    down_max = std::max(down_max, t.mean_down);
    down_min = std::min(down_min, t.mean_down);
    mean_max = std::max(mean_max, t.mean);
    mean_min = std::min(mean_min, t.mean);
    aup_max = std::max(aup_max, t.mean_up + 2 * t.s_up);
    aup_min = std::min(aup_min, t.mean_up - 2 * t.s_up);
    adown_max = std::max(adown_max, t.mean_down + 2 * t.s_down);
    adown_min = std::min(adown_min, t.mean_down - 2 * t.s_down);
  }
  r.B_mean = b_sum / static_cast<double>(r.targets.size());
  r.E_up = up_max - up_min;
  r.E_down = down_max - down_min;
  r.E = std::max(up_max, down_max) - std::min(up_min, down_min);
  r.M = mean_max - mean_min;
  r.A_up = aup_max - aup_min;
  r.A_down = adown_max - adown_min;
  r.A = std::max(aup_max, adown_max) - std::min(aup_min, adown_min);

  if (!std::isfinite(r.A) || !std::isfinite(r.R)) {
    throw std::invalid_argument("the deviations are too large for the figures to be computed (A or R overflows)");
  }
  if (largest < 0.01) {
    r.warnings.push_back("every deviation is below 0.01 um: are they in millimetres? (deviation_um is in micrometres)");
  }
  if (r.min_runs < 5) {
    r.warnings.push_back("fewer than the 5 runs per direction of the standard test cycle (" +
                         std::to_string(r.min_runs) + ")");
  }
  if (r.targets.size() < 5) {
    r.warnings.push_back("fewer than the 5 targets the standard asks for (" + std::to_string(r.targets.size()) + ")");
  }
  const double travel = r.targets.back().position - r.targets.front().position;
  if (travel > 0 && static_cast<double>(r.targets.size()) < 5 * travel / 1000.0) {
    r.warnings.push_back("fewer than 5 targets per metre of travel");
  }
  return r;
}

}  // namespace cnc::comp
