// The motion controller's commands (the manual's section 3.8): handle() and
// what each command does, in the servo thread.
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

// ---------------------------------------------------------------- commands

bool MotionController::handle(const MotionCommand& c, MotionResult& result) noexcept {
  const char* why = nullptr;
  bool retry = false;
  const auto joint_ok = [&](int j) { return j >= 0 && j < cfg_.num_joints; };
  switch (c.type) {
    case Cmd::Abort:
      abort_all();
      break;
    case Cmd::Free:
      why = cmd_mode(ipc::MotionMode::Free);
      break;
    case Cmd::Teleop:
      why = cmd_mode(ipc::MotionMode::Teleop);
      break;
    case Cmd::Coord:
      why = cmd_mode(ipc::MotionMode::Coord);
      break;
    case Cmd::Enable:
      why = cmd_enable(true);
      break;
    case Cmd::Disable:
      why = cmd_enable(false);
      break;
    case Cmd::EnableAmplifier:
    case Cmd::DisableAmplifier:
      if (!joint_ok(c.joint)) why = reason("no joint %d", c.joint);
      else joints_[static_cast<std::size_t>(c.joint)].amp_enabled = c.type == Cmd::EnableAmplifier;
      break;
    case Cmd::ActivateJoint:
    case Cmd::DeactivateJoint:
      if (!joint_ok(c.joint)) why = reason("no joint %d", c.joint);
      else joints_[static_cast<std::size_t>(c.joint)].active = c.type == Cmd::ActivateJoint;
      break;
    case Cmd::EstopReset:
      why = cmd_estop_reset();
      break;
    case Cmd::Pause:
      tp_.pause();
      break;
    case Cmd::Resume:
      tp_.resume();
      overrun_hold_ = false;
      break;
    case Cmd::Step:
      tp_.step();
      overrun_hold_ = false;
      break;
    case Cmd::Scale:
      if (!(c.value[0] >= 0 && c.value[0] <= 10)) why = reason("feed override %g is outside 0 to 10", c.value[0]);
      else feed_scale_ = c.value[0];
      break;
    case Cmd::RapidScale:
      if (!(c.value[0] >= 0 && c.value[0] <= 1)) why = reason("rapid override %g is outside 0 to 1", c.value[0]);
      else rapid_scale_ = c.value[0];
      break;
    case Cmd::MaxVelocity:
      if (!(c.value[0] > 0)) why = reason("maximum velocity %g must be positive", c.value[0]);
      else max_velocity_ = c.value[0];
      break;
    case Cmd::OverrideLimits:
      override_limits_ = c.value[0] != 0;
      if (override_limits_) post_text("limit switches overridden until the end of the next jog");
      break;
    case Cmd::Home:
      why = cmd_home(c.joint);
      break;
    case Cmd::Unhome:
      why = cmd_unhome(c.joint);
      break;
    case Cmd::JogCont:
    case Cmd::JogIncr:
    case Cmd::JogAbs:
    case Cmd::JogStop:
      why = cmd_jog(c);
      break;
    case Cmd::SetLine:
    case Cmd::SetCircle:
    case Cmd::SetDwell:
    case Cmd::Probe:
      why = cmd_segment(c, retry);
      break;
    case Cmd::SetTeleopVector:
      if (mode_ != ipc::MotionMode::Teleop) {
        why = "SET_TELEOP_VECTOR needs teleop mode";
      } else if (!enabled_) {
        why = "motion is not enabled";
      } else if (const char* not_ready = amps_not_ready("SET_TELEOP_VECTOR")) {
        why = not_ready;
      } else {
        for (int a = 0; a < kNumAxes; ++a) {
          auto& p = axis_free_[static_cast<std::size_t>(a)];
          const AxisConfig& ax = cfg_.axes[static_cast<std::size_t>(a)];
          const double v = c.end[a];
          if (!ax.present) continue;
          FreeLimits l = axis_lim_[static_cast<std::size_t>(a)];
          l.max_velocity = std::min(std::fabs(v) * feed_scale_, l.max_velocity);
          if (v == 0) {
            p.stop();
          } else {
            const double lim = v > 0 ? ax.max_limit : ax.min_limit;
            p.set_target(std::fabs(lim) < 1e98 ? lim : p.position() + (v > 0 ? kFar : -kFar), l);
          }
        }
      }
      break;
    case Cmd::ClearProbeFlag:
      probe_tripped_ = false;
      break;
    case Cmd::SetParameter:
      why = cmd_set_parameter(c);
      break;
    case Cmd::SetDigitalOut:
    case Cmd::SetAnalogOut: {
      const bool digital = c.type == Cmd::SetDigitalOut;
      const int count = digital ? cfg_.num_dio : cfg_.num_aio;
      if (c.joint < 0 || c.joint >= count) {
        why = reason("no %s output %d (there are %d)", digital ? "digital" : "analog", c.joint, count);
      } else if (c.value[1] != 0) {
        PendingOutput& p = (digital ? dout_pending_ : aout_pending_)[static_cast<std::size_t>(c.joint)];
        p = PendingOutput{true, last_queued_id_, c.value[0]};
      } else {
        set_output(digital, c.joint, c.value[0]);
      }
      break;
    }
    case Cmd::SetSpindle:
    case Cmd::SpindleBrake:
    case Cmd::SpindleOverride:
    case Cmd::SpindleOrient: {
      if (c.joint < 0 || c.joint >= cfg_.spindles) {
        why = reason("no spindle %d (there are %d)", c.joint, cfg_.spindles);
        break;
      }
      Spindle& s = spindles_[static_cast<std::size_t>(c.joint)];
      if (c.type == Cmd::SetSpindle && c.value[0] < 0 && c.value[1] != 0 &&
          cfg_.spindle[static_cast<std::size_t>(c.joint)].max_reverse <= 0) {
        why = reason("spindle %d may not turn in reverse ([SPINDLE_%d]MAX_REVERSE_VELOCITY is 0)", c.joint, c.joint);
      } else if (c.type == Cmd::SetSpindle) {
        const bool on = c.value[1] != 0 && c.value[0] != 0;
        // Started, reversed or a new speed: the next feed move waits for
        // spindle.N.at-speed (a stop does not wait).
        if (on && (!s.on || s.speed != c.value[0])) {
          atspeed_next_feed_ = true;
          at_speed_stale_[static_cast<std::size_t>(c.joint)] = 2;
        }
        s.speed = c.value[0];
        s.on = on;
        if (s.on) s.brake = false;
        s.orient = false;
      } else if (c.type == Cmd::SpindleBrake) {
        if (c.value[0] != 0 && s.on) why = "the spindle brake cannot engage while the spindle turns";
        else s.brake = c.value[0] != 0;
      } else if (c.type == Cmd::SpindleOverride) {
        if (!(c.value[0] >= 0 && c.value[0] <= 10)) why = reason("spindle override %g is outside 0 to 10", c.value[0]);
        else s.override_scale = c.value[0];
      } else {
        s.on = false;
        s.orient = true;
        s.orient_angle = c.value[0];
        s.orient_mode = static_cast<int32_t>(c.value[1]);
      }
      break;
    }
    case Cmd::FeedOverrideEnable:
      feed_override_enabled_ = c.value[0] != 0;
      break;
    case Cmd::AdaptiveFeedEnable:
      adaptive_enabled_ = c.value[0] != 0;
      break;
    case Cmd::FeedHoldEnable:
      feed_hold_enabled_ = c.value[0] != 0;
      break;
    case Cmd::SwitchKinematics:
      if (!in_position()) why = "kinematics can only be switched while the machine is stopped";
      else if (!kins_.switch_to(static_cast<int>(c.value[0])))
        why = reason("kinematics %s has no type %d", kins_.name(), static_cast<int>(c.value[0]));
      else if (usable_forward(kins_)) {
        double q[kMaxJoints];
        for (int j = 0; j < kMaxJoints; ++j) q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
        kins_.forward(q, carte_cmd_);
        tp_.reset(carte_cmd_);
        for (int a = 0; a < kNumAxes; ++a) axis_free_[static_cast<std::size_t>(a)].reset(carte_cmd_[a]);
      }
      if (!why) apply_limits();  // which joints move an axis alone may have changed
      break;
    case Cmd::SetToolOffset:
      tool_offset_ = c.end;
      break;
  }
  if (retry) return false;
  result.serial = c.serial;
  result.type = c.type;
  result.accepted = why == nullptr;
  result.reason.assign(why ? why : "");
  last_serial_ = c.serial;
  return true;
}

