#include "sim/cia402/plant.hpp"

#include <algorithm>

namespace cnc::cia402::sim {
namespace {

constexpr double kTwoPi = 6.283185307179586;

// One step of m dv/dt = f - b v - c sgn(v): viscous part implicit (stable
// for any step), Coulomb part with stiction (a body at rest stays at rest
// while the force does not exceed c; a body whose velocity would cross
// zero under a force that friction can hold stops there).
double friction_step(double v, double f, double m, double b, double c, double dt) {
  const double damp = 1.0 + b * dt / m;
  if (v == 0.0) {
    if (std::fabs(f) <= c) return 0.0;
    return (f - std::copysign(c, f)) * dt / m / damp;
  }
  const double next = (v + (f - std::copysign(c, v)) * dt / m) / damp;
  if ((next > 0) != (v > 0) && std::fabs(f) <= c) return 0.0;
  return next;
}

int sign(double v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

}  // namespace

Plant::Plant(const PlantConfig& c) { reset(c); }

void Plant::reset(const PlantConfig& c) {
  c_ = c;
  r_ = c_.lead_m / (kTwoPi * c_.gear);
  counts_per_rad_ = c_.encoder_counts / kTwoPi;
  theta_ = omega_ = v_t_ = torque_ = 0;
  x_t_ = nut(0);
  contact_ = c_.backlash_m > 0 ? 1 : 0;
  if (c_.backlash_m > 0) x_t_ -= c_.backlash_m / 2;  // power-on: the nut rests against the table's + side
  limited_ = false;
  probe_last_ = probe_input();
}

double Plant::pitch_error_at(double x) const noexcept {
  const std::size_t n = c_.pitch_points;
  if (n == 0) return 0;
  if (x <= c_.pitch_at[0]) return c_.pitch_error[0];
  if (x >= c_.pitch_at[n - 1]) return c_.pitch_error[n - 1];
  std::size_t i = 1;
  while (i < n - 1 && c_.pitch_at[i] < x) ++i;
  const double x0 = c_.pitch_at[i - 1], x1 = c_.pitch_at[i];
  const double f = x1 > x0 ? (x - x0) / (x1 - x0) : 0.0;
  return c_.pitch_error[i - 1] + f * (c_.pitch_error[i] - c_.pitch_error[i - 1]);
}

StepEvents Plant::step(double dt, double torque_cmd, bool power) noexcept {
  StepEvents ev;
  const double limit = c_.torque_constant * c_.max_current;
  const double wanted = power ? std::clamp(torque_cmd, -limit, limit) : 0.0;
  limited_ = power && std::fabs(torque_cmd) > limit;
  torque_ = power ? torque_ + (wanted - torque_) * (1.0 - std::exp(-dt / c_.current_tau)) : 0.0;

  const double theta0 = theta_, x0 = x_t_;
  const bool probe0 = probe_last_;
  const double half_gap = c_.backlash_m / 2;
  const double j_coupled = reflected_inertia();
  const double b_coupled = c_.motor_viscous + c_.load_viscous * r_ * r_;
  const double load_coulomb = c_.load_coulomb + extra_friction_;
  const double c_coupled = c_.motor_coulomb + load_coulomb * r_;

  bool coupled = c_.backlash_m <= 0;
  double omega_c = 0;
  if (!coupled && contact_ != 0) {
    omega_c = friction_step(omega_, torque_, j_coupled, b_coupled, c_coupled, dt);
    if (omega_c == 0.0 && omega_ == 0.0) {
      // At rest: the motor pulls away from the table only if it can move alone.
      coupled = !(contact_ * torque_ < 0 && std::fabs(torque_) > c_.motor_coulomb);
    } else {
      const double v_next = r_ * omega_c;
      const double a_t = (v_next - v_t_) / dt;
      const double v_ref = v_next != 0.0 ? v_next : v_t_;
      const double push = c_.load_mass * a_t + c_.load_viscous * v_ref + load_coulomb * sign(v_ref);
      coupled = contact_ * push >= 0;
    }
    if (!coupled) contact_ = 0;
  }
  if (coupled) {
    omega_ = c_.backlash_m <= 0 ? friction_step(omega_, torque_, j_coupled, b_coupled, c_coupled, dt) : omega_c;
    theta_ += omega_ * dt;
    v_t_ = r_ * omega_;
    x_t_ = nut(theta_) - contact_ * half_gap;
  } else {
    omega_ = friction_step(omega_, torque_, c_.motor_inertia, c_.motor_viscous, c_.motor_coulomb, dt);
    theta_ += omega_ * dt;
    v_t_ = friction_step(v_t_, 0.0, c_.load_mass, c_.load_viscous, load_coulomb, dt);
    x_t_ += v_t_ * dt;
    const double gap = nut(theta_) - x_t_;
    const double closing = r_ * omega_ - v_t_;
    const int side = gap >= half_gap && closing >= 0 ? 1 : (gap <= -half_gap && closing <= 0 ? -1 : 0);
    if (side != 0) {
      // Inelastic collision: one common velocity, momentum kept.
      const double m_motor = c_.motor_inertia / (r_ * r_);
      const double v = (m_motor * r_ * omega_ + c_.load_mass * v_t_) / (m_motor + c_.load_mass);
      omega_ = v / r_;
      v_t_ = v;
      contact_ = side;
      x_t_ = nut(theta_) - side * half_gap;
    }
  }

  // Zero pulses at index_offset + k revolutions of nut travel.
  const double theta_index = c_.index_offset / r_;
  const double k0 = std::floor((theta0 - theta_index) / kTwoPi);
  const double k1 = std::floor((theta_ - theta_index) / kTwoPi);
  if (k0 != k1) {
    const double k = theta_ > theta0 ? k1 : k0;
    ev.index = true;
    ev.index_counts = (theta_index + kTwoPi * k) * counts_per_rad_;
  }
  const bool probe1 = probe_input();
  probe_last_ = probe1;
  if (probe1 != probe0) {
    double f = 1.0;
    if (!probe_override_ && x_t_ != x0) f = std::clamp((c_.probe_position - x0) / (x_t_ - x0), 0.0, 1.0);
    ev.probe_rise = probe1;
    ev.probe_fall = !probe1;
    ev.probe_counts = theta0 * counts_per_rad_ + f * (theta_ - theta0) * counts_per_rad_;
  }
  return ev;
}

}  // namespace cnc::cia402::sim
