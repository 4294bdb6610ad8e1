#include "core/motion/motion_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

#include "core/ipc/estop.hpp"
#include "core/motion/params.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"

namespace cnc::motion {
namespace {

constexpr double kFar = 1e9;  // a continuous jog's target when there is no soft limit

const char* tp_result_text(tp::Result r) noexcept {
  switch (r) {
    case tp::Result::Ok: return "ok";
    case tp::Result::QueueFull: return "queue full";
    case tp::Result::InvalidSegment: return "invalid segment";
    case tp::Result::NotAllowed: return "not allowed";
  }
  return "?";
}

bool usable_forward(const kin::Kinematics& k) noexcept { return k.type() != kin::KinematicsType::InverseOnly; }

}  // namespace

tp::PlannerConfig planner_config(const MotionConfig& c, uint32_t axis_mask) {
  tp::PlannerConfig p;
  p.cycle_time_s = c.servo_period_s;
  p.max_linear_velocity = c.max_linear_velocity;
  p.max_linear_acceleration = c.max_linear_acceleration;
  p.max_linear_jerk = c.max_linear_jerk;
  p.axis_mask = axis_mask;
  p.lookahead_segments = c.lookahead_segments;
  p.blend_span_segments = c.blend_span_segments;
  p.max_blend_half_width = c.max_blend_half_width;
  for (int a = 0; a < kNumAxes; ++a) {
    const AxisConfig& ax = c.axes[static_cast<std::size_t>(a)];
    p.axes[static_cast<std::size_t>(a)] = tp::AxisLimits{ax.max_velocity, ax.max_acceleration, ax.max_jerk};
  }
  return p;
}

double limit_spindle_speed(double rpm, const SpindleConfig& l) noexcept {
  if (rpm > 0) return std::clamp(rpm, std::min(l.min_forward, l.max_forward), l.max_forward);
  if (rpm < 0) {
    if (l.max_reverse <= 0) return 0;  // reverse forbidden
    return -std::clamp(-rpm, std::min(l.min_reverse, l.max_reverse), l.max_reverse);
  }
  return 0;
}

const char* to_string(HomeState s) noexcept {
  switch (s) {
    case HomeState::Idle: return "idle";
    case HomeState::Start: return "start";
    case HomeState::UnlockWait: return "unlock";
    case HomeState::InitialBackoff: return "initial-backoff";
    case HomeState::InitialSearch: return "search";
    case HomeState::FinalBackoff: return "backoff";
    case HomeState::RiseSearch: return "latch-rise";
    case HomeState::FallSearch: return "latch-fall";
    case HomeState::IndexSearch: return "index";
    case HomeState::StopAfterLatch: return "stop-after-latch";
    case HomeState::WaitGroup: return "wait-group";
    case HomeState::FinalMove: return "final-move";
    case HomeState::LockWait: return "lock";
    case HomeState::DriveHoming: return "drive-homing";
    case HomeState::Finished: return "finished";
  }
  return "?";
}

MotionController::MotionController(const MotionConfig& config, kin::Kinematics& kinematics,
                                   tp::TrajectoryPlanner& planner, MessageQueue* messages)
    : cfg_(config), ini_cfg_(config), kins_(kinematics), tp_(planner), messages_(messages) {
  dt_ = cfg_.servo_period_s;
  for (int j = 0; j < kMaxJoints; ++j) joints_[static_cast<std::size_t>(j)].active = j < cfg_.num_joints;
  double q[kMaxJoints] = {};
  if (usable_forward(kins_) && kins_.forward(q, carte_cmd_) != kin::KinResult::Ok) carte_cmd_ = Pose{};
  for (int a = 0; a < kNumAxes; ++a) axis_free_[static_cast<std::size_t>(a)].reset(carte_cmd_[a]);
  tp_.reset(carte_cmd_);
  for (int j = 0; j < cfg_.num_joints; ++j) {
    const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
    if (h.has_sequence) max_sequence_ = std::max(max_sequence_, std::abs(h.sequence));
  }
  apply_limits();
}

void MotionController::set_compensation(int joint, JointCompensation* comp) noexcept {
  comp_[static_cast<std::size_t>(joint)] = comp;
  apply_limits();  // the joint's share kept for the correction (COMP_RESERVE)
}

bool MotionController::at_rest() const noexcept {
  if (!in_position() || !tp_.is_done()) return false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    const Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (jt.home_state != HomeState::Idle || !jt.free.done()) return false;
  }
  for (const FreePlanner& p : axis_free_) {
    if (!p.done()) return false;
  }
  return true;
}

