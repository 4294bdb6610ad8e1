// The motion controller's status: what each servo cycle publishes.
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
  t.probe_latch_pending = probe_tripped_ && probe_latch_pending_;
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
  s.tag = tp_out_.tag;
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
