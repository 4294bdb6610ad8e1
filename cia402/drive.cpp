#include "cia402/drive.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <stdexcept>

#include "core/util/messages.hpp"

namespace cnc::cia402 {
namespace {
constexpr int64_t kMs = 1'000'000;
constexpr int64_t kModeReadInterval = 2 * kMs;
bool is_faulted(State s) { return s == State::Fault || s == State::FaultReactionActive; }
long long ms(int64_t ns) { return static_cast<long long>(ns / kMs); }
}  // namespace

DriveSlots DriveSlots::find(const DriveLink& l, int a) noexcept {
  DriveSlots s;
  s.controlword = l.output(a, obj::kControlword);
  s.target_position = l.output(a, obj::kTargetPosition);
  s.target_velocity = l.output(a, obj::kTargetVelocity);
  s.target_torque = l.output(a, obj::kTargetTorque);
  s.modes = l.output(a, obj::kModes);
  s.probe_function = l.output(a, obj::kTouchProbeFunction);
  s.statusword = l.input(a, obj::kStatusword);
  s.position_actual = l.input(a, obj::kPositionActual);
  s.velocity_actual = l.input(a, obj::kVelocityActual);
  s.torque_actual = l.input(a, obj::kTorqueActual);
  s.ferror_actual = l.input(a, obj::kFollowingErrorActual);
  s.modes_display = l.input(a, obj::kModesDisplay);
  s.error_code = l.input(a, obj::kErrorCode);
  s.digital_inputs = l.input(a, obj::kDigitalInputs);
  s.probe_status = l.input(a, obj::kTouchProbeStatus);
  s.probe1_rising = l.input(a, obj::kTouchProbe1Rising);
  s.probe2_rising = l.input(a, obj::kTouchProbe2Rising);
  return s;
}

// A probe is re-armed by clearing and setting its enable bit; the status
// must show each step, so a stored value is never taken from an older arming.
bool Drive::Probe::update(bool want, uint16_t status) noexcept {
  const uint16_t s = static_cast<uint16_t>(status >> shift);
  const bool enabled = (s & tp::kStatusEnabled) != 0;
  const bool stored = (s & tp::kStatusRisingStored) != 0;
  switch (st) {
    case St::Off:
      if (want) st = enabled ? St::Disarming : St::Arming;
      return false;
    case St::Disarming:
      if (!enabled) st = want ? St::Arming : St::Off;
      return false;
    case St::Arming:
      if (!want) st = St::Disarming;
      else if (enabled && !stored) st = St::Armed;
      return false;
    case St::Armed:
      if (!want) {
        st = St::Disarming;
        return false;
      }
      if (stored) {
        st = St::Latched;
        held = 0;
        return true;
      }
      return false;
    case St::Latched:
      ++held;
      if (!want) st = St::Disarming;
      return false;
  }
  return false;
}

Drive::Drive(DriveConfig config, DriveLink& link, MessageQueue* messages)
    : config_(std::move(config)), link_(link), slots_(DriveSlots::find(link, config_.address)), messages_(messages) {
  update_period();
  probe1_.bits = tp::kEnable | tp::kRising;  // source: probe input 1
  probe1_.shift = 0;
  probe2_.bits = static_cast<uint16_t>((tp::kEnable | tp::kSourceZeroPulse | tp::kRising) << tp::kProbe2Shift);
  probe2_.shift = tp::kProbe2Shift;
  if (!slots_.probe_status || !slots_.probe1_rising) config_.probe = false;
}

void Drive::update_period() noexcept {
  period_s_ = static_cast<double>(link_.cycle_ns() > 0 ? link_.cycle_ns() : kMs) * 1e-9;
}

void Drive::check_mapping() const {
  auto need = [&](const Slot& s, const char* what) {
    if (!s) throw std::runtime_error(config_.origin + " " + config_.source + " (" + config_.name + ", address " +
                                     std::to_string(config_.address) + "): " + what + " is not in the process data");
  };
  need(slots_.statusword, "the statusword 0x6041");
  need(slots_.controlword, "the controlword 0x6040");
  if (config_.mode == Mode::CyclicSyncPosition || config_.home_method != 0) {
    need(slots_.position_actual, "the position actual value 0x6064 (mode CSP, homing)");
  }
  if (config_.mode == Mode::CyclicSyncPosition) need(slots_.target_position, "the target position 0x607A (mode CSP)");
  if (config_.mode == Mode::CyclicSyncVelocity) need(slots_.target_velocity, "the target velocity 0x60FF (mode CSV)");
  if (config_.mode == Mode::CyclicSyncTorque) need(slots_.target_torque, "the target torque 0x6071 (mode CST)");
}

void Drive::post(bool error, const char* fmt, ...) noexcept {
  if (!messages_) return;
  char text[256];
  int n = std::snprintf(text, sizeof text, "%s: ", config_.name.empty() ? config_.source.c_str() : config_.name.c_str());
  if (n < 0) n = 0;
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(text + n, sizeof text - static_cast<std::size_t>(n), fmt, ap);
  va_end(ap);
  messages_->post(error ? MessageKind::Error : MessageKind::Text, config_.source, text);
}

void Drive::explain_fault(uint16_t code, const char* how) noexcept {
  error_code_ = code;
  fault_text_.format("fault 0x%04X %s", code, error_code_text(code));
  const char* detail = "";
  if (code == err::kFollowingError) detail = ": the drive's following error window (0x6065/0x6066) was exceeded";
  else if (code == err::kHeartbeat) detail = ": the drive lost the master's heartbeat";
  else if (code == err::kRpdoTimeout) detail = ": the drive stopped receiving set-points";
  post(true, "fault 0x%04X %s%s (%s)", code, error_code_text(code), detail, how);
  fault_explained_ = true;
}

// ------------------------------------------------------------------ read

void Drive::read(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept {
  (void)now;
  health_ = link_.health(config_.address);
  const bool up = health_.operational && !health_.lost;
  // The stale-feedback budget: consecutive cycles whose inputs did not
  // answer the last cycle, while the bus still counts the drive as up.
  if (!up || health_.inputs_fresh) stale_cycles_ = 0;
  else if (stale_cycles_ < kStaleCountMax) ++stale_cycles_;
  const bool stale_out = config_.stale_limit > 0 && stale_cycles_ > config_.stale_limit;
  fb.link_ok = up && !stale_out;
  // Each new reason is said once: stale inputs often come first (a drive
  // that died stops answering at once), the bus's verdict (heartbeat, state)
  // follows and replaces it.
  const LinkDown down = !up ? LinkDown::Lost : stale_out ? LinkDown::Stale : LinkDown::No;
  if (down != link_down_ && down == LinkDown::Stale) {
    post(true, "no fresh feedback for %d cycles on %s (STALE_LIMIT = %d): the drive's inputs stopped arriving, "
         "the axis stops", stale_cycles_, link_.name().c_str(), config_.stale_limit);
    fault_text_.format("feedback stale for %d cycles on %s", stale_cycles_, link_.name().c_str());
  } else if (down != link_down_ && down == LinkDown::Lost && link_down_ != LinkDown::Start) {
    post(true, "lost the drive on %s (%s)", link_.name().c_str(), link_.loss_causes());
    // The status (and the task's message when motion stops) says why.
    fault_text_.format("lost on %s (%s)", link_.name().c_str(), link_.loss_causes());
  }
  if (down != LinkDown::Lost || link_down_ != LinkDown::Start) link_down_ = down;

  prev_state_ = state_;
  statusword_ = read_slot<uint16_t>(slots_.statusword);
  state_ = decode_state(statusword_);
  if (state_ == State::Invalid && !invalid_reported_) {
    post(true, "statusword 0x%04X matches no CiA 402 state", statusword_);
    invalid_reported_ = true;
  } else if (state_ != State::Invalid) {
    invalid_reported_ = false;
  }

  const int32_t raw = read_slot<int32_t>(slots_.position_actual);
  const int64_t pos = position_.update(raw);
  // Within the stale budget the position shown is the demand the sample
  // would belong to less the last measured lag (the drive is assumed to
  // keep following as it did), so one late frame neither freezes the
  // feedback of a moving axis nor trips a following error; past the budget
  // the link is not ok (above) and the axis stops.
  const bool operating = state_ == State::OperationEnabled;
  if (health_.inputs_fresh && operating) {
    fresh_lag_ = target_history_[1] - pos;
    have_fresh_lag_ = true;
  } else if (!operating) {
    have_fresh_lag_ = false;
  }
  const int64_t shown = stale_cycles_ > 0 && operating && have_fresh_lag_ ? target_history_[1] - fresh_lag_ : pos;
  fb.pos_fb = config_.scaling.to_units(shown);
  if (slots_.velocity_actual) {
    fb.vel_fb = config_.scaling.to_units_rate(static_cast<double>(read_slot<int32_t>(slots_.velocity_actual)));
  } else if (health_.inputs_fresh && have_prev_position_) {
    fb.vel_fb = config_.scaling.to_units(static_cast<double>(pos - prev_position_)) / period_s_;
  }
  vel_fb_ = fb.vel_fb;
  if (health_.inputs_fresh) {
    prev_position_ = pos;
    have_prev_position_ = true;
  }
  if (slots_.ferror_actual) {
    fb.ferror = config_.scaling.to_units(static_cast<int64_t>(read_slot<int32_t>(slots_.ferror_actual)));
  } else {
    // The target of two cycles ago is the demand this sample belongs to
    // (one cycle of transport, one of interpolation in the drive).
    fb.ferror = operating ? config_.scaling.to_units(target_history_[1] - shown) : 0.0;
  }
  fb.torque = slots_.torque_actual ? read_slot<int16_t>(slots_.torque_actual) * 0.1 * config_.scaling.direction : 0.0;
  if (slots_.modes_display) {
    mode_display_ = static_cast<Mode>(read_slot<int8_t>(slots_.modes_display));
    mode_display_known_ = true;
  }
  if (slots_.error_code) {
    error_code_ = read_slot<uint16_t>(slots_.error_code);
    error_code_known_ = true;
  }
  const uint32_t din = read_slot<uint32_t>(slots_.digital_inputs);
  fb.digital_inputs = din;
  fb.home_sw = (din & din::kHomeSwitch) != 0;
  const bool drive_pos = (din & din::kPositiveLimit) != 0, drive_neg = (din & din::kNegativeLimit) != 0;
  fb.pos_lim_sw = config_.scaling.direction > 0 ? drive_pos : drive_neg;
  fb.neg_lim_sw = config_.scaling.direction > 0 ? drive_neg : drive_pos;

  // Touch probes: 1 on the probe input, 2 on the encoder's zero pulse.
  probe_status_ = read_slot<uint16_t>(slots_.probe_status);
  fb.index_found = false;
  auto latched_units = [&](const Slot& s) {
    const int32_t at = read_slot<int32_t>(s);
    const int64_t unwrapped = pos + static_cast<int32_t>(static_cast<uint32_t>(at) - static_cast<uint32_t>(raw));
    return config_.scaling.to_units(unwrapped);
  };
  // A latch's position counts only from a frame no older than the status
  // frame that reported the latch (link_.input_sequence); else it waits.
  auto latch_ready = [&](Probe& p, const Slot& position, bool latched_now) {
    if (latched_now) {
      const uint64_t pos_seq = link_.input_sequence(position), status_seq = link_.input_sequence(slots_.probe_status);
      p.position_pending = pos_seq != 0 && pos_seq < status_seq;
      p.status_sequence = status_seq;
      return !p.position_pending;
    }
    if (p.position_pending && p.st == Probe::St::Latched && link_.input_sequence(position) > p.status_sequence) {
      p.position_pending = false;
      return true;
    }
    if (p.st != Probe::St::Latched) p.position_pending = false;
    return false;
  };
  const bool level = (probe_status_ & tp::kStatusInputLevel) != 0;
  bool release = probe1_.st == Probe::St::Latched && probe1_.held >= config_.probe_hold_cycles && !level &&
                 !probe1_.position_pending;
  if (latch_ready(probe1_, slots_.probe1_rising, probe1_.update(config_.probe && !release, probe_status_))) {
    probe_position_ = latched_units(slots_.probe1_rising);
    ++probe_count_;
  }
  fb.probe_input = probe1_.st == Probe::St::Latched || level;
  fb.probe_position = probe_position_;
  fb.probe_count = probe_count_;
  if (!cmd.index_enable) index_armed_ = false;
  else if (probe2_.st == Probe::St::Off && slots_.probe2_rising && slots_.probe_status) index_armed_ = true;
  if (latch_ready(probe2_, slots_.probe2_rising, probe2_.update(index_armed_, probe_status_))) {
    fb.index_found = true;
    fb.index_position = latched_units(slots_.probe2_rising);
    index_armed_ = false;
  }

  // Faults: explain each once, from 0x603F (mapped, or read acyclically).
  const bool faulted = is_faulted(state_);
  if (faulted && !fault_explained_) {
    if (error_code_known_ && error_code_ != 0) explain_fault(error_code_, "0x603F");
    else if (!error_read_wanted_ && pending_ != Acyclic::ReadError) error_read_wanted_ = true;
  }
  if (!faulted && !resetting_) {
    fault_explained_ = false;
    if (state_ != State::Invalid && state_ != State::NotReadyToSwitchOn && fb.link_ok) fault_text_.assign("");
  }

  fb.state = state_;
  fb.statusword = statusword_;
  fb.mode_display = mode_display_;
  fb.error_code = error_code_;
  fb.fault = faulted;
  const bool warning = (statusword_ & sw::kWarning) != 0;
  if (warning && !fb.warning && !faulted) post(false, "warning (statusword 0x%04X)", statusword_);
  fb.warning = warning;
  // While the enable sequence runs (the drive has not followed since the
  // enable rose) a drive still in fault (its reset comes with the enable
  // edge) or a link not up yet is not ready, not a fault: motion waits for
  // amp-ready (the `enabled` pin), and ENABLE_TIMEOUT_MS ends the wait with
  // a reason. Once the drive followed, either is a fault.
  const bool sequence_running = cmd.enable && !reached_oe_;
  fb.amp_fault = cmd.enable && (enable_failed_ || reset_failed_ || mode_failed_ || lost_enable_ || cmd.quick_stop ||
                                cmd.inhibit || (!sequence_running && (!fb.link_ok || (faulted && !resetting_))));
}

// ------------------------------------------------------------------ write

Mode Drive::wanted_mode(const DriveCommand& cmd) const noexcept {
  if (home_ == HomePhase::SwitchToHm || home_ == HomePhase::Start || home_ == HomePhase::Running) return Mode::Homing;
  switch (cmd.mode_request) {
    case 8: return Mode::CyclicSyncPosition;
    case 9: return Mode::CyclicSyncVelocity;
    case 10: return Mode::CyclicSyncTorque;
    default: return config_.mode;
  }
}

bool Drive::mode_switch_is_safe(const DriveCommand& cmd) const noexcept {
  if (state_ != State::OperationEnabled) return true;
  const double cmd_step = have_prev_cmd_ ? std::fabs(cmd.pos_cmd - prev_pos_cmd_) : 0.0;
  if (mode_cmd_ == Mode::Homing && mode_display_ == Mode::Homing) {
    // Out of HM: the drive says it is at rest ("target reached", bit 10, with
    // or without "homing attained"), its velocity actual may still hunt by a
    // count. The first CSP target is motion's command, which mirrored the
    // feedback while the drive homed: it must be where the drive is, or the
    // axis jumps.
    const bool at_rest = (statusword_ & sw::kTargetReached) != 0 || std::fabs(vel_fb_) <= config_.standstill_velocity;
    if (config_.mode != Mode::CyclicSyncPosition) return at_rest && std::fabs(cmd.vel_cmd) <= config_.standstill_velocity;
    return at_rest && cmd_step <= config_.home_return_window &&
           std::fabs(cmd.pos_cmd - position_units()) <= config_.home_return_window;
  }
  return std::fabs(vel_fb_) <= config_.standstill_velocity && cmd_step <= config_.standstill_velocity * period_s_ &&
         std::fabs(cmd.vel_cmd) <= config_.standstill_velocity;
}

double Drive::position_units() const noexcept { return config_.scaling.to_units(position_.value()); }

void Drive::run_modes(int64_t now, const DriveCommand& cmd) noexcept {
  const Mode want = wanted_mode(cmd);
  if (mode_cmd_ == Mode::None) {
    mode_cmd_ = want;  // the drive may have booted in any mode: set ours once
    switching_ = true;
    switch_started_ns_ = now;
    hold_position_ = position_.value();
  } else if (want != mode_cmd_ && !switching_ && !mode_failed_) {
    if (mode_switch_is_safe(cmd)) {
      mode_cmd_ = want;
      switching_ = true;
      switch_started_ns_ = now;
      hold_position_ = position_.value();
      unsafe_since_ns_ = -1;
      unsafe_reported_ = false;
    } else {
      if (unsafe_since_ns_ < 0) unsafe_since_ns_ = now;
      if (!unsafe_reported_ && now - unsafe_since_ns_ > config_.mode_timeout_ns) {
        post(false, "switch to mode %s waits for standstill", to_string(want));
        unsafe_reported_ = true;
      }
    }
  }
  if (!switching_) return;
  if (mode_display_known_ && mode_display_ == mode_cmd_) {
    switching_ = false;
  } else if (now - switch_started_ns_ > config_.mode_timeout_ns) {
    switching_ = false;
    mode_failed_ = true;
    post(true, "mode %s not confirmed by 0x6061 within %lld ms (it shows %d)", to_string(mode_cmd_),
         ms(config_.mode_timeout_ns), static_cast<int>(mode_display_));
  }
}

void Drive::run_homing(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept {
  const bool rise = cmd.home_start && !prev_home_start_;
  prev_home_start_ = cmd.home_start;
  const bool active = home_ == HomePhase::SwitchToHm || home_ == HomePhase::Start || home_ == HomePhase::Running;
  if (active && !cmd.home_start) {
    home_ = HomePhase::Aborting;  // motion gave up: stop the drive's homing and go back
  } else if (active && (state_ != State::OperationEnabled || mode_failed_)) {
    post(true, "drive homing stopped: the drive left operation enabled (%s)", to_string(state_));
    home_ = HomePhase::Error;
  } else if (active && now - home_started_ns_ > config_.home_timeout_ns) {
    post(true, "drive homing did not finish within %lld s", static_cast<long long>(config_.home_timeout_ns / 1'000'000'000));
    home_ = HomePhase::Error;
  }
  switch (home_) {
    case HomePhase::Idle:
      if (!rise) break;
      if (config_.home_method == 0) {
        post(true, "drive homing requested but no HOME_METHOD is configured");
        home_ = HomePhase::Error;
      } else if (state_ != State::OperationEnabled || !following_) {
        post(true, "drive homing needs the drive in operation enabled (it is in %s)", to_string(state_));
        home_ = HomePhase::Error;
      } else {
        home_ = HomePhase::SwitchToHm;
        home_started_ns_ = now;
        hold_position_ = position_.value();  // held until the drive is in HM (see write_targets)
        home_seen_progress_ = home_seen_other_ = false;
      }
      break;
    case HomePhase::SwitchToHm:
      if (mode_cmd_ == Mode::Homing && !switching_ && mode_display_ == Mode::Homing) home_ = HomePhase::Start;
      break;
    case HomePhase::Start:
      home_ = HomePhase::Running;  // bit 4 was 0 for this cycle: the next one is the edge
      home_started_ns_ = now;
      break;
    case HomePhase::Running: {
      // A "completed" left from an earlier homing must not count: accept it
      // once the status showed anything else since the start, or when it
      // persists (methods 35/37 complete within a cycle). "Interrupted" is
      // an error only after the drive was seen homing.
      const HomingStatus h = decode_homing(statusword_);
      if (h != HomingStatus::Completed) home_seen_other_ = true;
      if (h == HomingStatus::InProgress || h == HomingStatus::AttainedNotReached) home_seen_progress_ = true;
      if (h == HomingStatus::Completed && (home_seen_other_ || now - home_started_ns_ > 200'000'000)) {
        home_seen_progress_ = true;
      }
      if (h == HomingStatus::ErrorMoving || h == HomingStatus::ErrorStopped) {
        post(true, "drive homing (method %d) failed: %s", config_.home_method, to_string(h));
        home_ = HomePhase::Error;
      } else if (home_seen_progress_ && h == HomingStatus::Completed) {
        home_ = HomePhase::SwitchBack;
        home_started_ns_ = now;  // the return to the cyclic mode is timed from here
      } else if (h == HomingStatus::Interrupted && (home_seen_progress_ || now - home_started_ns_ > 2'000'000'000)) {
        post(true, "drive homing (method %d) %s", config_.home_method,
             home_seen_progress_ ? "was interrupted by the drive" : "did not start within 2 s");
        home_ = HomePhase::Error;
      }
      break;
    }
    case HomePhase::SwitchBack:
      if (mode_cmd_ != Mode::Homing && !switching_ && mode_display_ == mode_cmd_) {
        home_ = HomePhase::Done;
        post(false, "homed by the drive (method %d), position %.4f", config_.home_method, fb.pos_fb);
      } else if (mode_cmd_ == Mode::Homing && now - home_started_ns_ > config_.home_return_timeout_ns) {
        // The drive has stopped at its reference; what keeps it in HM is
        // motion's command (still moving, or away from the drive).
        const double step = have_prev_cmd_ ? cmd.pos_cmd - prev_pos_cmd_ : 0.0;
        post(true,
             "drive homing completed, but motion's command (%.4f, moving %.3f units/s) stays %.4f from the drive's "
             "position (%.4f, moving %.3f units/s) for %lld ms: not returning to %s (the axis would jump)",
             cmd.pos_cmd, step / period_s_, cmd.pos_cmd - position_units(), position_units(), vel_fb_,
             ms(config_.home_return_timeout_ns), to_string(config_.mode));
        home_ = HomePhase::Error;
      }
      break;
    case HomePhase::Aborting:
      if (mode_cmd_ != Mode::Homing && !switching_) home_ = HomePhase::Idle;
      break;
    case HomePhase::Done:
    case HomePhase::Error:
      if (!cmd.home_start) home_ = HomePhase::Idle;
      break;
  }
  fb.home_busy = home_ == HomePhase::SwitchToHm || home_ == HomePhase::Start || home_ == HomePhase::Running ||
                 home_ == HomePhase::SwitchBack || home_ == HomePhase::Aborting;
  fb.home_done = home_ == HomePhase::Done;
  fb.home_error = home_ == HomePhase::Error;
}

uint16_t Drive::run_state_machine(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept {
  const bool enable_rise = cmd.enable && !prev_enable_;
  const bool reset_rise = cmd.fault_reset && !prev_reset_;
  prev_enable_ = cmd.enable;
  prev_reset_ = cmd.fault_reset;
  if (!cmd.enable) {
    // Every latched refusal ends when the machine drops the enable: the
    // next enable edge tries once more (never a loop of resets).
    enable_failed_ = reset_failed_ = lost_enable_ = reached_oe_ = false;
  }
  if (enable_rise && mode_failed_) {
    mode_failed_ = false;
    mode_cmd_ = Mode::None;  // write the mode again
  }
  if (cmd.quick_stop && !prev_quick_stop_ && cmd.enable) post(true, "quick stop requested by the quick-stop input");
  prev_quick_stop_ = cmd.quick_stop;

  const bool faulted = is_faulted(state_);
  if (resetting_) {
    if (!faulted && state_ != State::Invalid) {
      resetting_ = false;
      post(false, "fault reset: the drive is in %s", to_string(state_));
    } else if (now - reset_started_ns_ > config_.fault_reset_timeout_ns) {
      resetting_ = false;
      reset_failed_ = cmd.enable;
      post(true, "fault reset did not clear the fault (%s)", fault_text_.empty() ? to_string(state_) : fault_text_.c_str());
    }
  } else if (faulted && (enable_rise || reset_rise)) {
    if (now - last_reset_ns_ < config_.fault_reset_holdoff_ns) {
      post(true, "fault reset refused: %lld ms after the previous one (hold-off %lld ms)", ms(now - last_reset_ns_),
           ms(config_.fault_reset_holdoff_ns));
      reset_failed_ = cmd.enable;
    } else {
      resetting_ = true;
      reset_phase_ = 0;
      reset_started_ns_ = last_reset_ns_ = now;
    }
  }

  if (reached_oe_ && cmd.enable && state_ != State::OperationEnabled && !lost_enable_) {
    lost_enable_ = true;  // the drive left operation enabled by itself
    if (!is_faulted(state_)) post(true, "the drive left operation enabled by itself (%s)", to_string(state_));
  }
  const bool asked = cmd.enable && !cmd.quick_stop && !cmd.inhibit && !enable_failed_ && !reset_failed_ &&
                     !mode_failed_ && !lost_enable_;
  const bool want = asked && fb.link_ok && !resetting_;

  // The enable sequence (later losses of bit 12 are not its business) is
  // timed from the enable, whether the link is up yet or a reset runs.
  if (asked && !reached_oe_) {
    if (enable_started_ns_ < 0) enable_started_ns_ = now;
    if (now - enable_started_ns_ > config_.enable_timeout_ns) {
      enable_failed_ = true;
      post(true, "did not reach operation enabled within %lld ms (stuck in %s, statusword 0x%04X%s)",
           ms(config_.enable_timeout_ns), to_string(state_), statusword_,
           fb.link_ok ? "" : "; the drive is not operational on the bus");
    }
  } else {
    enable_started_ns_ = -1;
  }

  if (state_ != State::QuickStopActive) quick_stop_since_ns_ = -1;
  if (resetting_) {
    // Bit 7 low for two cycles, then high: the drive sees a clean edge.
    return ++reset_phase_ <= 2 ? cw::kDisableVoltage : cw::kFaultResetCmd;
  }
  switch (state_) {
    case State::SwitchOnDisabled: return want ? cw::kShutdown : cw::kDisableVoltage;
    case State::ReadyToSwitchOn: return want ? cw::kSwitchOnCmd : cw::kDisableVoltage;
    case State::SwitchedOn:
      if (!want) return cw::kDisableVoltage;
      hold_position_ = position_.value();  // bumpless: the first target is where the motor is
      return cw::kEnableOperationCmd;
    case State::OperationEnabled:
      if (!want) return cw::kQuickStopCmd;  // stop on the quick-stop ramp, then power off (0x605A)
      // HM: bit 4 high runs the homing; back to 0 it interrupts it.
      if (home_ == HomePhase::Running) return cw::kEnableOperationCmd | cw::kBit4;
      return cw::kEnableOperationCmd;
    case State::QuickStopActive:
      if (quick_stop_since_ns_ < 0) quick_stop_since_ns_ = now;
      return now - quick_stop_since_ns_ > config_.quick_stop_timeout_ns ? cw::kDisableVoltage : cw::kQuickStopCmd;
    default:
      return cw::kDisableVoltage;
  }
}

void Drive::write_targets(const DriveCommand& cmd, bool operating) noexcept {
  const Scaling& sc = config_.scaling;
  int32_t velocity = 0;
  int16_t torque = 0;
  // In HM the drive moves by itself: the held target follows it (the first
  // cyclic target after HM is where the drive is). Not while the drive is
  // still in CSP waiting to switch: there a moving target would follow the
  // feedback it causes.
  if (state_ != State::OperationEnabled || mode_display_ == Mode::Homing) hold_position_ = position_.value();
  // Waiting for standstill before HM, motion already mirrors the feedback
  // into its command: sending that back as the target would close a loop
  // through the bus delay (the axis hunts instead of settling). The target
  // stays where the homing was asked for.
  const bool hold_for_homing = home_ == HomePhase::SwitchToHm;
  if (operating && mode_cmd_ == Mode::CyclicSyncPosition && !hold_for_homing) {
    target_ = sc.to_counts(cmd.pos_cmd);
  } else {
    target_ = hold_position_;
    if (operating && mode_cmd_ == Mode::CyclicSyncVelocity) {
      velocity = static_cast<int32_t>(std::clamp(sc.to_counts_rate(cmd.vel_cmd), -2.0e9, 2.0e9));
      target_ = position_.value();
    } else if (operating && mode_cmd_ == Mode::CyclicSyncTorque) {
      torque = static_cast<int16_t>(std::clamp(std::nearbyint(cmd.torque_cmd * 10.0 * sc.direction), -32768.0, 32767.0));
      target_ = position_.value();
    }
  }
  target_history_[1] = target_history_[0];
  target_history_[0] = target_;
  write_slot<int32_t>(slots_.target_position, static_cast<int32_t>(static_cast<uint32_t>(static_cast<uint64_t>(target_))));
  write_slot<int32_t>(slots_.target_velocity, velocity);
  write_slot<int16_t>(slots_.target_torque, torque);
}

void Drive::run_acyclic(int64_t now) noexcept {
  if (handle_ >= 0) {
    AcyclicResult r;
    if (!link_.poll(handle_, r)) return;
    handle_ = -1;
    const Acyclic done = pending_;
    pending_ = Acyclic::None;
    switch (done) {
      case Acyclic::WriteMode:
        if (r.abort_code == 0) {
          mode_written_ = mode_cmd_;
          mode_write_known_ = true;
          next_mode_read_ns_ = now;
        } else {
          post(true, "writing mode %s to 0x6060 failed (abort 0x%08X)", to_string(mode_cmd_), r.abort_code);
          switching_ = false;
          mode_failed_ = true;
        }
        break;
      case Acyclic::ReadMode:
        if (r.abort_code == 0) {
          mode_display_ = static_cast<Mode>(static_cast<int8_t>(r.value & 0xFF));
          mode_display_known_ = true;
        }
        next_mode_read_ns_ = now + kModeReadInterval;
        break;
      case Acyclic::WriteProbe:
        if (r.abort_code == 0) {
          probe_write_known_ = true;
        } else {
          post(true, "writing the touch probe function 0x60B8 failed (abort 0x%08X): probing off", r.abort_code);
          config_.probe = false;
          index_armed_ = false;
          probe_write_known_ = false;
        }
        break;
      case Acyclic::ReadError:
        error_read_wanted_ = false;
        if (r.abort_code == 0) explain_fault(static_cast<uint16_t>(r.value), "0x603F");
        else explain_fault(health_.emcy_code, "last EMCY; 0x603F unreadable");
        break;
      case Acyclic::None:
        break;
    }
    return;
  }
  const uint16_t probe_fn = static_cast<uint16_t>(probe1_.function() | probe2_.function());
  const int a = config_.address;
  if (!slots_.modes && mode_cmd_ != Mode::None && (!mode_write_known_ || mode_written_ != mode_cmd_)) {
    handle_ = link_.request_write(a, obj::kModes, static_cast<uint8_t>(static_cast<int8_t>(mode_cmd_)), 1);
    pending_ = Acyclic::WriteMode;
    mode_written_ = Mode::None;
    mode_write_known_ = false;
  } else if (!slots_.probe_function && (config_.probe || index_armed_ || probe_fn != 0) &&
             (!probe_write_known_ || probe_written_ != probe_fn)) {
    handle_ = link_.request_write(a, obj::kTouchProbeFunction, probe_fn, 2);
    pending_ = Acyclic::WriteProbe;
    probe_written_ = probe_fn;
    probe_write_known_ = false;
  } else if (error_read_wanted_) {
    handle_ = link_.request_read(a, obj::kErrorCode);
    pending_ = Acyclic::ReadError;
  } else if (!slots_.modes_display && (switching_ || !mode_display_known_) && now >= next_mode_read_ns_ &&
             (slots_.modes || mode_write_known_)) {
    handle_ = link_.request_read(a, obj::kModesDisplay);
    pending_ = Acyclic::ReadMode;
  }
  if (handle_ < 0) pending_ = Acyclic::None;  // every slot busy: try again next cycle
  else acyclic_started_ns_ = now;
}

void Drive::write(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept {
  run_homing(now, cmd, fb);
  run_modes(now, cmd);
  const uint16_t c = run_state_machine(now, cmd, fb);
  following_ = state_ == State::OperationEnabled &&
               (!is_cyclic(mode_display_) || (statusword_ & sw::kBit12) != 0) && mode_display_known_;
  if (following_ && cmd.enable) reached_oe_ = true;
  const bool operating = following_ && !switching_ && mode_display_ == mode_cmd_ && home_ != HomePhase::Aborting &&
                         (c & cw::kEnableOperation) && (c & cw::kQuickStop);
  write_targets(cmd, operating);
  controlword_ = c;
  write_slot<uint16_t>(slots_.controlword, c);
  write_slot<int8_t>(slots_.modes, static_cast<int8_t>(mode_cmd_));
  write_slot<uint16_t>(slots_.probe_function, static_cast<uint16_t>(probe1_.function() | probe2_.function()));
  run_acyclic(now);
  prev_pos_cmd_ = cmd.pos_cmd;
  have_prev_cmd_ = true;

  fb.controlword = c;
  fb.enabled = operating;
  fb.switching_mode = switching_;
}

bool Drive::is_safe() const noexcept {
  const bool powered = state_ == State::OperationEnabled || state_ == State::QuickStopActive ||
                       state_ == State::FaultReactionActive;
  return !powered || !health_.operational || health_.lost;
}

}  // namespace cnc::cia402
