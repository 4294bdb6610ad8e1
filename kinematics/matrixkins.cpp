#include "kinematics/matrixkins.hpp"

#include <cmath>

#include "kinematics/detail/rotation.hpp"

namespace cnc::kin {
namespace {

Eigen::Matrix3d load(const std::array<KinParam, 9>& c) noexcept {
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) m(i, j) = c[static_cast<std::size_t>(i * 3 + j)].get();
  }
  return m;
}

}  // namespace

MatrixKins::MatrixKins(JointMap map) noexcept
    : KinematicsModule("matrixkins", map, KinematicsType::Both, /*coupled=*/true, /*switchable=*/false) {
  for (int i = 0; i < 3; ++i) c(i, i).set(1.0);
}

void MatrixKins::bind(HalBinder& binder) {
  KinematicsModule::bind(binder);
  static constexpr const char* kXyz = "xyz";
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) binder.param(std::string("c-") + kXyz[i] + kXyz[j], c(i, j));
  }
}

KinResult MatrixKins::forward_own(const double* joints, Pose& pose) const noexcept {
  joint_map().joints_to_pose(joints, pose);
  const Eigen::Matrix3d m = load(c_);
  const double det = m.determinant();
  // A correction matrix is close to the identity; |det| this small means a
  // configuration error, and its inverse would amplify noise without bound.
  if (!(std::abs(det) > 1e-9)) return KinResult::Singular;
  const Eigen::Vector3d p = m.inverse() * Eigen::Vector3d(pose[0], pose[1], pose[2]);
  for (int i = 0; i < 3; ++i) pose[i] = p[i];
  return KinResult::Ok;
}

KinResult MatrixKins::inverse_own(const Pose& pose, const double*, double* joints) const noexcept {
  const Eigen::Matrix3d m = load(c_);
  if (!(std::abs(m.determinant()) > 1e-9)) return KinResult::Singular;
  const Eigen::Vector3d q = m * Eigen::Vector3d(pose[0], pose[1], pose[2]);
  Pose jp = pose;
  for (int i = 0; i < 3; ++i) jp[i] = q[i];
  joint_map().pose_to_joints(jp, joints);
  return KinResult::Ok;
}

}  // namespace cnc::kin
