#include "comp/cycle.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

namespace cnc::comp {
namespace {

int target_count(const CycleOptions& o) {
  if (o.targets > 0) return std::max(o.targets, 2);
  const double travel = o.x_max - o.x_min;
  return std::max({5, static_cast<int>(std::ceil(5 * travel / 1000.0)), static_cast<int>(std::round(travel / 25)) + 1});
}

void check(const CycleOptions& o) {
  if (!(o.x_max > o.x_min)) throw std::invalid_argument("the last target must lie above the first");
  if (o.runs < 1) throw std::invalid_argument("at least one run");
  if (!(o.overshoot_mm >= 0) || !(o.dwell_s >= 0) || !(o.feed_mm_min > 0)) {
    throw std::invalid_argument("overshoot and dwell must not be negative, the feed must be positive");
  }
}

std::string pos(char axis, double x) {
  char b[64];
  std::snprintf(b, sizeof b, "G53 G1 %c%.4f", axis, x);
  return b;
}

// One linear run up through `t` and back down, overshooting at both ends.
void emit_runs(std::string& out, const CycleOptions& o, const std::vector<double>& t, int runs, double dwell) {
  char b[96];
  std::snprintf(b, sizeof b, "G4 P%.3f\n", dwell);
  const std::string dwell_line = b;
  const double lo = t.front() - o.overshoot_mm, hi = t.back() + o.overshoot_mm;
  for (int run = 1; run <= runs; ++run) {
    out += "(run " + std::to_string(run) + " up)\n";
    for (double x : t) out += pos(o.axis, x) + "\n" + dwell_line;
    out += pos(o.axis, hi) + " (overshoot)\n";
    out += "(run " + std::to_string(run) + " down)\n";
    for (auto it = t.rbegin(); it != t.rend(); ++it) out += pos(o.axis, *it) + "\n" + dwell_line;
    out += pos(o.axis, lo) + " (overshoot)\n";
  }
}

std::string header(const CycleOptions& o, const std::string& what) {
  char b[256];
  std::string out = "(" + what + ", axis " + std::string(1, o.axis) + ", written by cnc-comp cycle)\n";
  // Both marks low now (the program starts at rest): the logger sees a
  // clean rising edge when the measurement starts, then when it ends.
  std::snprintf(b, sizeof b, "M65 P%d\nM65 P%d\n", o.digital_out, o.digital_out + 1);
  out += b;
  std::snprintf(b, sizeof b, "(feed %.0f mm/min, dwell %.2f s, overshoot %.3f mm, targets seed %llu)\n", o.feed_mm_min,
                o.dwell_s, o.overshoot_mm, static_cast<unsigned long long>(o.seed));
  out += b;
  std::snprintf(b, sizeof b, "G21 G90 G94 G17 G40 G49 G80 G61\nF%.1f\n", o.feed_mm_min);
  out += b;
  return out;
}

}  // namespace

std::vector<double> iso_targets(const CycleOptions& o) {
  check(o);
  const int m = target_count(o);
  const double p = (o.x_max - o.x_min) / (m - 1);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> r(-p / 5, p / 5);
  std::vector<double> t;
  for (int i = 0; i < m; ++i) {
    double x = o.x_min + i * p;
    if (i > 0 && i < m - 1) x += r(rng);
    t.push_back(std::round(x * 1000) / 1000);
  }
  return t;
}

std::vector<double> periodic_targets(const CycleOptions& o, int place) {
  check(o);
  if (!(o.lead_mm > 0) || o.periodic_steps_per_lead < 2) return {};
  const double length = o.lead_mm * o.periodic_leads;
  const int places = std::max(1, o.periodic_places);
  const double span = std::max(o.x_max - o.x_min - length, 0.0);
  const double start = o.x_min + (places == 1 ? span / 2 : span * place / (places - 1));
  const int steps = static_cast<int>(std::round(o.periodic_leads * o.periodic_steps_per_lead));
  std::vector<double> t;
  for (int k = 0; k <= steps; ++k) t.push_back(std::round((start + length * k / steps) * 1000) / 1000);
  return t;
}

std::string iso_cycle_gcode(const CycleOptions& o) {
  const std::vector<double> t = iso_targets(o);
  std::string out = header(o, "ISO 230-2 standard test cycle: " + std::to_string(t.size()) + " targets, " +
                                  std::to_string(o.runs) + " runs each way");
  out += "(targets:";
  char b[32];
  for (double x : t) {
    std::snprintf(b, sizeof b, " %.3f", x);
    out += b;
  }
  out += ")\n";
  out += pos(o.axis, t.front() - o.overshoot_mm) + " (start below the first target)\nG4 P0.05\n";
  out += "M62 P" + std::to_string(o.digital_out) + " (measurement on with the next move)\n";
  emit_runs(out, o, t, o.runs, o.dwell_s);
  out += "M62 P" + std::to_string(o.digital_out + 1) + " (measurement end with the next move)\n";
  out += pos(o.axis, t.front()) + "\nM2\n";
  return out;
}

std::string periodic_cycle_gcode(const CycleOptions& o) {
  if (!(o.lead_mm > 0)) throw std::invalid_argument("the periodic runs need the screw lead");
  std::string out = header(o, "Dense runs for the lead-periodic error, ISO 230-2 Annex C: " +
                                  std::to_string(o.periodic_places) + " places, " + std::to_string(o.periodic_runs) +
                                  " runs each way");
  bool first = true;
  for (int place = 0; place < std::max(1, o.periodic_places); ++place) {
    const std::vector<double> t = periodic_targets(o, place);
    out += "(place " + std::to_string(place + 1) + ")\n";
    out += pos(o.axis, t.front() - o.overshoot_mm) + "\nG4 P0.05\n";
    if (first) {
      out += "M62 P" + std::to_string(o.digital_out) + " (measurement on with the next move)\n";
      first = false;
    }
    emit_runs(out, o, t, o.periodic_runs, o.dwell_s);
  }
  out += "M62 P" + std::to_string(o.digital_out + 1) + " (measurement end with the next move)\n";
  out += pos(o.axis, o.x_min) + "\nM2\n";
  return out;
}

}  // namespace cnc::comp
