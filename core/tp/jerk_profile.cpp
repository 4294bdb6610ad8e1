#include "core/tp/jerk_profile.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cnc::tp {

PathState JerkProfile::at(double t) const noexcept {
  PathState m = start;
  for (int i = 0; i < 3; ++i) {
    const double d = duration[static_cast<std::size_t>(i)];
    if (t <= d) return integrate(m, jerk[static_cast<std::size_t>(i)], std::max(t, 0.0));
    m = integrate(m, jerk[static_cast<std::size_t>(i)], d);
    t -= d;
  }
  // Cruise: the profile ends with zero acceleration.
  m.s += m.v * t;
  m.a = 0;
  return m;
}

double JerkProfile::jerk_at(double t) const noexcept {
  for (int i = 0; i < 3; ++i) {
    const double d = duration[static_cast<std::size_t>(i)];
    if (t < d) return jerk[static_cast<std::size_t>(i)];
    t -= d;
  }
  return 0;
}

JerkProfile velocity_profile(const PathState& m, double target, double accel, double jerk) noexcept {
  JerkProfile p;
  p.start = m;
  const double a0 = m.a;
  // Velocity reached by ramping the acceleration to zero right now.
  const double v_ramp = m.v + a0 * std::fabs(a0) / (2 * jerk);
  if (std::fabs(v_ramp - target) <= 1e-12 * (1 + std::fabs(target))) {
    p.duration[0] = std::fabs(a0) / jerk;
    p.jerk[0] = a0 > 0 ? -jerk : jerk;
    return p;
  }
  // Work in the direction of the change: a = acceleration along it, dv = the
  // velocity change still needed (dv > a|a|/2j by the choice of direction).
  const double sg = target > v_ramp ? 1.0 : -1.0;
  const double a = sg * a0;
  const double dv = sg * (target - m.v);
  double peak = 0;
  double t1 = 0;
  double j1 = 0;
  if (a > accel) {
    peak = accel;
    t1 = (a - accel) / jerk;
    j1 = -jerk;
  } else {
    peak = std::min(accel, std::sqrt(std::max(0.0, jerk * dv + 0.5 * a * a)));
    t1 = std::max(0.0, (peak - a) / jerk);
    j1 = jerk;
  }
  const double t3 = peak / jerk;
  const double gain13 = 0.5 * (a + peak) * t1 + 0.5 * peak * t3;
  const double t2 = peak > 1e-300 ? std::max(0.0, (dv - gain13) / peak) : 0.0;
  p.duration = {t1, t2, t3};
  p.jerk = {sg * j1, 0.0, -sg * jerk};
  return p;
}

double brake_distance(double v, double a, double ceiling, double accel, double jerk) noexcept {
  const double peak = a > 0 ? v + a * a / (2 * jerk) : v;
  if (peak <= ceiling) return 0;
  const double v_ramp = v + a * std::fabs(a) / (2 * jerk);
  if (v_ramp <= ceiling) {
    // Already braking harder than needed (a < 0 here): ramp the acceleration
    // out. If even that stops below zero the motion would have to reverse:
    // no distance is enough.
    if (v_ramp < -1e-9 * (1 + v)) return std::numeric_limits<double>::infinity();
    // Distance until the velocity v + a t + j t^2 / 2 first reaches the
    // ceiling (it keeps falling after that).
    const double disc = std::max(0.0, a * a - 2 * jerk * (v - ceiling));
    const double t = std::clamp((-a - std::sqrt(disc)) / jerk, 0.0, -a / jerk);
    return integrate({0, v, a}, jerk, t).s;
  }
  return velocity_profile({0, v, a}, ceiling, accel, jerk).distance();
}

double max_entry_velocity(double distance, double ceiling, double accel, double jerk) noexcept {
  if (distance <= 0) return ceiling;
  const double w = ceiling;
  // Without a constant-deceleration phase the velocity drop dv = x^2 obeys
  // x^3 + 2 w x = d sqrt(j) (the profile is symmetric: mean velocity (v+w)/2).
  // Newton from an upper bound converges monotonically (convex, rising).
  const double p = 2 * w;
  const double q = distance * std::sqrt(jerk);
  double x = std::cbrt(q);
  if (p > 0) x = std::min(x, q / p);
  for (int i = 0; i < 40; ++i) {
    const double f = x * x * x + p * x - q;
    const double step = f / (3 * x * x + p);
    if (!(step > 0)) break;
    x -= step;
    if (step <= 1e-17 * x) break;
  }
  double dv = std::max(0.0, x * x);
  if (dv > accel * accel / jerk) {
    // With a phase at full deceleration: (2w + dv)(A/j + dv/A) = 2d, i.e.
    // dv^2 + b dv + c = 0 (stable root).
    const double b = accel * accel / jerk + 2 * w;
    const double c = 2 * w * accel * accel / jerk - 2 * distance * accel;
    dv = c < 0 ? -2 * c / (b + std::sqrt(b * b - 4 * c)) : 0.0;
  }
  // Stay on the safe side of rounding.
  for (int i = 0; i < 8 && dv > 0 && brake_distance(w + dv, 0, w, accel, jerk) > distance; ++i) dv *= 1 - 1e-12 * (1 << i);
  return w + dv;
}

}  // namespace cnc::tp
