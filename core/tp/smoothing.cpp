#include "core/tp/smoothing.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::tp {
namespace {

// Change of the unit direction at b on the polyline a-b-c (zero if a leg
// has no length).
void turn(const Pose& a, const Pose& b, const Pose& c, double* out) {
  double l0 = 0, l1 = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    l0 += (b[i] - a[i]) * (b[i] - a[i]);
    l1 += (c[i] - b[i]) * (c[i] - b[i]);
  }
  l0 = std::sqrt(l0);
  l1 = std::sqrt(l1);
  for (int i = 0; i < kNumAxes; ++i) {
    out[i] = (l0 > 0 && l1 > 0) ? (c[i] - b[i]) / l1 - (b[i] - a[i]) / l0 : 0.0;
  }
}

double dot(const double* a, const double* b) {
  double s = 0;
  for (int i = 0; i < kNumAxes; ++i) s += a[i] * b[i];
  return s;
}

}  // namespace

double distance_to_segment(const Pose& p, const Pose& a, const Pose& b) noexcept {
  double ab2 = 0, t = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    const double d = b[i] - a[i];
    ab2 += d * d;
    t += (p[i] - a[i]) * d;
  }
  t = ab2 > 0 ? std::clamp(t / ab2, 0.0, 1.0) : 0.0;
  double r = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    const double d = p[i] - (a[i] + t * (b[i] - a[i]));
    r += d * d;
  }
  return std::sqrt(r);
}

Pose smooth_vertex(const Pose* before, const Pose& prev, const Pose& p, const Pose& next, const Pose* after,
                   double budget, double tol) noexcept {
  if (!(budget > 0) || !(tol > 0)) return p;
  double step[kNumAxes];
  double len = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    step[i] = 0.25 * (prev[i] + next[i] - 2 * p[i]);
    len += step[i] * step[i];
  }
  len = std::sqrt(len);
  if (!(len > 0) || !std::isfinite(len)) return p;
  const double lambda = std::min(1.0, budget / len);
  bool smooth = len <= kFitAlwaysShare * tol && lambda >= 1.0;
  if (!smooth && lambda >= 0.5) {
    // Alternating: the turn at p points against the turn at a neighbour
    // (a zig-zag, rounding noise), not the same way (a curve).
    double t[kNumAxes];
    double o[kNumAxes];
    turn(prev, p, next, t);
    if (before) {
      turn(*before, prev, p, o);
      smooth = smooth || dot(t, o) < 0;
    }
    if (after) {
      turn(p, next, *after, o);
      smooth = smooth || dot(t, o) < 0;
    }
  }
  if (!smooth) return p;
  Pose q = p;
  for (int i = 0; i < kNumAxes; ++i) q[i] = p[i] + lambda * step[i];
  return q;
}

}  // namespace cnc::tp
