// The motion controller's servo cycle: feedback, E-stop and faults, the free,
// teleop and coord modes, kinematics, limits, backlash and the outputs.
#include "core/motion/motion_internal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

#include "core/ipc/estop.hpp"
#include "core/motion/params.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"

namespace cnc::motion {

using namespace detail;

// ---------------------------------------------------------------- cycle

double MotionController::axis_dtg(int a) const noexcept {
  switch (mode_) {
    case ipc::MotionMode::Coord: return tp_out_.move_end[a] - carte_cmd_[a];
    case ipc::MotionMode::Teleop: return axis_free_[static_cast<std::size_t>(a)].target() - carte_cmd_[a];
    default: return 0;
  }
}

void MotionController::read_feedback() noexcept {
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    const JointInputs& ji = in_.joints[static_cast<std::size_t>(j)];
    jt.pos_fb = ji.motor_pos_fb - jt.motor_offset - jt.backlash_filt - jt.screw_comp;
    jt.on_pos_limit = ji.pos_lim_sw;
    jt.on_neg_limit = ji.neg_lim_sw;
    jt.ferror = jt.pos_cmd - jt.pos_fb;
    const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
    jt.ferror_limit = std::max(c.min_ferror, c.ferror * std::fabs(jt.vel_cmd) / c.max_velocity);
    // The high-water mark follows the checked error: not while the drive
    // homes on its own (the check is suspended and the command lags by design).
    if (jt.home_state != HomeState::DriveHoming) jt.ferror_high = std::max(jt.ferror_high, std::fabs(jt.ferror));
  }
}

void MotionController::fault(int joint, int spindle, const char* fmt, ...) noexcept {
  char text[200];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(text, sizeof text, fmt, ap);
  va_end(ap);
  post_error("%s: motion disabled", text);
  cmd_enable(false);
  faulted_ = true;
  fault_reason_.assign(text);
  fault_joint_ = joint;
  fault_spindle_ = spindle;
  if (spindle >= 0) spindle_fault_[static_cast<std::size_t>(spindle)] = true;
}

// An E-stop request through the segment, or the E-stop chain open: acted on
// here, in the servo thread, whatever the task cycle does. The message is
// the task's when it catches up (it names the requesting process).
void MotionController::check_estop() noexcept {
  if (in_.estop_request != estop_seen_) {
    estop_seen_ = in_.estop_request;
    latch_estop(ipc::EstopCause::Request, ipc::estop_pid(in_.estop_request));
  }
  if (!in_.estop_chain_closed) latch_estop(ipc::EstopCause::ChainOpen, 0);
}

void MotionController::latch_estop(ipc::EstopCause cause, int32_t pid) noexcept {
  if (!estop_latched_) {
    estop_latched_ = true;
    estop_cause_ = cause;
    estop_pid_ = pid;
  }
  // Amplifiers and spindles off, planners flushed, homing and jogs ended.
  if (enabled_) cmd_enable(false);
}

// The enable handshake: amp-enable-out is on, and until every active
// joint's amplifier says it is ready (a CiA 402 drive: operation enabled and
// following) the command follows the feedback (no following error, nothing
// moves) and motion commands are refused. A joint whose amplifier is not
// ready within its AMP_READY_TIMEOUT faults, named. Afterwards
// amp-fault-in is what stops motion.
void MotionController::wait_for_amplifiers(double dt) noexcept {
  amps_wait_s_ += dt;
  amp_waiting_joint_ = -1;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (!joints_[static_cast<std::size_t>(j)].active || in_.joints[static_cast<std::size_t>(j)].amp_ready) continue;
    const double timeout = cfg_.joints[static_cast<std::size_t>(j)].amp_ready_timeout_s;
    if (amps_wait_s_ > timeout) {
      fault(j, -1, "joint %d amplifier not ready %.3f s after enable (joint.%d.amp-ready-in stayed false)", j, timeout, j);
      return;
    }
    if (amp_waiting_joint_ < 0) amp_waiting_joint_ = j;
  }
  if (amp_waiting_joint_ < 0) amps_ready_ = true;
  else resync_ = true;
}

