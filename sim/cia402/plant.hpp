// The mechanics behind a simulated servo drive, integrated at a fine time
// step: motor and screw inertia, table mass, viscous and Coulomb friction
// with stiction on both, a lead screw with a pitch-error profile, backlash
// between nut and table (two bodies that separate and collide), the motor's
// current loop as a first-order lag behind a current limit, an incremental
// encoder with a zero pulse once per motor revolution, and limit switches,
// a home switch and a probe input at physical table positions. The true
// table position (what a laser interferometer reads) is kept apart from the
// encoder. SI units inside. No allocation after construction.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace cnc::cia402::sim {

struct PlantConfig {
  double encoder_counts = 131072;   // increments per motor revolution
  double gear = 1.0;                // motor revolutions per screw revolution
  double lead_m = 0.005;            // table travel per screw revolution (m); rotary load: 2 pi
  double motor_inertia = 1.5e-4;    // kg m^2: rotor, coupling and screw
  double load_mass = 200;           // kg: table and work (rotary: kg m^2 of the load)
  double motor_viscous = 2e-4;      // N m s/rad
  double motor_coulomb = 0.02;      // N m
  double load_viscous = 150;        // N s/m
  double load_coulomb = 40;         // N
  double backlash_m = 0;            // lost motion between nut and table
  // Pitch error: table position error (m) at nominal positions (m), linear
  // in between and constant outside.
  static constexpr std::size_t kMaxPitchPoints = 64;
  std::array<double, kMaxPitchPoints> pitch_at{}, pitch_error{};
  std::size_t pitch_points = 0;
  double torque_constant = 0.8;     // N m / A
  double max_current = 12;          // A: the current limit
  double rated_torque = 3.2;        // N m: 100 % of the drive's torque objects
  double current_tau = 2e-4;        // s: current loop as a first-order lag
  // Physical positions on the table (m); a switch is active at or beyond its
  // position (limits) or inside [min, max] (home).
  double neg_limit = -std::numeric_limits<double>::infinity();
  double pos_limit = std::numeric_limits<double>::infinity();
  double home_min = std::numeric_limits<double>::infinity();
  double home_max = std::numeric_limits<double>::infinity();
  double index_offset = 0;          // nut travel (m) from the start to a zero pulse
  double start_position = 0;        // table position at power-on (m)
  double probe_position = std::numeric_limits<double>::quiet_NaN();  // probe input active beyond (in probe_direction)
  int probe_direction = -1;         // -1: active at or below probe_position, +1: at or above
};

// What one step saw happen inside it.
struct StepEvents {
  bool index = false;            // a zero pulse passed
  double index_counts = 0;       // encoder count at the zero pulse (exact)
  bool probe_rise = false, probe_fall = false;
  double probe_counts = 0;       // encoder count where the probe input changed (interpolated)
};

class Plant {
 public:
  explicit Plant(const PlantConfig& c = {});
  void reset(const PlantConfig& c);
  const PlantConfig& config() const noexcept { return c_; }

  // Advances `dt` with the torque the drive commands (before the current
  // limit and lag); `power` false: the power stage is off (no torque).
  StepEvents step(double dt, double torque_cmd, bool power) noexcept;

  // Motor side.
  double motor_angle() const noexcept { return theta_; }          // rad since power-on
  double motor_velocity() const noexcept { return omega_; }       // rad/s
  double torque() const noexcept { return torque_; }              // N m produced
  bool current_limited() const noexcept { return limited_; }
  // Encoder: whole increments since power-on (what the drive reads), and
  // the exact (unquantised) value.
  int64_t encoder() const noexcept { return static_cast<int64_t>(std::floor(counts_exact())); }
  double counts_exact() const noexcept { return theta_ * counts_per_rad_; }
  double counts_per_rad() const noexcept { return counts_per_rad_; }
  // Motor radians per metre of nut travel (for scaling set-points).
  double rad_per_m() const noexcept { return 1.0 / r_; }
  double reflected_inertia() const noexcept { return c_.motor_inertia + c_.load_mass * r_ * r_; }

  // Load side.
  double table_position() const noexcept { return x_t_; }   // true position (m): the interferometer
  double table_velocity() const noexcept { return v_t_; }
  double nut_position() const noexcept { return nut(theta_); }
  double pitch_error_at(double nominal) const noexcept;

  // Inputs at the table's true position.
  bool neg_limit() const noexcept { return x_t_ <= c_.neg_limit; }
  bool pos_limit() const noexcept { return x_t_ >= c_.pos_limit; }
  bool home_switch() const noexcept { return x_t_ >= c_.home_min && x_t_ <= c_.home_max; }
  bool probe_input() const noexcept { return probe_override_ || probe_at(x_t_); }
  // The positional probe input alone (PROBE_POSITION, e.g. a tool setter),
  // without the external signal.
  bool probe_position_input() const noexcept { return probe_at(x_t_); }
  // A mechanical jam: extra Coulomb friction on the table (N), e.g. a
  // crash or a seized way (fault injection).
  void set_extra_friction(double newton) noexcept { extra_friction_ = newton < 0 ? 0 : newton; }
  // An external probe signal (HAL pin, test) ORed with the positional one.
  void set_probe_override(bool on) noexcept { probe_override_ = on; }

 private:
  double nominal(double theta) const noexcept { return c_.start_position + theta * r_; }
  double nut(double theta) const noexcept { return nominal(theta) + pitch_error_at(nominal(theta)); }
  bool probe_at(double x) const noexcept {
    if (!(c_.probe_position == c_.probe_position)) return false;
    return c_.probe_direction < 0 ? x <= c_.probe_position : x >= c_.probe_position;
  }

  PlantConfig c_;
  double r_ = 0;                 // m of nut travel per motor radian
  double counts_per_rad_ = 0;
  double theta_ = 0, omega_ = 0; // motor
  double x_t_ = 0, v_t_ = 0;     // table
  double torque_ = 0;
  bool limited_ = false;
  int contact_ = 0;              // +1 nut pushes the table towards +, -1 towards -, 0 apart
  bool probe_override_ = false;
  bool probe_last_ = false;
  double extra_friction_ = 0;
};

}  // namespace cnc::cia402::sim