void MotionController::apply_limits() noexcept {
  for (int a = 0; a < kNumAxes; ++a) {
    const AxisConfig& ax = cfg_.axes[static_cast<std::size_t>(a)];
    FreeLimits l{ax.max_velocity, ax.max_acceleration, ax.max_jerk};
    // A joint that moves this axis alone (trivkins, each side of a gantry)
    // limits it too; joints coupled by the kinematics cannot be mapped.
    for (int j = 0; j < cfg_.num_joints; ++j) {
      if (kins_.joint_axis(j) != a) continue;
      const FreeLimits jl = joint_limits(j, 1e300);
      l.max_velocity = std::min(l.max_velocity, jl.max_velocity);
      l.max_acceleration = std::min(l.max_acceleration, jl.max_acceleration);
      l.max_jerk = std::min(l.max_jerk, jl.max_jerk);
    }
    axis_lim_[static_cast<std::size_t>(a)] = l;
  }
  tp::PlannerConfig p = planner_config(cfg_, kins_.axis_mask());
  for (int a = 0; a < kNumAxes; ++a) {
    const FreeLimits& l = axis_lim_[static_cast<std::size_t>(a)];
    p.axes[static_cast<std::size_t>(a)] = tp::AxisLimits{l.max_velocity, l.max_acceleration, l.max_jerk};
  }
  tp_.set_config(p);
}

const char* MotionController::cmd_set_parameter(const MotionCommand& c) noexcept {
  std::size_t n = 0;
  const ParamSpec* table = param_table(n);
  if (c.param >= n) return reason("no parameter number %u", c.param);
  const ParamSpec& p = table[c.param];
  if (p.while_stopped_only && !at_rest()) {
    return reason("%s cannot change while the machine moves (jogs, homing and queued moves keep the limits they were "
                  "planned with): stop it first",
                  p.name);
  }
  double ini_value = std::nan("");
  if (const char* r = set_param(cfg_, ini_cfg_, c.param, c.joint, c.value[0], &ini_value)) {
    if (std::isnan(ini_value)) return reason("%s: %s", p.name, r);
    char key[48];
    param_ini_name(c.param, c.joint, key, sizeof key);
    return reason("%s: %g is %s %s = %g, the machine's limit (run-time changes may only be stricter)", p.name,
                  c.value[0], p.bound == IniBound::AtMost ? "above" : "below", key, ini_value);
  }
  apply_limits();
  return nullptr;
}

// Reasons that carry numbers are formatted into a member buffer: the servo
// thread is its only writer, and the answer is copied before the next command.
const char* MotionController::reason(const char* fmt, ...) noexcept {
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(reason_.data, sizeof reason_.data, fmt, ap);
  va_end(ap);
  return reason_.c_str();
}

void MotionController::post_error(const char* fmt, ...) noexcept {
  if (!messages_) return;
  char buf[256];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  messages_->post(MessageKind::Error, "motion", buf);
}

void MotionController::post_text(const char* fmt, ...) noexcept {
  if (!messages_) return;
  char buf[256];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  messages_->post(MessageKind::Text, "motion", buf);
}

bool MotionController::all_homed() const noexcept {
  for (int j = 0; j < cfg_.num_joints; ++j) {
    const Joint& jt = joints_[static_cast<std::size_t>(j)];
    if (jt.active && !jt.homed) return false;
  }
  return true;
}

bool MotionController::in_position() const noexcept {
  switch (mode_) {
    case ipc::MotionMode::Free:
      for (int j = 0; j < cfg_.num_joints; ++j) {
        const Joint& jt = joints_[static_cast<std::size_t>(j)];
        if (!jt.free.done() || jt.home_state != HomeState::Idle) return false;
      }
      return true;
    case ipc::MotionMode::Teleop:
      for (const FreePlanner& p : axis_free_) {
        if (!p.done()) return false;
      }
      return true;
    case ipc::MotionMode::Coord:
      return tp_.is_done();
  }
  return true;
}