void MotionController::abort_all() noexcept {
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (jt.home_state != HomeState::Idle) abort_homing(j, "homing aborted");
    jt.free.stop();
  }
  for (FreePlanner& p : axis_free_) p.stop();
  tp_.abort();
  home_all_ = false;
  home_sequence_ = -1;
  overrun_hold_ = false;
}

const char* MotionController::cmd_mode(ipc::MotionMode target) noexcept {
  if (target == mode_) return nullptr;
  if (!in_position()) {
    return reason("cannot change to %s mode while the machine moves (in %s mode)", ipc::to_string(target),
                  ipc::to_string(mode_));
  }
  if (target != ipc::MotionMode::Free) {
    if (!all_homed() && !cfg_.no_force_homing) {
      char list[96] = {};
      std::size_t len = 0;
      for (int j = 0; j < cfg_.num_joints && len + 4 < sizeof list; ++j) {
        if (joints_[static_cast<std::size_t>(j)].active && !joints_[static_cast<std::size_t>(j)].homed) {
          len += static_cast<std::size_t>(std::snprintf(list + len, sizeof list - len, "%s%d", len ? ", " : "", j));
        }
      }
      return reason("cannot change to %s mode: joints %s are not homed", ipc::to_string(target), list);
    }
    if (kins_.type() == kin::KinematicsType::ForwardOnly) {
      return reason("cannot change to %s mode: kinematics %s has no inverse", ipc::to_string(target), kins_.name());
    }
    double q[kMaxJoints];
    for (int j = 0; j < kMaxJoints; ++j) q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
    if (usable_forward(kins_)) {
      if (const auto r = kins_.forward(q, carte_cmd_); r != kin::KinResult::Ok) {
        return reason("cannot change to %s mode: forward kinematics failed (%s)", ipc::to_string(target),
                      kin::to_string(r));
      }
    }
    tp_.reset(carte_cmd_);
    for (int a = 0; a < kNumAxes; ++a) axis_free_[static_cast<std::size_t>(a)].reset(carte_cmd_[a]);
  } else {
    for (int j = 0; j < cfg_.num_joints; ++j) {
      Joint& jt = joints_[static_cast<std::size_t>(j)];
      jt.free.reset(jt.pos_cmd);
    }
  }
  mode_ = target;
  return nullptr;
}

