// matrixkins: squareness and scale correction of X Y Z by a 3x3 matrix C
// (LinuxCNC's matrixkins): joints = C * pose on XYZ, other axes one to one.
// C starts as the identity; a measured machine sets, for example, c-xy to the
// X error per unit of Y travel. Forward kinematics invert C at each call and
// report Singular when C has no inverse. Realtime: no allocation.
#pragma once

#include <array>

#include "kinematics/module.hpp"

namespace cnc::kin {

class MatrixKins final : public KinematicsModule {
 public:
  // `map` must name X, Y and Z.
  explicit MatrixKins(JointMap map) noexcept;

  // Row `row` (0..2 = joint X, Y, Z), column `col` (0..2 = pose X, Y, Z).
  KinParam& c(int row, int col) noexcept { return c_[static_cast<std::size_t>(row * 3 + col)]; }
  // Pins c-xx, c-xy, ... c-zz: row letter, then column letter.
  void bind(HalBinder& binder) override;

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override;
  KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept override;

 private:
  std::array<KinParam, 9> c_;
};

}  // namespace cnc::kin
