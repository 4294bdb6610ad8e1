// One-dimensional jerk-limited motion along the path parameter: the
// piecewise-constant-jerk profiles the servo side follows, the distance a
// brake needs and its inverse. Pure functions on plain numbers: realtime-safe
// (no allocation, no exception), used by both planner threads.
#pragma once

#include <array>

namespace cnc::tp {

// Position, velocity and acceleration along the path.
struct PathState {
  double s = 0;
  double v = 0;
  double a = 0;
};

// Exact integration of a constant jerk `j` over `t` seconds.
inline PathState integrate(const PathState& m, double j, double t) noexcept {
  return {m.s + t * (m.v + t * (m.a * 0.5 + t * j * (1.0 / 6.0))), m.v + t * (m.a + t * j * 0.5), m.a + j * t};
}

// Up to three constant-jerk phases from `start`, then constant velocity
// (the acceleration is zero at the end of the last phase).
struct JerkProfile {
  PathState start;
  std::array<double, 3> duration{};
  std::array<double, 3> jerk{};

  double total_time() const noexcept { return duration[0] + duration[1] + duration[2]; }
  // State `t` seconds after the start; past the end the motion cruises.
  PathState at(double t) const noexcept;
  PathState end() const noexcept { return at(total_time()); }
  double distance() const noexcept { return end().s - start.s; }
  // Jerk in force `t` seconds after the start (0 after the end).
  double jerk_at(double t) const noexcept;
};

// The time-optimal profile that changes the velocity from (m.v, m.a) to
// `target` and ends with zero acceleration, with |a| <= accel and
// |j| <= jerk. An initial |m.a| above `accel` is first ramped back.
JerkProfile velocity_profile(const PathState& m, double target, double accel, double jerk) noexcept;

// Shortest distance after which the velocity stays at or below `ceiling`,
// starting from (v, a): 0 when it never exceeds the ceiling; infinite when
// the deceleration is already too strong to end at a velocity >= 0.
double brake_distance(double v, double a, double ceiling, double accel, double jerk) noexcept;

// Largest velocity v >= ceiling such that, starting at rest acceleration,
// brake_distance(v, 0, ceiling, ...) <= distance.
double max_entry_velocity(double distance, double ceiling, double accel, double jerk) noexcept;

}  // namespace cnc::tp