const char* MotionController::cmd_estop_reset() noexcept {
  if (!in_.estop_chain_closed) return "the E-stop chain is open (iocontrol.0.emc-enable-in is false)";
  estop_latched_ = false;
  estop_cause_ = ipc::EstopCause::None;
  estop_pid_ = 0;
  return nullptr;
}

const char* MotionController::cmd_enable(bool enable) noexcept {
  if (enable && estop_latched_) {
    return reason("cannot enable: E-stop is latched (%s%s): reset the E-stop first", ipc::to_string(estop_cause_),
                  estop_cause_ == ipc::EstopCause::Request ? " by a client" : "");
  }
  if (enable == enabled_) return nullptr;
  // Queues and planners flushed, moves and homing ended (3.8.5, 3.8.6).
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (jt.home_state != HomeState::Idle) abort_homing(j, enable ? "motion enabled" : "motion disabled");
    jt.jogging = false;
    jt.ferror_fault = false;
    jt.amp_fault = false;
    jt.ferror_high = 0;
    if (jt.active) jt.amp_enabled = enable;
  }
  // Spindles stop with the machine and stay stopped when it comes back on.
  if (!enable) {
    for (Spindle& sp : spindles_) sp.on = sp.orient = false;
  }
  spindle_fault_ = {};
  if (enable) {
    fault_reason_.assign("");
    fault_joint_ = fault_spindle_ = -1;
  }
  home_all_ = false;
  home_sequence_ = -1;
  overrun_hold_ = false;
  if (!usable_forward(kins_)) mode_ = ipc::MotionMode::Free;
  enabled_ = enable;
  if (enable) faulted_ = false;
  // The amplifiers answer the enable (wait_for_amplifiers); those whose
  // ready input is already true (or unconnected) need not wait a cycle.
  amps_wait_s_ = 0;
  amp_waiting_joint_ = -1;
  for (int j = 0; enable && j < cfg_.num_joints && amp_waiting_joint_ < 0; ++j) {
    if (joints_[static_cast<std::size_t>(j)].active && !in_.joints[static_cast<std::size_t>(j)].amp_ready) {
      amp_waiting_joint_ = j;
    }
  }
  amps_ready_ = enable && amp_waiting_joint_ < 0;
  // Bumpless: the next cycle starts the command where the joints are.
  resync_ = true;
  return nullptr;
}

