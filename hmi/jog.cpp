#include "hmi/jog.hpp"

#include <algorithm>
#include <cmath>

#include "core/ipc/operator_commands.hpp"

namespace cnc::hmi {

JogController::JogController(Sink sink) : sink_(std::move(sink)) { std::fill(std::begin(joint_of_axis_), std::end(joint_of_axis_), -1); }

void JogController::set_axes(std::vector<AxisInfo> axes) {
  stop_all();
  axes_ = std::move(axes);
  for (const auto& a : axes_) {
    if (a.axis >= 0 && a.axis < kNumAxes) joint_of_axis_[a.axis] = a.joint;
  }
}

void JogController::set_increments(std::vector<Increment> linear, std::vector<Increment> angular) {
  stop_all();
  if (linear.empty()) linear.push_back(Increment{true, 0, "continuous"});
  if (angular.empty()) angular.push_back(Increment{true, 0, "continuous"});
  linear_increments_ = std::move(linear);
  angular_increments_ = std::move(angular);
  linear_index_ = angular_index_ = 0;
}

void JogController::select_increment(int index) {
  if (index < 0 || index >= static_cast<int>(linear_increments_.size())) return;
  if (index != linear_index_) stop_all();
  linear_index_ = index;
}

void JogController::select_angular_increment(int index) {
  if (index < 0 || index >= static_cast<int>(angular_increments_.size())) return;
  if (index != angular_index_) stop_all();
  angular_index_ = index;
}

const JogController::AxisInfo* JogController::info(int axis) const {
  for (const auto& a : axes_) {
    if (a.axis == axis) return &a;
  }
  return nullptr;
}

const Increment& JogController::increment_for(int axis) const {
  const AxisInfo* a = info(axis);
  if (a && a->angular) return angular_increments_[static_cast<std::size_t>(angular_index_)];
  return linear_increments_[static_cast<std::size_t>(linear_index_)];
}

void JogController::set_connected(bool connected) {
  if (connected_ && !connected) active_.clear();  // the controller is gone: nothing to stop
  connected_ = connected;
  if (!connected) have_status_ = false;
}

void JogController::update(const ipc::Status& s) {
  bool homed = s.motion.joints > 0;
  for (int j = 0; j < std::min(s.motion.joints, static_cast<int32_t>(kMaxJoints)); ++j) {
    homed = homed && s.joints[j].homed;
  }
  // The status knows which joint moves which axis (trivial kinematics).
  for (int a = 0; a < kNumAxes; ++a) {
    int joint = -1, count = 0;
    for (int j = 0; j < std::min(s.motion.joints, static_cast<int32_t>(kMaxJoints)); ++j) {
      if (s.joints[j].axis == a) {
        joint = j;
        ++count;
      }
    }
    if (count == 1) joint_of_axis_[a] = joint;
    else if (count > 1) joint_of_axis_[a] = -1;
  }
  const bool changed = have_status_ && (s.task.state != state_ || s.task.mode != mode_ || s.task.interp_state != interp_ ||
                                        homed != all_homed_);
  state_ = s.task.state;
  mode_ = s.task.mode;
  interp_ = s.task.interp_state;
  all_homed_ = homed;
  have_status_ = true;
  connected_ = true;
  if (changed) {
    stop_all();
    return;
  }
  // Increments end by themselves: forget them once motion is at rest again.
  bool at_rest = s.motion.inpos;
  for (int j = 0; j < std::min(s.motion.joints, static_cast<int32_t>(kMaxJoints)); ++j) {
    at_rest = at_rest && std::fabs(s.joints[j].velocity) < 1e-9;
  }
  motion_at_rest_ = at_rest;
  for (auto it = active_.begin(); it != active_.end();) {
    if (!it->continuous && ++it->updates_seen >= 2 && at_rest) it = active_.erase(it);
    else ++it;
  }
}

bool JogController::can_jog() const {
  if (!connected_ || !have_status_) {
    why_not_ = "no controller";
    return false;
  }
  if (state_ != ipc::TaskState::On) {
    why_not_ = "the machine is not on";
    return false;
  }
  if (mode_ != ipc::TaskMode::Manual) {
    why_not_ = "jogging needs MANUAL mode";
    return false;
  }
  if (interp_ != ipc::InterpState::Idle) {
    why_not_ = "a program or MDI is running";
    return false;
  }
  why_not_.clear();
  return true;
}

bool JogController::is_jogging(int axis) const {
  return std::any_of(active_.begin(), active_.end(), [axis](const Active& a) { return a.axis == axis; });
}

bool JogController::press(int axis, int direction, Source source) {
  if (source == Source::Key && text_focus_) return false;
  const AxisInfo* ai = info(axis);
  if (!ai) {
    why_not_ = "no such axis";
    return false;
  }
  if (!can_jog()) return false;
  for (const auto& a : active_) {
    if (a.axis == axis && a.continuous) return false;  // already moving (key and button together)
  }
  const bool joint_mode = !all_homed_;
  int target = axis;
  if (joint_mode) {
    target = joint_of_axis_[axis];
    if (target < 0) {
      why_not_ = std::string("axis ") + kAxisLetters[axis] + " moves several joints: home the machine first, or jog joints";
      return false;
    }
  }
  const Increment& inc = increment_for(axis);
  const double velocity = ai->angular ? angular_velocity_ : linear_velocity_;
  if (velocity <= 0) {
    why_not_ = "jog speed is zero";
    return false;
  }
  const int dir = direction < 0 ? -1 : 1;
  const ipc::Command c = inc.continuous ? ipc::commands::jog_continuous(target, joint_mode, dir * velocity)
                                        : ipc::commands::jog_increment(target, joint_mode, dir * velocity, inc.distance);
  // A new increment on an axis replaces the record of the previous one.
  active_.erase(std::remove_if(active_.begin(), active_.end(), [axis](const Active& a) { return a.axis == axis; }),
                active_.end());
  active_.push_back(Active{axis, target, joint_mode, inc.continuous, source, 0});
  sink_(c);
  return true;
}

ipc::Command JogController::stop_command(const Active& a) const {
  return ipc::commands::jog_stop(a.target, a.joint_mode);
}

void JogController::release(int axis, Source source) {
  for (auto it = active_.begin(); it != active_.end(); ++it) {
    if (it->axis != axis || !it->continuous || it->source != source) continue;
    const ipc::Command c = stop_command(*it);
    active_.erase(it);
    sink_(c);
    return;
  }
}

void JogController::stop_all() {
  if (active_.empty()) return;
  const auto jogs = std::move(active_);
  active_.clear();
  for (const auto& a : jogs) sink_(stop_command(a));
}

void JogController::set_text_input_focus(bool focused) {
  if (focused && !text_focus_) {
    // Keys already held would never see their release: stop keyboard jogs.
    std::vector<Active> keep;
    for (const auto& a : active_) {
      if (a.source == Source::Key) sink_(stop_command(a));
      else keep.push_back(a);
    }
    active_ = std::move(keep);
  }
  text_focus_ = focused;
}

}  // namespace cnc::hmi