const char* MotionController::amps_not_ready(const char* what) noexcept {
  if (!enabled_ || amps_ready_) return nullptr;
  return reason("cannot %s: joint %d's amplifier is not ready yet (joint.%d.amp-ready-in)", what, amp_waiting_joint_,
                amp_waiting_joint_);
}

// The servo thread became late (OVERRUN_STREAK consecutive overruns, or
// that many periods missed at once): once per streak, what OVERRUN_ACTION
// says. The thread itself reports the streak and the function to blame.
void MotionController::apply_overrun_action() noexcept {
  const bool became_late = in_.servo_late && !servo_was_late_;
  servo_was_late_ = in_.servo_late;
  if (!became_late || !enabled_) return;
  switch (cfg_.overrun_action) {
    case OverrunAction::Warn:
      break;
    case OverrunAction::Hold:
      // The operator's pause: the planner brakes along the path, or does
      // not start its next move, and holds until resume (the task adopts
      // the pause, or resumes at once when nothing runs). Jogs and homing
      // (free, teleop) are not held.
      if (mode_ == ipc::MotionMode::Coord && !tp_.is_paused()) {
        tp_.pause();
        overrun_hold_ = true;
        ++overrun_holds_;
      }
      break;
    case OverrunAction::Stop:
      fault(-1, -1, "the servo thread is late: %u consecutive overruns, %lld periods missed just now (OVERRUN_ACTION = STOP)",
            in_.overrun_streak, static_cast<long long>(in_.missed_cycles));
      break;
  }
}

void MotionController::check_faults() noexcept {
  if (!enabled_) return;
  if (!in_.enable) {
    fault(-1, -1, "motion.enable went false (external stop)");
    return;
  }
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (!jt.active) continue;
    const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
    const JointInputs& ji = in_.joints[static_cast<std::size_t>(j)];
    if (ji.amp_fault && jt.amp_enabled) {
      fault(j, -1, "joint %d amplifier fault (joint.%d.amp-fault-in)", j, j);
      jt.amp_fault = true;
      return;
    }
    const bool homing_ignores = jt.home_state != HomeState::Idle && c.homing.ignore_limits;
    // OVERRIDE_LIMITS serves jogging off a switch: it counts in free mode
    // (and for the jog that consumed it), never under coordinated motion.
    const bool overridden = (override_limits_ && mode_ == ipc::MotionMode::Free) || jt.jog_override_limits;
    if ((jt.on_pos_limit || jt.on_neg_limit) && !homing_ignores && !overridden) {
      fault(-1, -1, "joint %d on its %s limit switch%s (send override-limits, then jog off it)", j,
            jt.on_pos_limit ? "positive" : "negative", jt.home_state != HomeState::Idle ? " while homing" : "");
      return;
    }
    const bool drive_moves = jt.home_state == HomeState::DriveHoming;
    if (!drive_moves && std::fabs(jt.ferror) > jt.ferror_limit) {
      const double fe = jt.ferror, lim = jt.ferror_limit;
      fault(-1, -1, "joint %d following error %.4f exceeds its limit %.4f", j, fe, lim);
      jt.ferror_fault = true;
      return;
    }
  }
  // A spindle's drive (or VFD) in fault stops everything, as in LinuxCNC:
  // the axes must not keep cutting with a spindle that stopped.
  for (int s = 0; s < cfg_.spindles; ++s) {
    if (in_.spindles[static_cast<std::size_t>(s)].amp_fault) {
      fault(-1, s, "spindle %d amplifier fault (spindle.%d.amp-fault-in)", s, s);
      return;
    }
  }
}

