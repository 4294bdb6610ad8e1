// Per-joint compensation as the motion controller applies it (the manual's
// 3.6: motor = joint + backlash + screw correction + home offset): the
// interface a screw-error table (comp/) implements, and the ramp that moves
// the applied correction toward what the table or BACKLASH asks for without
// ever taking the joint past its velocity or acceleration limit.
// Realtime: both are called once per cycle per joint and never allocate,
// block or throw.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/motion/free_planner.hpp"

namespace cnc::motion {

class JointCompensation {
 public:
  virtual ~JointCompensation() = default;
  // The correction (motor units) a table asks for at commanded joint
  // position `pos_cmd` while moving with `vel_cmd` (> 0: forward trim,
  // < 0: reverse trim, 0: the direction of the last move). False when there
  // is no table: the controller then applies +-BACKLASH/2 itself. The
  // controller ramps toward the returned value (CompensationRamp); it calls
  // this every cycle, homed or not, and uses the value once the joint is
  // homed.
  virtual bool correction(double pos_cmd, double vel_cmd, double& value) noexcept = 0;
};

// Limits of a movement, in joint units per second (squared, cubed).
struct RampLimits {
  double max_velocity = 0;
  double max_acceleration = 0;
  double max_jerk = 0;
};

// What the joint's own command does this cycle, so that the ramp keeps the
// sum (the motor command) inside the joint's limits.
struct JointMotion {
  double vel_cmd = 0;        // (pos_cmd[k] - pos_cmd[k-1]) / dt
  double acc_cmd = 0;        // (vel_cmd[k] - vel_cmd[k-1]) / dt
  double max_velocity = 0;   // the joint's limits, whole
  double max_acceleration = 0;
};

// Moves the applied compensation toward a target that may step (a reversal
// with backlash or a bidirectional table) or slide (a table's slope while
// the joint moves). The ramp follows a sliding target without lag (the
// target's rate is fed forward) and reaches a stepped one as fast as its own
// limits (the reserved share, [EMCMOT]COMP_RESERVE) allow, jerk-limited.
// On top of that, every sample is clamped so that the motor command's
// velocity and acceleration (finite differences over the servo period,
// joint command plus compensation) stay within the joint's whole limits,
// whatever the planner does with its share.
class CompensationRamp {
 public:
  void reset(double value) noexcept {
    c_ = target_prev_ = value;
    u_ = a_ = w_prev_ = ff_ = 0;
  }

  // One servo period toward `target`; returns the applied value.
  double update(double target, double dt, const RampLimits& own, const JointMotion& joint) noexcept {
    if (!(dt > 0) || !(own.max_velocity > 0) || !(own.max_acceleration > 0) || !(own.max_jerk > 0)) {
      return hold();
    }
    const double V = own.max_velocity, A = own.max_acceleration;
    const double J = std::min(own.max_jerk, A / (4 * dt));
    // Feed forward the target's rate while it slides; a rate above half the
    // ramp's velocity is a step, not a slide: keep the last rate.
    const double rate = (target - target_prev_) / dt;
    target_prev_ = target;
    if (std::fabs(rate) <= V / 2) ff_ = rate;
    // Relative frame: the target's smooth path, one period back.
    const double p = c_ - (target - ff_ * dt);
    const double v = u_ - ff_;
    const double v_rel = std::max(V - std::fabs(ff_), 0.0);
    double step, nv, na;
    const bool lands = relative_step(p, v, a_, dt, v_rel, A, J, step, nv, na);
    // Finite-difference velocity of the applied value over this period.
    const double w = lands ? (target - c_) / dt : ff_ + step / dt;
    // The joint's headroom: motor velocity and acceleration (finite
    // differences) within the joint's limits.
    const double al = w_prev_ + (-joint.max_acceleration - joint.acc_cmd) * dt;
    const double ah = w_prev_ + (joint.max_acceleration - joint.acc_cmd) * dt;
    double lo = std::max(-joint.max_velocity - joint.vel_cmd, al);
    double hi = std::min(joint.max_velocity - joint.vel_cmd, ah);
    if (lo > hi) {
      // The joint's command alone leaves no room: keep within the
      // acceleration window, as close to the velocity window as it allows.
      lo = al;
      hi = ah;
    }
    const double wc = std::clamp(w, lo, hi);
    if (wc != w) {
      c_ += wc * dt;
      u_ = wc;
      a_ = std::clamp((wc - w_prev_) / dt, -A, A);
    } else if (lands) {
      c_ = target;
      u_ = ff_;
      a_ = 0;
    } else {
      c_ += w * dt;
      u_ = ff_ + nv;
      a_ = na;
    }
    w_prev_ = wc;
    return c_;
  }

  double value() const noexcept { return c_; }
  // Velocity of the applied value (finite difference of the last period).
  double velocity() const noexcept { return w_prev_; }
  bool at_target(double target) const noexcept { return c_ == target && w_prev_ == 0; }

 private:
  // No share reserved (COMP_RESERVE = 0): the applied value stays put.
  double hold() noexcept {
    u_ = a_ = w_prev_ = 0;
    return c_;
  }

  // One jerk-limited step toward 0 from (p, v, a): the largest jerk after
  // which the ramp can still stop at 0 within the limits (as the free
  // planner decides), landing exactly once close enough.
  // True when this step lands on the target.
  static bool relative_step(double p, double v, double a, double dt, double V, double A, double J, double& step,
                            double& nv, double& na) noexcept {
    const double s = p <= 0 ? 1.0 : -1.0;  // direction toward 0
    const double dist = std::fabs(p);
    const double vv = v * s, aa = a * s;
    const double jdt = J * dt;
    // Close and slow enough: land on the target this period.
    if (dist <= jdt * dt * dt && std::fabs(vv) <= jdt * dt && std::fabs(aa) <= 2 * jdt) {
      step = -p;
      nv = na = 0;
      return true;
    }
    const auto advance = [&](double j, double& x, double& nvel, double& nacc) {
      nacc = std::clamp(aa + j * dt, -A, A);
      nvel = vv + (aa + nacc) / 2 * dt;
      x = vv * dt + (2 * aa + nacc) / 6 * dt * dt;
    };
    const auto feasible = [&](double j) {
      double x, nvel, nacc;
      advance(j, x, nvel, nacc);
      if (nvel + (nacc > 0 ? nacc * nacc / (2 * J) : 0) > V * (1 + 1e-12)) return false;
      return stopping_distance(nvel, nacc, A, J) <= dist - x;
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
    double x, nvel, nacc;
    advance(jerk, x, nvel, nacc);
    // Never step past the target when the step itself would land: the last
    // sample of a stop goes to the target exactly.
    if (x > dist && std::fabs(nvel) <= jdt * dt * 4) {
      step = -p;
      nv = na = 0;
      return true;
    }
    step = x * s;
    nv = nvel * s;
    na = nacc * s;
    return false;
  }

  double c_ = 0, u_ = 0, a_ = 0;
  double w_prev_ = 0;
  double target_prev_ = 0, ff_ = 0;
};

}  // namespace cnc::motion
