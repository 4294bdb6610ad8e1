#include "sim/modbus/vfd_model.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::modbus_sim {

void VfdModel::set_reference_hz(double hz) noexcept { ref_hz_ = std::clamp(hz, 0.0, p_.max_hz); }

void VfdModel::reset_fault() noexcept { fault_ = 0; }

void VfdModel::trip(uint16_t code) noexcept {
  fault_ = code;
  current_ = 0;
}

void VfdModel::advance(int64_t now_ns) noexcept {
  if (last_ns_ == 0) last_ns_ = now_ns;
  double dt = static_cast<double>(now_ns - last_ns_) * 1e-9;
  last_ns_ = now_ns;
  // Substeps keep the ramp exact at any request rate.
  while (dt > 0) {
    const double h = std::min(dt, 0.001);
    dt -= h;
    const bool driven = run_ && fault_ == 0;
    const double target = driven ? (reverse_ ? -ref_hz_ : ref_hz_) : 0.0;
    // Driven: the ramp. Coasting after a trip: friction only, a tenth of it.
    const double rate = (driven || fault_ == 0) ? p_.ramp_hz_s / std::max(p_.inertia, 0.1) : p_.ramp_hz_s * 0.1;
    const double step = std::clamp(target - hz_, -rate * h, rate * h);
    hz_ += step;
    if (fault_ != 0 || (!run_ && std::fabs(hz_) < 1e-9)) {
      current_ = 0;
    } else {
      const double accel = std::fabs(step) / h;
      const double speed_share = std::fabs(hz_) / std::max(p_.max_hz, 1.0);
      current_ = p_.idle_a + p_.load_a * speed_share + p_.accel_a_per_hz_s * accel * p_.inertia;
      if (current_ > p_.trip_a) trip(p_.overcurrent_code);
    }
  }
}

}  // namespace cnc::modbus_sim