void MotionController::resync_from_feedback() noexcept {
  for (int j = 0; j < cfg_.num_joints; ++j) {
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    jt.pos_cmd = jt.pos_fb;
    jt.ferror = 0;
    if (enabled_) jt.free.resync(jt.pos_fb);
    else jt.free.reset(jt.pos_fb);
    out_.joints[static_cast<std::size_t>(j)].pos_cmd = jt.pos_fb;
  }
  double q[kMaxJoints];
  for (int j = 0; j < kMaxJoints; ++j) q[j] = joints_[static_cast<std::size_t>(j)].pos_cmd;
  if (usable_forward(kins_)) {
    Pose p;
    if (kins_.forward(q, p) == kin::KinResult::Ok) carte_cmd_ = p;
  }
  if (!enabled_ || resync_) {
    tp_.reset(carte_cmd_);
    for (int a = 0; a < kNumAxes; ++a) axis_free_[static_cast<std::size_t>(a)].reset(carte_cmd_[a]);
  }
  resync_ = false;
}

double MotionController::search_span(int j) const noexcept {
  const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
  const double span = c.max_limit - c.min_limit;
  return span < 1e98 ? span * 1.5 + 1 : kFar;
}

const char* MotionController::cmd_home(int joint) noexcept {
  if (!enabled_) return "cannot home: motion is not enabled (machine off)";
  if (const char* why = amps_not_ready("home")) return why;
  if (mode_ != ipc::MotionMode::Free) return reason("homing needs free mode (now %s)", ipc::to_string(mode_));
  if (in_.homing_inhibit) return "homing is inhibited (motion.homing-inhibit is set)";
  if (joint == -1) {
    bool any = false;
    for (int j = 0; j < cfg_.num_joints; ++j) any = any || cfg_.joints[static_cast<std::size_t>(j)].homing.has_sequence;
    if (!any) return "no joint has a HOME_SEQUENCE: home joints one at a time";
    if (!in_position()) return "cannot home while joints move";
    home_all_ = true;
    start_home_sequence(0);
    return nullptr;
  }
  if (joint < 0 || joint >= cfg_.num_joints) return reason("no joint %d", joint);
  Joint& jt = joints_[static_cast<std::size_t>(joint)];
  if (!jt.active) return reason("joint %d is not active", joint);
  if (jt.home_state != HomeState::Idle) return reason("joint %d is already homing", joint);
  if (!jt.free.done()) return reason("joint %d is moving", joint);
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(joint)].homing;
  if (joint_in_sync_group(joint)) {
    // A synchronised group (a gantry) is homed as a whole.
    home_all_ = false;
    start_home_sequence(std::abs(h.sequence));
    return nullptr;
  }
  if (h.is_shared && in_.joints[static_cast<std::size_t>(joint)].home_sw && h.search_vel != 0) {
    return reason("joint %d: its shared home switch is already active; move the joint off it first", joint);
  }
  jt.homed = false;
  jt.home_state = HomeState::Start;
  return nullptr;
}

void MotionController::start_home_sequence(int sequence) noexcept {
  home_sequence_ = sequence;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (!jt.active || !h.has_sequence || std::abs(h.sequence) != sequence) continue;
    if (h.is_shared && in_.joints[static_cast<std::size_t>(j)].home_sw && h.search_vel != 0) {
      abort_homing(j, "its shared home switch is already active; move the joint off it first");
      continue;
    }
    jt.homed = false;
    jt.home_state = HomeState::Start;
  }
}

const char* MotionController::cmd_unhome(int joint) noexcept {
  if (joint >= 0 && joint >= cfg_.num_joints) return reason("no joint %d", joint);
  if (joint < -2) return reason("unhome: %d is not a joint, -1 (all) or -2 (volatile)", joint);
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (joint >= 0 && j != joint) continue;
    Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (joint == -2 && !cfg_.joints[static_cast<std::size_t>(j)].homing.volatile_home) continue;
    if (jt.home_state != HomeState::Idle || !jt.free.done()) return reason("joint %d moves or homes: stop it first", j);
  }
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (joint >= 0 && j != joint) continue;
    if (joint == -2 && !cfg_.joints[static_cast<std::size_t>(j)].homing.volatile_home) continue;
    joints_[static_cast<std::size_t>(j)].homed = false;
  }
  if (mode_ != ipc::MotionMode::Free && !all_homed() && !cfg_.no_force_homing) {
    for (int j = 0; j < cfg_.num_joints; ++j) {
      Joint& jt = joints_[static_cast<std::size_t>(j)];
      jt.free.reset(jt.pos_cmd);
    }
    mode_ = ipc::MotionMode::Free;
  }
  return nullptr;
}

