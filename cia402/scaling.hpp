// Machine units <-> drive increments, configured in exactly one place (the
// controller, from INI): encoder increments per motor revolution, gear
// ratio, screw lead (machine units per load revolution) and direction. The
// drive's own factor group stays 1:1 (positions in encoder increments).
// Position counts are 32 bits on the wire and unwrapped to 64 bits here, so
// rotary axes may turn for ever. Realtime-safe.
#pragma once

#include <cmath>
#include <cstdint>

namespace cnc::cia402 {

struct Scaling {
  double counts_per_unit = 1.0;  // increments per machine unit (mm, inch or degree)
  int direction = 1;             // +1, or -1 when the drive counts the other way

  // increments per motor rev x motor revs per load rev / units per load rev
  static Scaling from_mechanics(double encoder_counts_per_rev, double gear_motor_revs, double gear_load_revs,
                                double units_per_load_rev, bool reverse) noexcept {
    Scaling s;
    s.counts_per_unit = encoder_counts_per_rev * (gear_motor_revs / gear_load_revs) / units_per_load_rev;
    s.direction = reverse ? -1 : 1;
    return s;
  }

  double to_units(int64_t counts) const noexcept {
    return static_cast<double>(counts) * direction / counts_per_unit;
  }
  double to_units(double counts) const noexcept { return counts * direction / counts_per_unit; }
  // Nearest increment; saturates far beyond any real travel.
  int64_t to_counts(double units) const noexcept {
    const double c = std::nearbyint(units * counts_per_unit * direction);
    if (!(c > -9.0e18)) return c != c ? 0 : INT64_MIN / 2;
    if (c > 9.0e18) return INT64_MAX / 2;
    return static_cast<int64_t>(c);
  }
  // Velocities and accelerations (increments/s, increments/s^2).
  double to_counts_rate(double units_per_s) const noexcept { return units_per_s * counts_per_unit * direction; }
  double to_units_rate(double counts_per_s) const noexcept { return counts_per_s * direction / counts_per_unit; }
  // Magnitudes (no direction): speeds, windows, decelerations.
  uint32_t to_counts_magnitude(double units) const noexcept {
    const double c = std::nearbyint(std::fabs(units) * counts_per_unit);
    return c >= 4294967295.0 ? 0xFFFFFFFFu : static_cast<uint32_t>(c);
  }
};

// Unwraps a 32-bit position that may overflow into a 64-bit count.
class PositionUnwrap {
 public:
  int64_t update(int32_t raw) noexcept {
    if (!valid_) {
      valid_ = true;
      value_ = raw;
    } else {
      value_ += static_cast<int32_t>(static_cast<uint32_t>(raw) - static_cast<uint32_t>(last_));
    }
    last_ = raw;
    return value_;
  }
  int64_t value() const noexcept { return value_; }
  bool valid() const noexcept { return valid_; }
  void reset() noexcept { valid_ = false; }

 private:
  bool valid_ = false;
  int32_t last_ = 0;
  int64_t value_ = 0;
};

}  // namespace cnc::cia402
