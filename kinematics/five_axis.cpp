#include "kinematics/five_axis.hpp"

#include "kinematics/detail/rotation.hpp"

namespace cnc::kin {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr int kC = static_cast<int>(Axis::C);

int tilt_index(TiltAxis t) noexcept { return t == TiltAxis::A ? static_cast<int>(Axis::A) : static_cast<int>(Axis::B); }

Matrix3d tilt_rotation(TiltAxis t, double deg) noexcept {
  return t == TiltAxis::A ? detail::rot_x(deg * detail::kDeg) : detail::rot_y(deg * detail::kDeg);
}

Vector3d xyz(const Pose& p) noexcept { return {p[0], p[1], p[2]}; }
void set_xyz(Pose& p, const Vector3d& v) noexcept {
  p[0] = v[0];
  p[1] = v[1];
  p[2] = v[2];
}

}  // namespace

// Table-table. A workpiece point w sits, in machine coordinates, at
//   m = T (Rc (w - r) - d) + r + d
// r: the C axis point, d: from it to the tilt axis (plus the tool length, see
// below), Rc: C's turn, T: the tilt's turn. The slides carry the gauge point,
// which is the tool tip raised by the tool length along machine Z; the pose
// is the tip raised by the same length along workpiece Z. Adding that length
// to d's Z turns one into the other, so the same formula maps pose to joints.

void TableTableKins::bind(HalBinder& b) {
  KinematicsModule::bind(b);
  b.param("x-rot-point", p_.x_rot_point);
  b.param("y-rot-point", p_.y_rot_point);
  b.param("z-rot-point", p_.z_rot_point);
  b.param("x-offset", p_.x_offset);
  b.param("y-offset", p_.y_offset);
  b.param("z-offset", p_.z_offset);
  b.param("tool-offset", p_.tool_offset);
}

KinResult TableTableKins::inverse_own(const Pose& pose, const double*, double* joints) const noexcept {
  const Vector3d r(p_.x_rot_point.get(), p_.y_rot_point.get(), p_.z_rot_point.get());
  const Vector3d d(p_.x_offset.get(), p_.y_offset.get(), p_.z_offset.get() + p_.tool_offset.get());
  const Vector3d in_c = detail::rot_z(pose[kC] * detail::kDeg) * (xyz(pose) - r);
  Pose jp = pose;
  set_xyz(jp, tilt_rotation(tilt_, pose[tilt_index(tilt_)]) * (in_c - d) + r + d);
  joint_map().pose_to_joints(jp, joints);
  return KinResult::Ok;
}

KinResult TableTableKins::forward_own(const double* joints, Pose& pose) const noexcept {
  joint_map().joints_to_pose(joints, pose);
  const Vector3d r(p_.x_rot_point.get(), p_.y_rot_point.get(), p_.z_rot_point.get());
  const Vector3d d(p_.x_offset.get(), p_.y_offset.get(), p_.z_offset.get() + p_.tool_offset.get());
  const Vector3d in_c = tilt_rotation(tilt_, pose[tilt_index(tilt_)]).transpose() * (xyz(pose) - r - d) + d;
  set_xyz(pose, detail::rot_z(pose[kC] * detail::kDeg).transpose() * in_c + r);
  return KinResult::Ok;
}

// Head-table. The tip in machine coordinates is the workpiece point turned
// by C about the vertical line through r; the head's tilt axis sits
// (pivot + tool) up the tool axis u = H ez from the tip, and the slides read
// the gauge point, pivot-length below the tilt axis along machine Z (so with
// the head upright the joints are the tip raised by the tool length, as on a
// 3-axis mill).

void HeadTableKins::bind(HalBinder& b) {
  KinematicsModule::bind(b);
  b.param("x-rot-point", p_.x_rot_point);
  b.param("y-rot-point", p_.y_rot_point);
  b.param("pivot-length", p_.pivot_length);
  b.param("tool-offset", p_.tool_offset);
}

KinResult HeadTableKins::inverse_own(const Pose& pose, const double*, double* joints) const noexcept {
  const Vector3d r(p_.x_rot_point.get(), p_.y_rot_point.get(), 0.0);
  const double pivot = p_.pivot_length.get();
  const double tool = p_.tool_offset.get();
  const Vector3d tip_w = xyz(pose) - Vector3d(0, 0, tool);
  const Vector3d tip_m = detail::rot_z(pose[kC] * detail::kDeg) * (tip_w - r) + r;
  const Vector3d u = tilt_rotation(head_, pose[tilt_index(head_)]).col(2);
  Pose jp = pose;
  set_xyz(jp, tip_m + (pivot + tool) * u - Vector3d(0, 0, pivot));
  joint_map().pose_to_joints(jp, joints);
  return KinResult::Ok;
}

KinResult HeadTableKins::forward_own(const double* joints, Pose& pose) const noexcept {
  joint_map().joints_to_pose(joints, pose);
  const Vector3d r(p_.x_rot_point.get(), p_.y_rot_point.get(), 0.0);
  const double pivot = p_.pivot_length.get();
  const double tool = p_.tool_offset.get();
  const Vector3d u = tilt_rotation(head_, pose[tilt_index(head_)]).col(2);
  const Vector3d tip_m = xyz(pose) + Vector3d(0, 0, pivot) - (pivot + tool) * u;
  const Vector3d tip_w = detail::rot_z(pose[kC] * detail::kDeg).transpose() * (tip_m - r) + r;
  set_xyz(pose, tip_w + Vector3d(0, 0, tool));
  return KinResult::Ok;
}

}  // namespace cnc::kin
