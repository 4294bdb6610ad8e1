// A simulated VFD and its motor for the Modbus simulator: a speed that
// follows the frequency reference along acceleration ramps limited by the
// motor's inertia, a current made of magnetising, load and acceleration
// parts, and an over-current trip. Not product code (sim/ only).
#pragma once

#include <cstdint>

namespace cnc::modbus_sim {

struct MotorParams {
  double max_hz = 400;          // the drive's maximum output frequency
  double ramp_hz_s = 200;       // acceleration and deceleration ramp
  double inertia = 1.0;         // scales the current needed to accelerate
  double load_a = 1.0;          // current at speed from the load
  double idle_a = 0.5;          // magnetising current while running
  double accel_a_per_hz_s = 0.01;  // extra current per Hz/s of acceleration (x inertia)
  double trip_a = 20;           // over-current trip level
  uint16_t overcurrent_code = 1;  // the fault code the family reports for it
};

class VfdModel {
 public:
  explicit VfdModel(MotorParams p = {}) : p_(p) {}

  // Advances the motor to monotonic time `now_ns`.
  void advance(int64_t now_ns) noexcept;

  void command(bool run, bool reverse) noexcept { run_ = run, reverse_ = reverse; }
  void set_reference_hz(double hz) noexcept;
  void reset_fault() noexcept;
  // Trips with `code` (the family's over-current code): output off, the
  // motor coasts.
  void trip(uint16_t code) noexcept;
  void trip_overcurrent() noexcept { trip(p_.overcurrent_code); }
  void set_load_a(double a) noexcept { p_.load_a = a; }

  bool run() const noexcept { return run_; }
  bool reverse() const noexcept { return reverse_; }
  double reference_hz() const noexcept { return ref_hz_; }
  double output_hz() const noexcept { return hz_; }  // signed: negative in reverse
  double current_a() const noexcept { return current_; }
  uint16_t fault_code() const noexcept { return fault_; }
  const MotorParams& params() const noexcept { return p_; }

 private:
  MotorParams p_;
  bool run_ = false;
  bool reverse_ = false;
  double ref_hz_ = 0;
  double hz_ = 0;
  double current_ = 0;
  uint16_t fault_ = 0;
  int64_t last_ns_ = 0;
};

}  // namespace cnc::modbus_sim
