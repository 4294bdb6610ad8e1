// Eigen helpers the module sources share: degrees, elementary rotations,
// the roll-pitch-yaw angles of pose A B C. Private to kinematics/*.cpp (keeps
// Eigen out of public headers). Fixed-size types only: nothing allocates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace cnc::kin::detail {

inline constexpr double kDeg = std::numbers::pi / 180.0;

inline Eigen::Matrix3d rot_x(double rad) noexcept {
  const double c = std::cos(rad), s = std::sin(rad);
  Eigen::Matrix3d m;
  m << 1, 0, 0, 0, c, -s, 0, s, c;
  return m;
}

inline Eigen::Matrix3d rot_y(double rad) noexcept {
  const double c = std::cos(rad), s = std::sin(rad);
  Eigen::Matrix3d m;
  m << c, 0, s, 0, 1, 0, -s, 0, c;
  return m;
}

inline Eigen::Matrix3d rot_z(double rad) noexcept {
  const double c = std::cos(rad), s = std::sin(rad);
  Eigen::Matrix3d m;
  m << c, -s, 0, s, c, 0, 0, 0, 1;
  return m;
}

// Pose A B C (degrees) as LinuxCNC's serial-arm modules read them: roll A
// about X, pitch B about Y, yaw C about Z, fixed axes: R = Rz(C) Ry(B) Rx(A).
inline Eigen::Matrix3d rpy_to_matrix(double a_deg, double b_deg, double c_deg) noexcept {
  return rot_z(c_deg * kDeg) * rot_y(b_deg * kDeg) * rot_x(a_deg * kDeg);
}

// The inverse of rpy_to_matrix, angles in (-180, 180] and B in [-90, 90].
// At B = +-90 (gimbal lock) only A -+ C is defined: A is then 0.
inline void matrix_to_rpy(const Eigen::Matrix3d& r, double& a_deg, double& b_deg, double& c_deg) noexcept {
  const double cb = std::hypot(r(0, 0), r(1, 0));
  b_deg = std::atan2(-r(2, 0), cb) / kDeg;
  if (cb > 1e-12) {
    a_deg = std::atan2(r(2, 1), r(2, 2)) / kDeg;
    c_deg = std::atan2(r(1, 0), r(0, 0)) / kDeg;
  } else {
    a_deg = 0.0;
    c_deg = std::atan2(-r(0, 1), r(1, 1)) / kDeg;
  }
}

// The multiple of 360 degrees that brings `deg` closest to `near`.
inline double unwrap_deg(double deg, double near) noexcept {
  return deg + 360.0 * std::round((near - deg) / 360.0);
}

}  // namespace cnc::kin::detail
