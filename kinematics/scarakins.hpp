// scarakins: a SCARA arm (LinuxCNC's scarakins, same joints and dimensions).
// Joints: 0 inner arm about the base's vertical axis, 1 outer arm about the
// elbow (0 = arms in line), 2 the quill (length, positive down), 3 the tool
// about the quill, in degrees; 4 and 5 pass through to A and B. Pose: X Y Z of
// the tool tip, C = joints 0 + 1 + 3. Inverse keeps the hint's elbow side
// (sign of joint 1); the pose on the base axis (inner and outer arms of equal
// length) is Singular, beyond the arm's reach Unreachable. Switchable: type 1
// is identity. Realtime: no allocation.
#pragma once

#include "kinematics/module.hpp"

namespace cnc::kin {

class ScaraKins final : public KinematicsModule {
 public:
  // Pins d1 ... d6, LinuxCNC's D1 ... D6 and their defaults (mm):
  //   d1 490: base plane to the inner arm; d2 340: inner arm length;
  //   d3 50: inner arm to outer arm (vertical); d4 250: outer arm length;
  //   d5 50: end effector down to the tool tip; d6 50: tool tip off the
  //   quill axis (horizontal).
  struct Params {
    KinParam d1{490}, d2{340}, d3{50}, d4{250}, d5{50}, d6{50};
  };
  ScaraKins() noexcept;

  Params& params() noexcept { return p_; }
  void bind(HalBinder& binder) override;

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override;
  KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept override;

 private:
  Params p_;
};

}  // namespace cnc::kin