const char* MotionController::cmd_jog(const MotionCommand& c) noexcept {
  if (c.type != Cmd::JogStop) {
    if (!enabled_) return "cannot jog: motion is not enabled (machine off)";
    if (const char* why = amps_not_ready("jog")) return why;
    if (in_.jog_inhibit) return "jogging is inhibited (motion.jog-inhibit is set)";
  }
  return c.axis_mode ? cmd_jog_axis(c) : cmd_jog_joint(c);
}

const char* MotionController::cmd_jog_joint(const MotionCommand& c) noexcept {
  const int j = c.joint;
  if (j < 0 || j >= cfg_.num_joints) return reason("no joint %d", j);
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  if (c.type == Cmd::JogStop) {
    jt.free.stop();
    return nullptr;
  }
  if (mode_ != ipc::MotionMode::Free) return reason("joint jogs need free mode (now %s): jog the axis instead", ipc::to_string(mode_));
  if (!jt.active) return reason("joint %d is not active", j);
  if (jt.home_state != HomeState::Idle) return reason("joint %d is homing", j);
  if (joint_in_sync_group(j) && jt.homed == false) {
    return reason("joint %d belongs to synchronised homing sequence %d (a gantry): home it, then jog the axis", j,
                  cfg_.joints[static_cast<std::size_t>(j)].homing.sequence);
  }
  const JointConfig& cfg = cfg_.joints[static_cast<std::size_t>(j)];
  double vel = std::fabs(c.value[0]);
  double target = 0;
  double dir = 0;
  switch (c.type) {
    case Cmd::JogCont:
      dir = c.value[0] > 0 ? 1 : -1;
      if (c.value[0] == 0) return "continuous jog needs a non-zero velocity";
      target = jt.homed ? (dir > 0 ? cfg.max_limit : cfg.min_limit) : jt.pos_cmd + dir * kFar;
      if (std::fabs(target) > 1e98) target = jt.pos_cmd + dir * kFar;
      break;
    case Cmd::JogIncr: {
      if (c.value[1] == 0) return "incremental jog needs a non-zero distance";
      if (vel == 0) return "incremental jog needs a velocity";
      // Increments accumulate (3.8.20): add to where the jog is going.
      const double base = jt.jogging ? jt.free.target() : jt.pos_cmd;
      target = base + c.value[1];
      dir = c.value[1] > 0 ? 1 : -1;
      break;
    }
    case Cmd::JogAbs:
      if (vel == 0) return "absolute jog needs a velocity";
      target = c.value[1];
      dir = target > jt.pos_cmd ? 1 : -1;
      break;
    default:
      return "not a jog";
  }
  // Never further past a limit switch or a soft limit.
  if (dir > 0 && in_.joints[static_cast<std::size_t>(j)].pos_lim_sw) {
    return reason("joint %d is on its positive limit switch: jogging further in + is refused", j);
  }
  if (dir < 0 && in_.joints[static_cast<std::size_t>(j)].neg_lim_sw) {
    return reason("joint %d is on its negative limit switch: jogging further in - is refused", j);
  }
  if (jt.homed) {
    if (dir > 0 && jt.pos_cmd >= cfg.max_limit) {
      return reason("joint %d is at its maximum soft limit %g: jogging further in + is refused", j, cfg.max_limit);
    }
    if (dir < 0 && jt.pos_cmd <= cfg.min_limit) {
      return reason("joint %d is at its minimum soft limit %g: jogging further in - is refused", j, cfg.min_limit);
    }
    target = std::clamp(target, cfg.min_limit, cfg.max_limit);
  }
  jt.free.set_target(target, joint_limits(j, vel * feed_scale_));
  jt.jogging = true;
  if (override_limits_) jt.jog_override_limits = true;
  return nullptr;
}

