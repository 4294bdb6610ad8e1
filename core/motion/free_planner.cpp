#include "core/motion/free_planner.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::motion {
namespace {

// Distance covered from (v >= 0, a) to rest with |a| <= A and |j| <= J:
// ramp a down to -ap, hold, ramp back to 0 (ap chosen so that v reaches 0).
double stop_distance_positive(double v, double a, double A, double J) noexcept {
  // If even ramping a straight back to zero ends with v <= 0, the joint is
  // already braking hard enough: the distance is that of the ramp.
  if (a < 0 && v <= a * a / (2 * J)) {
    const double t = -a / J;
    return v * t + a * t * t / 2 + J * t * t * t / 6;
  }
  double ap = std::sqrt(J * v + a * a / 2);
  double t2 = 0;
  if (ap > A) {
    ap = A;
    t2 = (v + a * a / (2 * J) - A * A / J) / A;
    if (t2 < 0) t2 = 0;
  }
  const double t1 = (a + ap) / J;
  const double d1 = v * t1 + a * t1 * t1 / 2 - J * t1 * t1 * t1 / 6;
  const double v1 = v + a * t1 - J * t1 * t1 / 2;
  const double d2 = v1 * t2 - ap * t2 * t2 / 2;
  const double v2 = v1 - ap * t2;
  const double t3 = ap / J;
  const double d3 = v2 * t3 - ap * t3 * t3 / 2 + J * t3 * t3 * t3 / 6;
  return d1 + d2 + d3;
}

struct Profile {
  double t1, t2, t3, ap, j1;
};

// Braking from (v >= 0, a) with peak deceleration ap: the acceleration
// ramps at +-J to -ap, holds, and ramps at +J back to 0 exactly as the
// velocity reaches 0. False when no such profile exists (t2 < 0).
bool braking_profile(double v, double a, double ap, double J, Profile& p) noexcept {
  if (ap <= 0) return false;
  p.ap = ap;
  p.j1 = -ap - a >= 0 ? J : -J;
  p.t1 = std::fabs(-ap - a) / J;
  const double v1 = v + a * p.t1 + p.j1 * p.t1 * p.t1 / 2;
  p.t3 = ap / J;
  p.t2 = (v1 - ap * ap / (2 * J)) / ap;
  return p.t2 >= -1e-15;
}

// State after time t along a braking profile (t clamped to its end).
void sample(double v, double a, double J, const Profile& p, double t, double& dp, double& nv, double& na) noexcept {
  double pos = 0;
  const auto run = [&](double dur, double jerk) {
    const double d = std::min(dur, t);
    if (d <= 0) return;
    pos += v * d + a * d * d / 2 + jerk * d * d * d / 6;
    v += a * d + jerk * d * d / 2;
    a += jerk * d;
    t -= d;
  };
  run(p.t1, p.j1);
  run(std::max(p.t2, 0.0), 0);
  run(p.t3, J);
  dp = pos;
  nv = v;
  na = a;
}

double profile_distance(double v, double a, double J, const Profile& p) noexcept {
  double dp, nv, na;
  sample(v, a, J, p, 1e300, dp, nv, na);
  return dp;
}

}  // namespace

double stopping_distance(double v, double a, double max_acc, double max_jerk) noexcept {
  if (max_acc <= 0 || max_jerk <= 0) return 0;
  if (v < 0 || (v == 0 && a < 0)) return -stop_distance_positive(-v, -a, max_acc, max_jerk);
  return stop_distance_positive(v, a, max_acc, max_jerk);
}

void FreePlanner::reset(double position) noexcept {
  p_ = target_ = position;
  v_ = a_ = 0;
  enabled_ = false;
}

void FreePlanner::set_target(double target, const FreeLimits& limits) noexcept {
  target_ = target;
  limits_ = limits;
  enabled_ = true;
}

void FreePlanner::stop() noexcept {
  if (!enabled_) return;
  target_ = p_ + stopping_distance(v_, a_, limits_.max_acceleration, limits_.max_jerk);
}

