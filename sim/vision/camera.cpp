#include "sim/vision/camera.hpp"

#include <cmath>

namespace cnc::vision::sim {

Frame SimulatedScaleCamera::grab() {
  Frame f;
  if (disconnect_after_ >= 0 && frames_ >= disconnect_after_) {
    f.error = name() + ": no frame (the camera stopped delivering images: disconnected?)";
    return f;
  }
  ScaleScene s = scene_;
  try {
    s.centre_mm = zero_ + sign_ * position_();
  } catch (const std::exception& e) {
    f.error = name() + ": no position of the table (" + e.what() + ")";
    return f;
  }
  ++frames_;
  s.imaging.seed = scene_.imaging.seed + static_cast<uint64_t>(frames_);
  f.image = render_scale(s);
  return f;
}

PlantAxis::PlantAxis(const cnc::cia402::sim::PlantConfig& plant, Options o) : plant_(plant), o_(o) {
  cmd_mm_ = plant.start_position * 1000;
}

void PlantAxis::step(double cmd_mm, double vel_mm_s) {
  // Cascaded loop on the motor side (what the drive sees): position P with
  // velocity feed-forward, velocity PI; the plant's table follows through
  // the screw's pitch error and the backlash.
  const double rad_per_mm = plant_.rad_per_m() / 1000;
  const double start_rad = plant_.config().start_position * plant_.rad_per_m();
  const double theta_cmd = cmd_mm * rad_per_mm - start_rad;
  const double omega_cmd = vel_mm_s * rad_per_mm + o_.position_gain * (theta_cmd - plant_.motor_angle());
  const double kv = plant_.reflected_inertia() * 2 * M_PI * o_.velocity_bandwidth_hz;
  const double e = omega_cmd - plant_.motor_velocity();
  integral_ += e * o_.step_s / o_.velocity_integral_time;
  plant_.step(o_.step_s, kv * (e + integral_), true);
  t_ += o_.step_s;
}

std::string PlantAxis::move_to(double target_mm) {
  const int dir = target_mm > cmd_mm_ ? 1 : target_mm < cmd_mm_ ? -1 : direction_;
  direction_ = dir;
  const double goal = target_mm + (compensation ? compensation(target_mm, dir) : 0);
  const double from = cmd_mm_, dist = std::abs(goal - from), sgn = goal >= from ? 1 : -1;
  // Trapezoidal (or triangular) profile.
  const double v = std::min(o_.feed_mm_s, std::sqrt(dist * o_.accel_mm_s2));
  const double ta = v / o_.accel_mm_s2, da = 0.5 * o_.accel_mm_s2 * ta * ta;
  const double tc = v > 0 ? (dist - 2 * da) / v : 0;
  const double total = 2 * ta + tc;
  for (double t = 0; t < total; t += o_.step_s) {
    double s, vel;
    if (t < ta) {
      s = 0.5 * o_.accel_mm_s2 * t * t;
      vel = o_.accel_mm_s2 * t;
    } else if (t < ta + tc) {
      s = da + v * (t - ta);
      vel = v;
    } else {
      const double td = total - t;
      s = dist - 0.5 * o_.accel_mm_s2 * td * td;
      vel = o_.accel_mm_s2 * td;
    }
    step(from + sgn * s, sgn * vel);
  }
  cmd_mm_ = goal;
  step(cmd_mm_, 0);
  const double ferror_mm = std::abs(cmd_mm_ - (plant_.motor_angle() + plant_.config().start_position * plant_.rad_per_m()) /
                                                  (plant_.rad_per_m() / 1000));
  if (ferror_mm > 1.0) return "following error " + std::to_string(ferror_mm) + " mm after the move";
  return "";
}

void PlantAxis::settle(double seconds) {
  for (double t = 0; t < seconds; t += o_.step_s) step(cmd_mm_, 0);
}

}  // namespace cnc::vision::sim