void MotionController::update_jog_wheels() noexcept {
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    const JointInputs& ji = in_.joints[static_cast<std::size_t>(j)];
    const int32_t delta = ji.jog_counts - jt.prev_jog_counts;
    jt.prev_jog_counts = ji.jog_counts;
    if (!jt.jog_counts_valid) {
      jt.jog_counts_valid = true;
      continue;
    }
    if (delta == 0 || !ji.jog_enable || !enabled_ || mode_ != ipc::MotionMode::Free || in_.jog_inhibit) continue;
    if (jt.home_state != HomeState::Idle || joint_in_sync_group(j)) continue;
    const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
    double target = (jt.free.enabled() ? jt.free.target() : jt.pos_cmd) + delta * ji.jog_scale;
    if (ji.jog_vel_mode) {
      // Velocity mode: the joint stops when the wheel stops.
      const FreeLimits l = joint_limits(j, c.max_velocity);
      const double reach = jt.pos_cmd + stopping_distance(jt.free.velocity(), jt.free.acceleration(), l.max_acceleration,
                                                          l.max_jerk) + delta * ji.jog_scale;
      target = reach;
    }
    if (jt.homed) target = std::clamp(target, c.min_limit, c.max_limit);
    jt.free.set_target(target, joint_limits(j, c.max_velocity));
    jt.jogging = true;
  }
}

void MotionController::run_free(double dt) noexcept {
  update_jog_wheels();
  if (in_.jog_stop || in_.jog_stop_immediate) {
    for (int j = 0; j < cfg_.num_joints; ++j) {
      Joint& jt = joints_[static_cast<std::size_t>(j)];
      if (!jt.jogging) continue;
      if (in_.jog_stop_immediate) jt.free.reset(jt.pos_cmd);
      else jt.free.stop();
    }
  }
  run_homing(dt);
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (!jt.active) continue;
    if (jt.home_state == HomeState::DriveHoming) {
      jt.pos_cmd = jt.pos_fb;  // the drive moves: the command follows the feedback
      jt.free.reset(jt.pos_fb);
      continue;
    }
    if (jt.home_state == HomeState::FinalMove && joint_in_sync_group(j)) continue;  // set by the group planner
    jt.pos_cmd = jt.free.update(dt);
    if (jt.jogging && jt.free.done()) {
      jt.jogging = false;
      if (jt.jog_override_limits) {
        // OVERRIDE_LIMITS lasts until the end of the next jog (3.8.17).
        jt.jog_override_limits = false;
        override_limits_ = false;
      }
    }
  }
  if (usable_forward(kins_)) {
    double q[kMaxJoints];
    for (int j = 0; j < kMaxJoints; ++j) q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
    Pose p;
    if (kins_.forward(q, p) == kin::KinResult::Ok) carte_cmd_ = p;
  }
}

// The planner trips on the probe input in the cycle it sees it: its pose
// is the commanded one then, late by the input's transport and off by the
// following error. A drive whose touch probe latched its encoder at the
// edge (its probe count advanced since the cycle before the trip) gives
// that joint exactly; the probed pose is the forward kinematics of the
// joints at the trip with those replaced. A latch whose position arrives
// after the trip (another PDO) is taken when it arrives; only the first
// latch of each joint counts until the next probe move.
void MotionController::take_probe_latches() noexcept {
  bool changed = false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    const auto u = static_cast<std::size_t>(j);
    if ((probe_latched_mask_ >> j) & 1u) continue;
    if (in_.joints[u].probe_count == probe_count_before_[u]) continue;
    const Joint& jt = joints_[u];
    probe_latched_joint_[u] = in_.joints[u].probe_position - jt.motor_offset - jt.backlash_filt - jt.screw_comp;
    probe_latched_mask_ |= 1u << j;
    changed = true;
  }
  if (!changed || !usable_forward(kins_)) return;
  double hint[kMaxJoints], q[kMaxJoints];
  for (int j = 0; j < kMaxJoints; ++j) hint[j] = q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
  if (kins_.inverse(probe_tp_pos_, hint, q) != kin::KinResult::Ok) return;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if ((probe_latched_mask_ >> j) & 1u) q[j] = probe_latched_joint_[static_cast<std::size_t>(j)];
  }
  Pose p;
  if (kins_.forward(q, p) == kin::KinResult::Ok) probed_pos_ = p;
}