bool MotionController::joint_in_sync_group(int j) const noexcept {
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
  return h.has_sequence && h.sequence < 0;
}

FreeLimits MotionController::joint_limits(int j, double vel) const noexcept {
  const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
  const bool reserve = c.backlash > 0 || comp_[static_cast<std::size_t>(j)] != nullptr;
  const double k = reserve ? 1 - cfg_.comp_reserve : 1.0;
  FreeLimits l;
  l.max_velocity = std::min(std::fabs(vel), c.max_velocity * k);
  l.max_acceleration = c.max_acceleration * k;
  l.max_jerk = c.max_jerk * k;
  return l;
}

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
    probed_pos_ = tp_out_.probed_position;
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

void MotionController::fill_status(MotionStatus& s) const noexcept {
  ipc::TrajStatus& t = s.traj;
  t.mode = mode_;
  t.enabled = enabled_;
  t.inpos = out_.in_position;
  t.paused = tp_.is_paused();
  t.queue = tp_.queue_depth();
  t.queue_full = tp_.is_queue_full();
  t.probing = false;
  t.probe_tripped = probe_tripped_;
  t.probe_input = in_.probe_input;
  t.probed_position = probed_pos_;
  t.carte_fb_valid = carte_fb_valid_;
  t.watchdog_enabled = enabled_;
  t.estop_latched = estop_latched_;
  t.estop_cause = estop_cause_;
  t.estop_pid = estop_pid_;
  t.feed_override_enabled = feed_override_enabled_;
  t.adaptive_feed_enabled = adaptive_enabled_;
  t.feed_hold_enabled = feed_hold_enabled_;
  t.teleop_enabled = mode_ == ipc::MotionMode::Teleop;
  t.motion_line = tp_out_.line;
  t.motion_id = tp_out_.id;
  uint32_t mask = kins_.axis_mask();
  t.axis_mask = mask;
  t.joints = cfg_.num_joints;
  t.spindles = cfg_.spindles;
  t.kinematics_type = static_cast<uint8_t>(kins_.type());
  t.position = carte_cmd_;
  t.actual_position = carte_fb_valid_ ? carte_fb_ : Pose{};
  for (int a = 0; a < kNumAxes; ++a) {
    t.dtg[a] = axis_dtg(a);
  }
  t.current_vel = out_.current_vel;
  t.distance_to_go = out_.distance_to_go;
  t.feed_scale = feed_scale_;
  t.rapid_scale = rapid_scale_;
  t.max_velocity = max_velocity_;
  t.max_linear_velocity = cfg_.max_linear_velocity;
  t.max_linear_acceleration = cfg_.max_linear_acceleration;
  t.max_linear_jerk = cfg_.max_linear_jerk;
  t.linear_units = cfg_.linear_units_per_mm;
  t.angular_units = cfg_.angular_units_per_degree;
  t.cycle_time_s = dt_;
  t.servo_cycles = cycles_;
  t.spindle_wait = spindle_wait_;
  t.spindle_wait_s = spindle_wait_s_;
  for (int j = 0; j < kMaxJoints; ++j) {
    ipc::JointStatus& js = s.joints[j];
    if (j >= cfg_.num_joints) {
      js = ipc::JointStatus{};
      continue;
    }
    const Joint& jt = joints_[static_cast<std::size_t>(j)];
    const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
    js.type = static_cast<uint8_t>(c.type);
    js.active = jt.active;
    js.enabled = jt.amp_enabled && enabled_;
    js.homing = jt.home_state != HomeState::Idle;
    js.homed = jt.homed;
    js.fault = jt.amp_fault || jt.ferror_fault;
    js.inpos = out_.joints[static_cast<std::size_t>(j)].in_position;
    js.min_soft_limit = jt.soft_min;
    js.max_soft_limit = jt.soft_max;
    js.min_hard_limit = jt.on_neg_limit;
    js.max_hard_limit = jt.on_pos_limit;
    js.override_limits = override_limits_ || jt.jog_override_limits;
    js.axis = static_cast<int8_t>(kins_.joint_axis(j));
    js.pos_cmd = jt.pos_cmd;
    js.pos_fb = jt.pos_fb;
    js.motor_pos_cmd = out_.joints[static_cast<std::size_t>(j)].motor_pos_cmd;
    js.motor_pos_fb = in_.joints[static_cast<std::size_t>(j)].motor_pos_fb;
    js.velocity = jt.vel_cmd;
    js.ferror_current = jt.ferror;
    js.ferror_highmark = jt.ferror_high;
    js.ferror_limit = jt.ferror_limit;
    js.min_position_limit = c.min_limit;
    js.max_position_limit = c.max_limit;
    js.max_velocity = c.max_velocity;
    js.max_acceleration = c.max_acceleration;
    js.max_jerk = c.max_jerk;
    js.velocity_limit = joint_limits(j, 1e300).max_velocity;
    js.ferror = c.ferror;
    js.min_ferror = c.min_ferror;
    js.backlash = c.backlash;
    js.home_offset = c.homing.offset;
    js.compensation = jt.backlash_filt + jt.screw_comp;
  }
  for (int a = 0; a < kNumAxes; ++a) {
    const AxisConfig& ax = cfg_.axes[static_cast<std::size_t>(a)];
    s.axes[a].min_position_limit = ax.min_limit;
    s.axes[a].max_position_limit = ax.max_limit;
    s.axes[a].max_velocity = ax.max_velocity;
    s.axes[a].max_acceleration = ax.max_acceleration;
    s.axes[a].max_jerk = ax.max_jerk;
    s.axes[a].velocity_limit = axis_lim_[static_cast<std::size_t>(a)].max_velocity;
    s.axes[a].acceleration_limit = axis_lim_[static_cast<std::size_t>(a)].max_acceleration;
    s.axes[a].velocity = axis_free_[static_cast<std::size_t>(a)].velocity();
  }
  for (int i = 0; i < ipc::kMaxSpindles; ++i) {
    const Spindle& sp = spindles_[static_cast<std::size_t>(i)];
    ipc::SpindleStatus& ss = s.spindles[i];
    ss.speed = sp.speed;
    ss.override_scale = sp.override_scale;
    const SpindleConfig& lim = cfg_.spindle[static_cast<std::size_t>(i)];
    ss.speed_out = out_.spindles[static_cast<std::size_t>(i)].speed_out;
    const double requested = sp.on && enabled_ ? sp.speed * sp.override_scale : 0;
    ss.speed_limited = std::fabs(requested - ss.speed_out) > 1e-9 * std::max(1.0, std::fabs(requested));
    ss.max_forward = lim.max_forward;
    ss.min_forward = lim.min_forward;
    ss.max_reverse = lim.max_reverse;
    ss.min_reverse = lim.min_reverse;
    ss.direction = sp.on ? (sp.speed > 0 ? 1 : -1) : 0;
    ss.enabled = sp.on && enabled_;
    ss.brake = out_.spindles[static_cast<std::size_t>(i)].brake;
    ss.at_speed = in_.spindles[static_cast<std::size_t>(i)].at_speed;
    ss.speed_feedback = in_.spindles[static_cast<std::size_t>(i)].speed_in * 60;
    ss.orient_state = sp.orient ? (in_.spindles[static_cast<std::size_t>(i)].is_oriented ? 2 : 1) : 0;
    ss.orient_fault = in_.spindles[static_cast<std::size_t>(i)].orient_fault;
    ss.amp_fault = spindle_fault_[static_cast<std::size_t>(i)];
  }
  s.cycles = cycles_;
  s.last_serial = last_serial_;
  s.all_homed = all_homed();
  bool homing = false, jogging = false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    homing = homing || joints_[static_cast<std::size_t>(j)].home_state != HomeState::Idle;
    jogging = jogging || joints_[static_cast<std::size_t>(j)].jogging;
  }
  s.any_homing = homing;
  s.jogging = jogging;
  s.tp_done = tp_.is_done();
  s.faulted = faulted_;
  s.amps_ready = enabled_ && amps_ready_;
  s.amp_waiting_joint = enabled_ && !amps_ready_ ? amp_waiting_joint_ : -1;
  s.homing_sequence_active = home_sequence_;
  s.fault_reason = fault_reason_;
  s.fault_joint = fault_joint_;
  s.fault_spindle = fault_spindle_;
  s.overrun_hold = overrun_hold_;
  s.overrun_holds = overrun_holds_;
  s.spindle_timeouts = spindle_timeouts_;
  s.spindle_timeout_reason = spindle_timeout_reason_;
}

}  // namespace cnc::motion
