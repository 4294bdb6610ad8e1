#include "kinematics/module.hpp"

#include <algorithm>
#include <cmath>

#include "core/hal/hal.hpp"
#include "core/hal/types.hpp"

namespace cnc::kin {

const char* to_string(KinResult r) noexcept {
  switch (r) {
    case KinResult::Ok: return "ok";
    case KinResult::Unreachable: return "pose out of reach";
    case KinResult::Singular: return "singular pose (joint velocities unbounded)";
    case KinResult::JointLimit: return "solution outside the joint limits";
    case KinResult::NotConverged: return "iterative inverse did not converge";
  }
  return "unknown kinematics result";
}

JointMap JointMap::parse(std::string_view coordinates, const std::string& who, bool allow_duplicates,
                         std::string_view required) {
  const std::string given(coordinates);
  if (coordinates.empty()) throw hal::HalError(who + ": coordinates= is empty; expected letters from XYZABCUVW");
  if (coordinates.size() > static_cast<std::size_t>(kMaxJoints)) {
    throw hal::HalError(who + ": coordinates=" + given + " names " + std::to_string(coordinates.size()) +
                        " joints, at most " + std::to_string(kMaxJoints) + " are supported");
  }
  JointMap m;
  for (char c : coordinates) {
    const int a = axis_index(c);
    if (a < 0) {
      throw hal::HalError(who + ": coordinates=" + given + ": '" + std::string(1, c) +
                          "' is not an axis letter; expected letters from XYZABCUVW");
    }
    if (m.first_[static_cast<std::size_t>(a)] >= 0 && !allow_duplicates) {
      throw hal::HalError(who + ": coordinates=" + given + ": " + std::string(1, kAxisLetters[a]) +
                          " appears twice; this module gives each axis one joint");
    }
    if (m.first_[static_cast<std::size_t>(a)] < 0) m.first_[static_cast<std::size_t>(a)] = static_cast<int8_t>(m.n_);
    m.axis_[static_cast<std::size_t>(m.n_++)] = static_cast<int8_t>(a);
  }
  for (char c : required) {
    if (!m.has_axis(axis_index(c))) {
      throw hal::HalError(who + ": coordinates=" + given + " lacks " + std::string(1, c) + "; this module needs " +
                          std::string(required));
    }
  }
  return m;
}

JointMap JointMap::identity(std::string_view letters) { return parse(letters, "JointMap", false); }

uint32_t JointMap::axis_mask() const noexcept {
  uint32_t mask = 0;
  for (int a = 0; a < kNumAxes; ++a) {
    if (has_axis(a)) mask |= 1u << a;
  }
  return mask;
}

std::string JointMap::letters() const {
  std::string s;
  for (int j = 0; j < n_; ++j) s += kAxisLetters[axis_of(j)];
  return s;
}

void JointMap::pose_to_joints(const Pose& pose, double* joints) const noexcept {
  for (int j = 0; j < n_; ++j) joints[j] = pose[axis_[static_cast<std::size_t>(j)]];
}

void JointMap::joints_to_pose(const double* joints, Pose& pose) const noexcept {
  for (int a = 0; a < kNumAxes; ++a) {
    const int j = first_[static_cast<std::size_t>(a)];
    pose[a] = j >= 0 ? joints[j] : 0.0;
  }
}

KinResult KinematicsModule::forward(const double* joints, Pose& pose) const noexcept {
  Pose out;
  KinResult r = KinResult::Ok;
  if (active_switch() == 1) map_.joints_to_pose(joints, out);
  else r = forward_own(joints, out);
  if (r == KinResult::Ok) pose = out;
  return r;
}

KinResult KinematicsModule::inverse(const Pose& pose, const double* hint, double* joints) const noexcept {
  // A NaN or infinite coordinate is no place the machine can go.
  for (int a = 0; a < kNumAxes; ++a) {
    if (!std::isfinite(pose[a])) {
      if (hint != nullptr) std::copy(hint, hint + map_.num_joints(), joints);
      return KinResult::Unreachable;
    }
  }
  if (active_switch() == 1) {
    map_.pose_to_joints(pose, joints);
    return KinResult::Ok;
  }
  const KinResult r = inverse_own(pose, hint, joints);
  if (r != KinResult::Ok && hint != nullptr) std::copy(hint, hint + map_.num_joints(), joints);
  return r;
}

bool KinematicsModule::switch_to(int kins_type) noexcept {
  if (kins_type != 0 && !(switchable_ && kins_type == 1)) return false;
  active_.store(kins_type, std::memory_order_relaxed);
  for (int t = 0; t < 2; ++t) {
    if (is_type_[t].valid()) is_type_[t].set(t == kins_type);
  }
  return true;
}

KinematicsComponent* find_kinematics(hal::Hal& hal) {
  for (hal::Component* c : hal.components()) {
    if (auto* k = dynamic_cast<KinematicsComponent*>(c)) return k;
  }
  return nullptr;
}

void KinematicsModule::bind(HalBinder& binder) {
  if (!switchable_) return;
  for (int t = 0; t < 2; ++t) is_type_[t] = binder.out_bit("kinstype.is-" + std::to_string(t), active_switch() == t);
}

}  // namespace cnc::kin