void MotionController::wait_for_probe_latches() noexcept {
  if (!probe_latch_pending_) return;
  uint32_t missing = 0;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (in_.joints[static_cast<std::size_t>(j)].probe_latch_wired && !((probe_latched_mask_ >> j) & 1u)) missing |= 1u << j;
  }
  if (missing == 0) {
    probe_latch_pending_ = false;
    return;
  }
  if (++probe_latch_cycles_ * dt_ < kProbeLatchWait) return;
  probe_latch_pending_ = false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if ((missing >> j) & 1u) {
      post_text("probe: joint %d's touch probe latched nothing within %.0f ms of the trip: its probed position is the "
                "commanded one at the trip (check the probe wiring to its drive and the latch's PDO)",
                j, kProbeLatchWait * 1000);
    }
  }
}

void MotionController::apply_inverse_kinematics() noexcept {
  double hint[kMaxJoints], q[kMaxJoints];
  for (int j = 0; j < kMaxJoints; ++j) hint[j] = q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
  const kin::KinResult r = kins_.inverse(carte_cmd_, hint, q);
  if (r != kin::KinResult::Ok) {
    post_error("inverse kinematics failed (%s) at X%.4f Y%.4f Z%.4f: motion stopped", kin::to_string(r), carte_cmd_[0],
               carte_cmd_[1], carte_cmd_[2]);
    // Hold the joints where they are; the planner restarts from there.
    if (usable_forward(kins_)) kins_.forward(hint, carte_cmd_);
    tp_.reset(carte_cmd_);
    for (int a = 0; a < kNumAxes; ++a) axis_free_[static_cast<std::size_t>(a)].reset(carte_cmd_[a]);
    return;
  }
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    jt.coarse_pos = q[j];
    jt.pos_cmd = q[j];  // the planner runs every servo period: interpolation is the identity
  }
}

void MotionController::run_teleop(double dt) noexcept {
  for (int a = 0; a < kNumAxes; ++a) {
    if (!cfg_.axes[static_cast<std::size_t>(a)].present) continue;
    carte_cmd_[a] = axis_free_[static_cast<std::size_t>(a)].update(dt);
  }
  apply_inverse_kinematics();
}

void MotionController::run_coord(double dt) noexcept {
  tp::CycleInputs ti;
  double scale = feed_override_enabled_ ? feed_scale_ : 1.0;
  if (adaptive_enabled_) scale *= std::clamp(in_.adaptive_feed, 0.0, 1.0);
  if ((feed_hold_enabled_ && in_.feed_hold) || in_.feed_inhibit) scale = 0;
  ti.feed_scale = scale;
  ti.rapid_scale = feed_override_enabled_ ? rapid_scale_ : 1.0;
  ti.max_velocity = max_velocity_;
  ti.probe_input = in_.probe_input;
  for (int i = 0; i < cfg_.spindles; ++i) {
    int& stale = at_speed_stale_[static_cast<std::size_t>(i)];
    ti.spindles_at_speed = ti.spindles_at_speed && stale == 0 && in_.spindles[static_cast<std::size_t>(i)].at_speed;
    if (stale > 0) --stale;
  }
  tp_.run_cycle(ti, tp_out_);
  watch_spindle_wait(dt);
  carte_cmd_ = tp_out_.position;
  if (tp_out_.probe_tripped && !probe_tripped_) {
    probe_tripped_ = true;
    probed_pos_ = probe_tp_pos_ = tp_out_.probed_position;
    probe_latched_mask_ = 0;
    probe_latch_pending_ = true;
    probe_latch_cycles_ = 0;
  }
  if (probe_tripped_) {
    take_probe_latches();
    wait_for_probe_latches();
  } else {
    for (int j = 0; j < cfg_.num_joints; ++j) {
      probe_count_before_[static_cast<std::size_t>(j)] = in_.joints[static_cast<std::size_t>(j)].probe_count;
    }
  }
  // Outputs synchronised with motion (M62-M65, M67) change as the first
  // move queued after them starts (the task numbers segments in order).
  if (!tp_out_.done) {
    for (int digital = 0; digital < 2; ++digital) {
      auto& pending = digital ? dout_pending_ : aout_pending_;
      const int count = digital ? cfg_.num_dio : cfg_.num_aio;
      for (int i = 0; i < count; ++i) {
        PendingOutput& p = pending[static_cast<std::size_t>(i)];
        if (p.pending && tp_out_.id > p.after_id) {
          set_output(digital != 0, i, p.value);
          p.pending = false;
        }
      }
    }
  }
  apply_inverse_kinematics();
}

