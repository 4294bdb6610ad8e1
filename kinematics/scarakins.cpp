#include "kinematics/scarakins.hpp"

#include <cmath>

#include "kinematics/detail/rotation.hpp"

namespace cnc::kin {

using detail::kDeg;

ScaraKins::ScaraKins() noexcept
    : KinematicsModule("scarakins", JointMap::identity("XYZABC"), KinematicsType::Both, /*coupled=*/true,
                       /*switchable=*/true) {}

void ScaraKins::bind(HalBinder& b) {
  KinematicsModule::bind(b);
  b.param("d1", p_.d1);
  b.param("d2", p_.d2);
  b.param("d3", p_.d3);
  b.param("d4", p_.d4);
  b.param("d5", p_.d5);
  b.param("d6", p_.d6);
}

KinResult ScaraKins::forward_own(const double* j, Pose& pose) const noexcept {
  const double inner = j[0] * kDeg;
  const double outer = (j[0] + j[1]) * kDeg;
  const double tool = (j[0] + j[1] + j[3]) * kDeg;
  const double d2 = p_.d2.get(), d4 = p_.d4.get(), d6 = p_.d6.get();
  pose = Pose{};
  pose[Axis::X] = d2 * std::cos(inner) + d4 * std::cos(outer) + d6 * std::cos(tool);
  pose[Axis::Y] = d2 * std::sin(inner) + d4 * std::sin(outer) + d6 * std::sin(tool);
  pose[Axis::Z] = p_.d1.get() + p_.d3.get() - p_.d5.get() - j[2];
  pose[Axis::A] = j[4];
  pose[Axis::B] = j[5];
  pose[Axis::C] = j[0] + j[1] + j[3];
  return KinResult::Ok;
}

KinResult ScaraKins::inverse_own(const Pose& pose, const double* hint, double* j) const noexcept {
  const double d2 = p_.d2.get(), d4 = p_.d4.get(), d6 = p_.d6.get();
  if (!(d2 > 0.0) || !(d4 > 0.0)) return KinResult::Unreachable;
  const double c = pose[Axis::C] * kDeg;
  // The quill axis, where the tool's horizontal offset d6 starts.
  const double wx = pose[Axis::X] - d6 * std::cos(c);
  const double wy = pose[Axis::Y] - d6 * std::sin(c);
  const double r2 = wx * wx + wy * wy;
  double cos_elbow = (r2 - d2 * d2 - d4 * d4) / (2.0 * d2 * d4);
  // 1e-9 of the cosine is ~1e-7 mm of reach: rounding at full stretch, not a
  // pose out of reach.
  constexpr double kSlack = 1e-9;
  if (cos_elbow > 1.0 + kSlack || cos_elbow < -1.0 - kSlack) return KinResult::Unreachable;
  cos_elbow = std::fmin(1.0, std::fmax(-1.0, cos_elbow));
  // On the base axis the inner arm's direction is free: no unique answer.
  if (r2 < 1e-18 * (d2 * d2 + d4 * d4)) return KinResult::Singular;

  const bool elbow_negative = hint != nullptr && std::sin(hint[1] * kDeg) < 0.0;
  const double sin_elbow = (elbow_negative ? -1.0 : 1.0) * std::sqrt(1.0 - cos_elbow * cos_elbow);
  double elbow = std::atan2(sin_elbow, cos_elbow) / kDeg;
  double inner = (std::atan2(wy, wx) - std::atan2(d4 * sin_elbow, d2 + d4 * cos_elbow)) / kDeg;
  if (hint != nullptr) {
    inner = detail::unwrap_deg(inner, hint[0]);
    elbow = detail::unwrap_deg(elbow, hint[1]);
  }
  j[0] = inner;
  j[1] = elbow;
  j[2] = p_.d1.get() + p_.d3.get() - p_.d5.get() - pose[Axis::Z];
  j[3] = pose[Axis::C] - inner - elbow;
  j[4] = pose[Axis::A];
  j[5] = pose[Axis::B];
  return KinResult::Ok;
}

}  // namespace cnc::kin