double FreePlanner::update(double dt) noexcept {
  if (!enabled_ || dt <= 0) return p_;
  const double V = limits_.max_velocity, A = limits_.max_acceleration;
  if (V <= 0 || A <= 0 || limits_.max_jerk <= 0) return p_;
  // A jerk so high that acceleration could swing across its whole range in
  // under a few periods cannot be followed by a sampled controller (the
  // model would promise stops the samples cannot make): plan with a jerk
  // that spreads each acceleration ramp over at least 4 periods.
  const double J = std::min(limits_.max_jerk, A / (4 * dt));
  // Work in the frame where the target lies ahead (positive direction).
  const double s = target_ >= p_ ? 1.0 : -1.0;
  const double dist = (target_ - p_) * s;
  const double v = v_ * s, a = a_ * s;

  // Close enough and slow enough: land exactly. A jerk-limited stop ends
  // between two samples in general; when what is left is no more than one
  // step of the jerk limit could cover from rest, the last sample goes to
  // the target (the step stays within the jerk limit).
  const double jdt = J * dt;
  if (dist <= jdt * dt * dt / 6 && std::fabs(v) <= jdt * dt / 2 && std::fabs(a) <= jdt) {
    p_ = target_;
    v_ = a_ = 0;
    return p_;
  }

  // Braking towards the target: follow the jerk-limited braking profile
  // that ends exactly at the target (peak deceleration chosen to fit the
  // remaining distance), sampled at the period. Sampling an exact profile
  // keeps the approach monotone and lands on the target.
  const auto dist_ok = [&](double j) {
    const double na = std::clamp(a + j * dt, -A, A);
    const double nv = v + (a + na) / 2 * dt;
    const double step = v * dt + (2 * a + na) / 6 * dt * dt;
    return stopping_distance(nv, na, A, J) <= dist - step;
  };
  if (v >= 0 && !dist_ok(J)) {
    // The largest peak deceleration with a valid profile (validity holds
    // for small peaks and fails above some value).
    Profile p;
    double ap_hi = A;
    if (!braking_profile(v, a, ap_hi, J, p)) {
      double lo = 0, hi = A;
      for (int i = 0; i < 40; ++i) {
        const double mid = (lo + hi) / 2;
        if (braking_profile(v, a, mid, J, p)) lo = mid;
        else hi = mid;
      }
      ap_hi = lo;
    }
    Profile hi_p;
    if (ap_hi > 0 && braking_profile(v, a, ap_hi, J, hi_p) && profile_distance(v, a, J, hi_p) <= dist) {
      // Distance falls as the peak grows: find the peak that fits exactly.
      double lo = 0, hi = ap_hi;
      p = hi_p;
      for (int i = 0; i < 40; ++i) {
        const double mid = (lo + hi) / 2;
        Profile m;
        if (!braking_profile(v, a, mid, J, m) || profile_distance(v, a, J, m) > dist) {
          lo = mid;
        } else {
          hi = mid;
          p = m;
        }
      }
      if (p.t1 + p.t2 + p.t3 <= dt) {
        p_ = target_;
        v_ = a_ = 0;
        return p_;
      }
      double dp, nv, na;
      sample(v, a, J, p, dt, dp, nv, na);
      p_ += dp * s;
      v_ = nv * s;
      a_ = na * s;
      return p_;
    }
  }

  // Otherwise the jerk for this step is the largest in [-J, J] after which
  // the joint can still stop before the target without exceeding the
  // velocity limit (counting the velocity gained while a returns to 0).
  // Both conditions grow with the jerk, so the feasible set is an interval
  // found by bisection.
  const auto feasible = [&](double j) {
    const double na = std::clamp(a + j * dt, -A, A);
    const double nv = v + (a + na) / 2 * dt;
    if (nv + (na > 0 ? na * na / (2 * J) : 0) > V * (1 + 1e-12)) return false;
    return dist_ok(j);
  };
  double jerk = -J;
  if (feasible(J)) {
    jerk = J;
  } else if (feasible(-J)) {
    double lo = -J, hi = J;
    for (int i = 0; i < 30; ++i) {
      const double mid = (lo + hi) / 2;
      if (feasible(mid)) lo = mid;
      else hi = mid;
    }
    jerk = lo;
  }
  const double chosen_a = std::clamp(a + jerk * dt, -A, A);
  const double na = chosen_a;
  const double nv = v + (a + na) / 2 * dt;
  const double step = v * dt + (2 * a + na) / 6 * dt * dt;
  p_ += step * s;
  v_ = nv * s;
  a_ = na * s;
  return p_;
}

}  // namespace cnc::motion