void MotionController::watch_spindle_wait(double dt) noexcept {
  if (!tp_out_.waiting_for_spindle) {
    spindle_wait_ = -1;
    spindle_wait_s_ = 0;
    return;
  }
  int s = 0;
  while (s + 1 < cfg_.spindles && in_.spindles[static_cast<std::size_t>(s)].at_speed &&
         at_speed_stale_[static_cast<std::size_t>(s)] == 0) {
    ++s;
  }
  if (s != spindle_wait_) spindle_wait_s_ = 0;  // the timeout is the waited-for spindle's
  spindle_wait_ = s;
  spindle_wait_s_ += dt;
  const double timeout = cfg_.spindle[static_cast<std::size_t>(s)].at_speed_timeout_s;
  if (timeout > 0 && spindle_wait_s_ >= timeout) {
    spindle_timeout_reason_.format("spindle %d did not reach speed within %g s ([SPINDLE_%d]AT_SPEED_TIMEOUT; "
                                   "spindle.%d.at-speed stayed FALSE)",
                                   s, timeout, s, s);
    ++spindle_timeouts_;
    tp_.abort();
    spindle_wait_ = -1;
    spindle_wait_s_ = 0;
  }
}

void MotionController::set_output(bool digital, int index, double value) noexcept {
  if (digital) out_.digital_out[static_cast<std::size_t>(index)] = value != 0;
  else out_.analog_out[static_cast<std::size_t>(index)] = value;
}

void MotionController::check_soft_limits() noexcept {
  bool on_limit = false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
    jt.soft_min = jt.homed && jt.pos_cmd <= c.min_limit;
    jt.soft_max = jt.homed && jt.pos_cmd >= c.max_limit;
    const double excess = jt.homed ? std::max(jt.pos_cmd - c.max_limit, c.min_limit - jt.pos_cmd) : 0;
    if (excess > 1e-6 && enabled_ && mode_ != ipc::MotionMode::Free) {
      post_error("joint %d: commanded position %.4f exceeds its soft limit (%g..%g): motion stopped", j, jt.pos_cmd,
                 c.min_limit, c.max_limit);
      abort_all();
    }
    on_limit = on_limit || jt.soft_min || jt.soft_max;
  }
  out_.on_soft_limit = on_limit;
}

