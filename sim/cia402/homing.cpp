#include "sim/cia402/homing.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::cia402::sim {

bool HomingEngine::is_supported(int m) noexcept {
  return (m >= 1 && m <= 6) || (m >= 17 && m <= 22) || m == 33 || m == 34 || m == 35 || m == 37;
}

bool HomingEngine::sensor(const Inputs& in) const noexcept {
  switch (sensor_) {
    case Sensor::NegLimit: return in.neg_limit;
    case Sensor::PosLimit: return in.pos_limit;
    case Sensor::Home: return in.home;
    case Sensor::None: return false;
  }
  return false;
}

void HomingEngine::fail(const char* why) noexcept {
  status_ = Status::Error;
  error_ = why;
  stopping_ = true;
  done_after_stop_ = false;
}

bool HomingEngine::start(int method, double switch_speed, double zero_speed, double accel, const Inputs& now) noexcept {
  count_ = at_ = 0;
  stopping_ = done_after_stop_ = false;
  v_ = target_v_ = 0;
  error_ = "";
  status_ = Status::InProgress;
  switch_speed_ = std::fabs(switch_speed);
  zero_speed_ = std::fabs(zero_speed);
  accel_ = accel > 0 ? accel : 10.0 * std::max(switch_speed_, zero_speed_);
  if (!is_supported(method)) {
    fail("homing method not supported by this drive");
    stopping_ = false;
    return false;
  }
  if (method == 35 || method == 37) {
    sensor_ = Sensor::None;
    add({0, false, Until::Now, true, true});
    return true;
  }
  if (zero_speed_ <= 0 || ((method < 33) && switch_speed_ <= 0)) {
    fail("homing speeds (0x6099) are zero");
    stopping_ = false;
    return false;
  }
  const bool index = method <= 14 || method >= 33;
  const int base = method > 16 && method < 33 ? method - 16 : method;
  // Which switch, the direction of the final approach through its edge, and
  // whether that approach leaves the switch (true) or enters it.
  int dir = 1;
  bool leaving = true;
  switch (base) {
    case 1: sensor_ = Sensor::NegLimit; dir = 1; leaving = true; break;
    case 2: sensor_ = Sensor::PosLimit; dir = -1; leaving = true; break;
    case 3: sensor_ = Sensor::Home; dir = -1; leaving = true; break;   // switch active on the + side, index left of its edge
    case 4: sensor_ = Sensor::Home; dir = 1; leaving = false; break;   // ... index right of its edge
    case 5: sensor_ = Sensor::Home; dir = 1; leaving = true; break;    // switch active on the - side, index right of its edge
    case 6: sensor_ = Sensor::Home; dir = -1; leaving = false; break;  // ... index left of its edge
    case 33: sensor_ = Sensor::None; dir = -1; break;
    case 34: sensor_ = Sensor::None; dir = 1; break;
    default: break;
  }
  if (sensor_ == Sensor::None) {
    add({dir, false, Until::Index, true, true});
    return true;
  }
  const bool on = sensor(now);
  if (leaving) {
    if (!on) add({-dir, true, Until::On, false, true});
  } else if (!on) {
    add({dir, true, Until::On, false, true});
    add({-dir, true, Until::Off, false, true});
  } else {
    add({-dir, true, Until::Off, false, true});
  }
  add({dir, false, leaving ? Until::Off : Until::On, !index, !index});
  if (index) add({dir, false, Until::Index, true, true});
  return true;
}

void HomingEngine::interrupt() noexcept {
  if (status_ == Status::InProgress || status_ == Status::Attained) {
    status_ = Status::Idle;
    stopping_ = true;
    done_after_stop_ = false;
  }
}

HomingEngine::Output HomingEngine::step(double dt, const Inputs& in) noexcept {
  Output o;
  const double v0 = v_;
  auto ramp_to = [&](double target) {
    const double dv = accel_ * dt;
    v_ = v_ < target ? std::min(v_ + dv, target) : std::max(v_ - dv, target);
  };
  if (stopping_) {
    ramp_to(0.0);
    if (v_ == 0.0) {
      stopping_ = false;
      if (status_ == Status::Error || status_ == Status::Idle) {
        // stays
      } else if (done_after_stop_) {
        status_ = Status::Completed;
      } else {
        ++at_;
      }
    }
  } else if (status_ == Status::InProgress || status_ == Status::Attained) {
    const Move& m = plan_[at_];
    const bool looks_for_pos = sensor_ == Sensor::PosLimit && m.until == Until::On;
    const bool looks_for_neg = sensor_ == Sensor::NegLimit && m.until == Until::On;
    if (m.dir > 0 && in.pos_limit && !looks_for_pos && sensor_ != Sensor::PosLimit) {
      fail("the positive limit switch was reached while homing");
    } else if (m.dir < 0 && in.neg_limit && !looks_for_neg && sensor_ != Sensor::NegLimit) {
      fail("the negative limit switch was reached while homing");
    } else {
      bool met = false;
      switch (m.until) {
        case Until::On: met = sensor(in); break;
        case Until::Off: met = !sensor(in); break;
        case Until::Index: met = in.index && (in.velocity * m.dir > 0 || v_ * m.dir > 0); break;
        case Until::Now: met = true; break;
      }
      if (met) {
        if (m.reference) {
          o.home_event = true;
          o.home_counts = m.until == Until::Index ? in.index_counts : in.counts;
          status_ = Status::Attained;
        }
        if (m.stop || at_ + 1 >= count_) {
          stopping_ = true;
          done_after_stop_ = at_ + 1 >= count_;
          ramp_to(0.0);
          if (v_ == 0.0) {
            stopping_ = false;
            if (done_after_stop_) status_ = Status::Completed;
            else ++at_;
          }
        } else {
          ++at_;
        }
      } else {
        ramp_to(m.dir * (m.fast ? switch_speed_ : zero_speed_));
      }
    }
    if (status_ == Status::Error) ramp_to(0.0);
  }
  o.velocity = v_;
  o.acceleration = dt > 0 ? (v_ - v0) / dt : 0.0;
  return o;
}

}  // namespace cnc::cia402::sim