const char* MotionController::cmd_jog_axis(const MotionCommand& c) noexcept {
  const int a = c.joint;
  if (a < 0 || a >= kNumAxes || !cfg_.axes[static_cast<std::size_t>(a)].present) return reason("no axis %d", a);
  FreePlanner& p = axis_free_[static_cast<std::size_t>(a)];
  if (c.type == Cmd::JogStop) {
    p.stop();
    return nullptr;
  }
  if (mode_ != ipc::MotionMode::Teleop) return reason("axis jogs need teleop mode (now %s)", ipc::to_string(mode_));
  const AxisConfig& ax = cfg_.axes[static_cast<std::size_t>(a)];
  const double vel = std::fabs(c.value[0]);
  double target = 0, dir = 0;
  switch (c.type) {
    case Cmd::JogCont:
      if (c.value[0] == 0) return "continuous jog needs a non-zero velocity";
      dir = c.value[0] > 0 ? 1 : -1;
      target = dir > 0 ? ax.max_limit : ax.min_limit;
      if (std::fabs(target) > 1e98) target = p.position() + dir * kFar;
      break;
    case Cmd::JogIncr:
      if (c.value[1] == 0 || vel == 0) return "incremental jog needs a velocity and a non-zero distance";
      target = (p.done() ? p.position() : p.target()) + c.value[1];
      dir = c.value[1] > 0 ? 1 : -1;
      break;
    case Cmd::JogAbs:
      if (vel == 0) return "absolute jog needs a velocity";
      target = c.value[1];
      dir = target > p.position() ? 1 : -1;
      break;
    default:
      return "not a jog";
  }
  if (dir > 0 && p.position() >= ax.max_limit) {
    return reason("axis %c is at its maximum limit %g: jogging further in + is refused", kAxisLetters[a], ax.max_limit);
  }
  if (dir < 0 && p.position() <= ax.min_limit) {
    return reason("axis %c is at its minimum limit %g: jogging further in - is refused", kAxisLetters[a], ax.min_limit);
  }
  target = std::clamp(target, ax.min_limit, ax.max_limit);
  FreeLimits l = axis_lim_[static_cast<std::size_t>(a)];
  l.max_velocity = std::min(vel * feed_scale_, l.max_velocity);
  p.set_target(target, l);
  return nullptr;
}

const char* MotionController::cmd_segment(const MotionCommand& c, bool& retry) noexcept {
  if (mode_ != ipc::MotionMode::Coord) return reason("%s needs coord mode (now %s)", to_string(c.type), ipc::to_string(mode_));
  if (!enabled_) return "motion is not enabled (machine off)";
  if (const char* why = amps_not_ready(to_string(c.type))) return why;
  if (c.type != Cmd::SetDwell) {
    for (int a = 0; a < kNumAxes; ++a) {
      const AxisConfig& ax = cfg_.axes[static_cast<std::size_t>(a)];
      if (!ax.present) continue;
      if (c.end[a] > ax.max_limit + 1e-9 || c.end[a] < ax.min_limit - 1e-9) {
        return reason("line %d: %c%.4f is outside the soft limits %g..%g", c.segment.line, kAxisLetters[a], c.end[a],
                      ax.min_limit, ax.max_limit);
      }
    }
  }
  tp::Result r = tp::Result::Ok;
  const bool feed = c.type == Cmd::SetCircle || c.type == Cmd::Probe ||
                    (c.type == Cmd::SetLine && c.segment.type != tp::MotionType::Traverse);
  if (feed && atspeed_next_feed_) {
    // The feed move starts after a stop that waits for the spindles to be
    // at speed (LinuxCNC holds the move's start; rapids do not wait).
    tp::SegmentParams w = c.segment;
    w.type = tp::MotionType::Dwell;
    w.wait_spindle_at_speed = true;
    r = tp_.add_dwell(0, w);
    if (r == tp::Result::QueueFull) {
      retry = true;
      return nullptr;
    }
    if (r != tp::Result::Ok) return reason("line %d: the planner refused the wait for the spindle: %s", c.segment.line, tp_result_text(r));
    atspeed_next_feed_ = false;
  }
  switch (c.type) {
    case Cmd::SetLine:
      r = tp_.add_line(c.end, c.segment);
      break;
    case Cmd::Probe: {
      tp::SegmentParams s = c.segment;
      s.type = tp::MotionType::Probe;
      probe_tripped_ = false;
      r = tp_.add_line(c.end, s);
      break;
    }
    case Cmd::SetCircle:
      r = tp_.add_circle(c.end, c.center, c.normal, c.turns, c.segment);
      break;
    case Cmd::SetDwell:
      r = tp_.add_dwell(c.value[0], c.segment);
      break;
    default:
      break;
  }
  if (r == tp::Result::QueueFull) {
    retry = true;
    return nullptr;
  }
  if (r != tp::Result::Ok) return reason("line %d: the planner refused the segment: %s", c.segment.line, tp_result_text(r));
  last_queued_id_ = c.segment.id;
  return nullptr;
}

}  // namespace cnc::motion