void MotionController::update_backlash(int j, double dt) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
  JointCompensation* comp = comp_[static_cast<std::size_t>(j)];
  if (c.backlash <= 0 && comp == nullptr) {
    jt.backlash_corr = jt.backlash_filt = jt.backlash_vel = 0;
    jt.comp_ramp.reset(0);
    return;
  }
  if (jt.home_state == HomeState::DriveHoming) {
    // The drive moves on its own and its position jumps to the home offset
    // at the reference; the command copies the feedback. The correction is
    // held: a ramp chasing that jump would leave the motor command behind by
    // the jump (a 264 mm step when the drive hands back to CSP).
    jt.comp_ramp.reset(jt.backlash_filt);
    jt.backlash_vel = 0;
    return;
  }
  // What the direction of travel asks for: the screw table's correction once
  // the joint is homed (a table replaces BACKLASH, as in LinuxCNC), else
  // +-BACKLASH/2; at rest the last direction stays.
  double table = 0;
  const bool has_table = comp != nullptr && comp->correction(jt.pos_cmd, jt.vel_cmd, table);
  double corr;
  if (has_table && jt.homed) {
    corr = table;
  } else if (c.backlash > 0) {
    corr = jt.backlash_corr > 0 ? c.backlash / 2 : jt.backlash_corr < 0 ? -c.backlash / 2 : 0;
    if (jt.vel_cmd > 1e-9) corr = c.backlash / 2;
    else if (jt.vel_cmd < -1e-9) corr = -c.backlash / 2;
  } else {
    corr = 0;
  }
  jt.backlash_corr = corr;
  // The ramp moves within the share of the joint's limits the planners
  // leave free (COMP_RESERVE) and is clamped so that joint command plus
  // correction never exceed the joint's own limits.
  const double r = cfg_.comp_reserve;
  const RampLimits own{c.max_velocity * r, c.max_acceleration * r, c.max_jerk * r};
  const JointMotion motion{jt.vel_cmd, jt.acc_cmd, c.max_velocity, c.max_acceleration};
  jt.backlash_filt = jt.comp_ramp.update(corr, dt, own, motion);
  jt.backlash_vel = jt.comp_ramp.velocity();
  jt.screw_comp = 0;
}

