// The motion controller: construction, the planner configuration, the
// parameters in force (SET_xxx) and the message helpers; its commands,
// cycle and status are in motion_commands.cpp, motion_cycle.cpp and
// motion_status.cpp (motion_internal.hpp: what they share).
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

tp::PlannerConfig planner_config(const MotionConfig& c, uint32_t axis_mask) {
  tp::PlannerConfig p;
  p.cycle_time_s = c.servo_period_s;
  // No [TRAJ] key (1e99 here) is the planner's 0, "no limit": passing 1e99
  // made it take max_linear_acceleration / max_linear_jerk = 1 s as its
  // smoothing time when both were missing.
  const auto limit = [](double v) { return v < 1e98 ? v : 0.0; };
  p.max_linear_velocity = limit(c.max_linear_velocity);
  p.max_linear_acceleration = limit(c.max_linear_acceleration);
  p.max_linear_jerk = limit(c.max_linear_jerk);
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

}  // namespace cnc::motion
