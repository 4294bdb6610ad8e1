// One joint's free-mode trajectory planner: a jerk-limited (S-curve) move
// to a target that may change at any time (jogs, homing, JOG_ABS retargets
// in flight). Each cycle it picks the jerk that heads for the target
// fastest while the machine can still stop at the target, so velocity,
// acceleration and jerk limits hold on every sample and the target is not
// overshot unless it is moved behind the joint. Realtime-safe.
#pragma once

namespace cnc::motion {

struct FreeLimits {
  double max_velocity = 0;
  double max_acceleration = 0;
  double max_jerk = 0;
};

// Distance travelled while stopping from (v, a) as fast as the limits allow
// (signed, in the direction of v). Public for tests and for other planners.
double stopping_distance(double v, double a, double max_acc, double max_jerk) noexcept;

class FreePlanner {
 public:
  void reset(double position) noexcept;
  // At rest at `position`, keeping a target already set (a jog asked for
  // before the first cycle after enabling).
  void resync(double position) noexcept {
    p_ = position;
    v_ = a_ = 0;
  }

  // Sets where to go and how fast; takes effect on the next update().
  void set_target(double target, const FreeLimits& limits) noexcept;
  // Stop as fast as the limits allow, then hold (ABORT, limit, jog release).
  void stop() noexcept;
  bool enabled() const noexcept { return enabled_; }
  void disable() noexcept { enabled_ = false; }

  // Advances one period; returns the new position.
  double update(double dt) noexcept;

  // Relabels the coordinate (homing moves the joint's origin): position and
  // target move by `delta`, velocity and acceleration stay.
  void shift(double delta) noexcept {
    p_ += delta;
    target_ += delta;
  }

  double position() const noexcept { return p_; }
  double velocity() const noexcept { return v_; }
  double acceleration() const noexcept { return a_; }
  double target() const noexcept { return target_; }
  // At the target and at rest.
  bool done() const noexcept { return !enabled_ || (p_ == target_ && v_ == 0 && a_ == 0); }
  const FreeLimits& limits() const noexcept { return limits_; }

 private:
  double p_ = 0, v_ = 0, a_ = 0;
  double target_ = 0;
  FreeLimits limits_{};
  bool enabled_ = false;
};

}  // namespace cnc::motion