void MotionController::compute_outputs(double dt) noexcept {
  out_.motion_enabled = enabled_;
  out_.coord_mode = mode_ == ipc::MotionMode::Coord;
  out_.teleop_mode = mode_ == ipc::MotionMode::Teleop;
  out_.in_position = in_position();
  out_.is_all_homed = all_homed();
  bool jogging = false;
  double q[kMaxJoints] = {};
  for (int j = 0; j < kMaxJoints; ++j) q[j] = joints_[static_cast<std::size_t>(j)].pos_fb;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    JointOutputs& o = out_.joints[static_cast<std::size_t>(j)];
    const double prev_vel = jt.vel_cmd;
    jt.vel_cmd = (jt.pos_cmd - o.pos_cmd) / dt;
    jt.acc_cmd = (jt.vel_cmd - prev_vel) / dt;
    if (!enabled_) jt.vel_cmd = jt.acc_cmd = 0;
    update_backlash(j, dt);
    o.pos_cmd = jt.pos_cmd;
    o.coarse_pos_cmd = mode_ == ipc::MotionMode::Free ? jt.pos_cmd : jt.coarse_pos;
    o.motor_pos_cmd = jt.pos_cmd + jt.backlash_filt + jt.screw_comp + jt.motor_offset;
    o.pos_fb = jt.pos_fb;
    o.vel_cmd = jt.vel_cmd;
    o.acc_cmd = jt.acc_cmd;
    o.f_error = jt.ferror;
    o.f_error_lim = jt.ferror_limit;
    o.f_errored = jt.ferror_fault;
    o.faulted = jt.amp_fault;
    o.motor_offset = jt.motor_offset;
    o.backlash_corr = jt.backlash_corr;
    o.backlash_filt = jt.backlash_filt;
    o.backlash_vel = jt.backlash_vel;
    o.free_pos_cmd = jt.free.target();
    o.free_vel_lim = jt.free.limits().max_velocity;
    o.free_tp_enable = jt.free.enabled() && !jt.free.done();
    o.amp_enable = jt.amp_enabled && enabled_;
    o.active = jt.active;
    o.homed = jt.homed;
    o.homing = jt.home_state != HomeState::Idle;
    o.home_state = static_cast<int32_t>(jt.home_state);
    o.in_position = mode_ == ipc::MotionMode::Free ? jt.free.done() : out_.in_position;
    o.drive_home_start = jt.drive_home_request;
    o.unlock = jt.unlock_request;
    o.pos_hard_limit = jt.on_pos_limit;
    o.neg_hard_limit = jt.on_neg_limit;
    jogging = jogging || jt.jogging;
  }
  out_.jog_is_active = jogging;
  // carte_pos_fb: forward kinematics when usable, otherwise unknown (3.6).
  carte_fb_valid_ = false;
  if (usable_forward(kins_) && (all_homed() || !kins_.requires_homing())) {
    Pose p;
    if (kins_.forward(q, p) == kin::KinResult::Ok) {
      carte_fb_ = p;
      carte_fb_valid_ = true;
    }
  }
  for (int a = 0; a < kNumAxes; ++a) {
    AxisOutputs& ao = out_.axes[static_cast<std::size_t>(a)];
    const FreePlanner& p = axis_free_[static_cast<std::size_t>(a)];
    ao.pos_cmd = carte_cmd_[a];
    ao.teleop_pos_cmd = p.position();
    ao.teleop_vel_cmd = p.velocity();
    ao.teleop_vel_lim = p.limits().max_velocity;
    ao.teleop_tp_enable = mode_ == ipc::MotionMode::Teleop && !p.done();
  }
  if (mode_ == ipc::MotionMode::Coord) {
    out_.program_line = tp_out_.line;
    out_.current_vel = enabled_ ? tp_out_.path_velocity : 0.0;  // disabled: nothing moves
    out_.motion_type = 0;
  } else {
    out_.current_vel = 0;
    for (int j = 0; j < cfg_.num_joints; ++j) {
      out_.current_vel = std::max(out_.current_vel, std::fabs(joints_[static_cast<std::size_t>(j)].vel_cmd));
    }
  }
  out_.requested_vel = 0;
  if (mode_ == ipc::MotionMode::Coord) {
    out_.distance_to_go = tp_out_.distance_to_go;  // along the path (an arc's length, not its chord)
  } else {
    double dtg = 0;
    for (int a = 0; a < kNumAxes; ++a) {
      const double d = axis_dtg(a);
      dtg += d * d;
    }
    out_.distance_to_go = std::sqrt(dtg);
  }
  // The watchdog toward the drives runs whenever motion is enabled: if this
  // function stops, the drive layer sees it stand still and stops the drives.
  out_.watchdog_enabled = enabled_;
  out_.watchdog = enabled_ && !out_.watchdog;
  out_.tool_offset = tool_offset_;
  for (int s = 0; s < cfg_.spindles; ++s) {
    const Spindle& sp = spindles_[static_cast<std::size_t>(s)];
    SpindleOutputs& so = out_.spindles[static_cast<std::size_t>(s)];
    // Command x override, kept within the spindle's limits whatever both say.
    const double cmd = limit_spindle_speed(sp.on && enabled_ ? sp.speed * sp.override_scale : 0,
                                           cfg_.spindle[static_cast<std::size_t>(s)]);
    so.speed_out = cmd;
    so.speed_out_abs = std::fabs(cmd);
    so.speed_out_rps = cmd / 60;
    so.speed_cmd_rps = sp.speed / 60;
    so.on = sp.on && enabled_;
    so.forward = so.on && cmd > 0;
    so.reverse = so.on && cmd < 0;
    so.brake = sp.brake || !enabled_;
    so.orient = sp.orient && enabled_;
    so.orient_angle = sp.orient_angle;
    so.orient_mode = sp.orient_mode;
  }
}

void MotionController::update(double dt) noexcept {
  dt_ = dt;
  ++cycles_;
  out_.servo_last_period_ns = dt * 1e9;
  for (JointOutputs& o : out_.joints) o.index_enable_write = -1;
  read_feedback();
  check_estop();
  if (enabled_ && !amps_ready_) wait_for_amplifiers(dt);
  if (resync_ || !enabled_) resync_from_feedback();
  apply_overrun_action();
  check_faults();
  if (enabled_) {
    switch (mode_) {
      case ipc::MotionMode::Free: run_free(dt); break;
      case ipc::MotionMode::Teleop: run_teleop(dt); break;
      case ipc::MotionMode::Coord: run_coord(dt); break;
    }
  }
  check_soft_limits();
  compute_outputs(dt);
}

}  // namespace cnc::motion
