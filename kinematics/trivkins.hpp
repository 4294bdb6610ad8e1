// trivkins: each joint moves one axis, named by `coordinates=` (LinuxCNC's
// generalized trivial kinematics). A letter given twice makes a gantry: both
// joints follow the axis; forward kinematics read the first of them.
// Realtime forward/inverse: copies only.
#pragma once

#include <string>
#include <string_view>

#include "kinematics/module.hpp"

namespace cnc::kin {

// `kinstype=`: 1 (identity, the default), B (both), F (forward only),
// I (inverse only), first letter, any case, as LinuxCNC's trivkins.
// Throws hal::HalError naming `who` for anything else.
KinematicsType parse_kinstype(std::string_view text, const std::string& who);

class TrivKins final : public KinematicsModule {
 public:
  TrivKins(JointMap map, KinematicsType type) noexcept
      : KinematicsModule("trivkins", map, type, /*coupled=*/false, /*switchable=*/false) {}

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override {
    joint_map().joints_to_pose(joints, pose);
    return KinResult::Ok;
  }
  KinResult inverse_own(const Pose& pose, const double*, double* joints) const noexcept override {
    joint_map().pose_to_joints(pose, joints);
    return KinResult::Ok;
  }
};

}  // namespace cnc::kin
