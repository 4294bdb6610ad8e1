#include "kinematics/genserkins.hpp"

#include <algorithm>
#include <cmath>

#include "kinematics/detail/rotation.hpp"

namespace cnc::kin {
namespace {

using detail::kDeg;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;
constexpr int kN = GenserKins::kJoints;

// The parameters as numbers for one call (read once from the pins).
struct Chain {
  double ca[kN], sa[kN], a[kN], d[kN];
  bool prismatic[kN];
  double length;  // scale between rotation and position errors
};

// The last frame and, per joint, its axis and a point on it (world frame).
struct Frames {
  Eigen::Matrix3d r;
  Eigen::Vector3d p;
  Eigen::Vector3d axis[kN];
  Eigen::Vector3d origin[kN];
};

void forward_chain(const Chain& c, const double* q, Frames& f) noexcept {
  f.r.setIdentity();
  f.p.setZero();
  for (int i = 0; i < kN; ++i) {
    // Tx(a) then Rx(alpha) (they commute); columns turned in place.
    f.p += c.a[i] * f.r.col(0);
    const Eigen::Vector3d y = f.r.col(1), z = f.r.col(2);
    f.r.col(1) = c.ca[i] * y + c.sa[i] * z;
    f.r.col(2) = -c.sa[i] * y + c.ca[i] * z;
    f.axis[i] = f.r.col(2);
    f.origin[i] = f.p;
    const double theta = c.prismatic[i] ? 0.0 : q[i] * kDeg;
    const double d = c.d[i] + (c.prismatic[i] ? q[i] : 0.0);
    if (theta != 0.0) {
      const double ct = std::cos(theta), st = std::sin(theta);
      const Eigen::Vector3d x = f.r.col(0), y2 = f.r.col(1);
      f.r.col(0) = ct * x + st * y2;
      f.r.col(1) = -st * x + ct * y2;
    }
    f.p += d * f.axis[i];
  }
}

// Rows 0-2: position per unit joint motion divided by the length scale;
// rows 3-5: rotation (radians). Columns per radian or per unit length, so the
// singular values do not depend on the machine's units or its size.
Matrix6d normalised_jacobian(const Chain& c, const Frames& f) noexcept {
  Matrix6d j;
  for (int i = 0; i < kN; ++i) {
    if (c.prismatic[i]) {
      j.col(i) << f.axis[i], Eigen::Vector3d::Zero();
    } else {
      j.col(i) << f.axis[i].cross(f.p - f.origin[i]) / c.length, f.axis[i];
    }
  }
  return j;
}

// Tikhonov damping of the normal equations: keeps them solvable on a
// singularity; 1e-12 is far below any threshold worth setting (sigma 1e-6).
constexpr double kDamping = 1e-12;

// Cholesky factor (lower) of a symmetric positive definite 6x6, written out
// because Eigen's general fixed-size factorizations cost several times more
// at this size. False when `a` is not positive definite.
bool cholesky(const Matrix6d& a, Matrix6d& l) noexcept {
  for (int j = 0; j < 6; ++j) {
    double d = a(j, j);
    for (int k = 0; k < j; ++k) d -= l(j, k) * l(j, k);
    if (!(d > 0.0)) return false;
    l(j, j) = std::sqrt(d);
    for (int i = j + 1; i < 6; ++i) {
      double s = a(i, j);
      for (int k = 0; k < j; ++k) s -= l(i, k) * l(j, k);
      l(i, j) = s / l(j, j);
    }
  }
  return true;
}

// Solves L L^T x = b in place.
void cholesky_solve(const Matrix6d& l, Vector6d& b) noexcept {
  for (int i = 0; i < 6; ++i) {
    double s = b[i];
    for (int k = 0; k < i; ++k) s -= l(i, k) * b[k];
    b[i] = s / l(i, i);
  }
  for (int i = 5; i >= 0; --i) {
    double s = b[i];
    for (int k = i + 1; k < 6; ++k) s -= l(k, i) * b[k];
    b[i] = s / l(i, i);
  }
}

// The smallest singular value of `j` by inverse iteration on J^T J (a few
// 6x6 solves instead of a full eigen decomposition). The estimate never
// falls below the true value; next to a singularity, where it matters, the
// smallest eigenvalue is far below the next and four steps settle it, and
// two small ones at once still read small.
double smallest_singular_value(const Matrix6d& j) noexcept {
  Matrix6d l;
  if (!cholesky(j.transpose() * j + kDamping * Matrix6d::Identity(), l)) return 0.0;
  Vector6d v;
  v << 0.9, -0.4, 0.7, 0.3, -0.8, 0.5;  // no special direction of any arm
  double lambda = 0.0;
  for (int i = 0; i < 4; ++i) {
    v /= v.norm();
    cholesky_solve(l, v);
    const double grow = v.norm();
    if (!(grow > 0.0) || !std::isfinite(grow)) return 0.0;
    lambda = 1.0 / grow;
  }
  return std::sqrt(std::max(0.0, lambda - kDamping));
}

Chain load_chain(const GenserKins::Params& p, const GenserKins& k) noexcept {
  Chain c{};
  double length = 0.0;
  for (int i = 0; i < kN; ++i) {
    const auto u = static_cast<std::size_t>(i);
    const double alpha = p.alpha[u].get();
    c.ca[i] = std::cos(alpha);
    c.sa[i] = std::sin(alpha);
    c.a[i] = p.a[u].get();
    c.d[i] = p.d[u].get();
    c.prismatic[i] = k.is_prismatic(i);
    length += std::abs(c.a[i]) + std::abs(c.d[i]);
    if (c.prismatic[i]) length += std::max(std::abs(p.min_limit[u].get()), std::abs(p.max_limit[u].get()));
  }
  c.length = length > 0.0 ? length : 1.0;
  return c;
}

}  // namespace

GenserKins::GenserKins(std::array<bool, kJoints> prismatic) noexcept
    : KinematicsModule("genserkins", JointMap::identity("XYZABC"), KinematicsType::Both, /*coupled=*/true,
                       /*switchable=*/true),
      prismatic_(prismatic) {}

void GenserKins::bind(HalBinder& b) {
  KinematicsModule::bind(b);
  for (int i = 0; i < kJoints; ++i) {
    const auto u = static_cast<std::size_t>(i);
    const std::string n = std::to_string(i);
    b.param("a-" + n, p_.a[u]);
    b.param("alpha-" + n, p_.alpha[u]);
    b.param("d-" + n, p_.d[u]);
  }
  for (int i = 0; i < kJoints; ++i) {
    const auto u = static_cast<std::size_t>(i);
    b.param("min-limit-" + std::to_string(i), p_.min_limit[u]);
    b.param("max-limit-" + std::to_string(i), p_.max_limit[u]);
  }
  b.param("max-iterations", p_.max_iterations);
  b.param("singular-threshold", p_.singular_threshold);
  last_iterations_pin_ = b.out_u32(b.prefix() + ".last-iterations");
}

KinResult GenserKins::forward_own(const double* joints, Pose& pose) const noexcept {
  const Chain c = load_chain(p_, *this);
  Frames f;
  forward_chain(c, joints, f);
  pose = Pose{};
  pose[Axis::X] = f.p.x();
  pose[Axis::Y] = f.p.y();
  pose[Axis::Z] = f.p.z();
  detail::matrix_to_rpy(f.r, pose[Axis::A], pose[Axis::B], pose[Axis::C]);
  return KinResult::Ok;
}

double GenserKins::singularity_measure(const double* joints) const noexcept {
  const Chain c = load_chain(p_, *this);
  Frames f;
  forward_chain(c, joints, f);
  return smallest_singular_value(normalised_jacobian(c, f));
}

KinResult GenserKins::inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept {
  const Chain c = load_chain(p_, *this);
  const Eigen::Vector3d target_p(pose[Axis::X], pose[Axis::Y], pose[Axis::Z]);
  const Eigen::Matrix3d target_r = detail::rpy_to_matrix(pose[Axis::A], pose[Axis::B], pose[Axis::C]);
  // Each link reaches at most |a| + |d| (+ its stroke): farther is out of reach.
  if (target_p.norm() > c.length * (1.0 + 1e-12)) return KinResult::Unreachable;

  const int max_iterations = static_cast<int>(std::clamp(p_.max_iterations.get(), 1.0, 1000.0));
  const double threshold = p_.singular_threshold.get();
  // Converged: well below the 1e-6 mm the round trips need, one Newton step
  // above rounding.
  constexpr double kTolPosition = 1e-9;   // machine units
  constexpr double kTolRotation = 1e-12;  // radians
  // One step turns a joint by at most this much: keeps the iteration on the
  // hint's branch instead of leaping across the workspace.
  constexpr double kMaxStepRad = 0.35;

  double q[kN];
  for (int i = 0; i < kN; ++i) q[i] = hint != nullptr ? hint[i] : 0.0;

  Frames f;
  Matrix6d jac;
  bool converged = false;
  int iterations = 0;
  for (; iterations <= max_iterations; ++iterations) {
    forward_chain(c, q, f);
    const Eigen::Vector3d ep = target_p - f.p;
    const Eigen::AngleAxisd er(target_r * f.r.transpose());
    const Eigen::Vector3d eo = er.angle() * er.axis();
    jac = normalised_jacobian(c, f);
    if (ep.norm() < kTolPosition && eo.norm() < kTolRotation) {
      converged = true;
      break;
    }
    if (iterations == max_iterations) break;
    Vector6d e;
    e << ep / c.length, eo;
    // Damped least squares; the damping only matters next to a singularity,
    // where plain Newton steps would be unbounded.
    Matrix6d l;
    if (!cholesky(jac.transpose() * jac + kDamping * Matrix6d::Identity(), l)) break;
    Vector6d dq = jac.transpose() * e;
    cholesky_solve(l, dq);
    double largest = 0.0;
    for (int i = 0; i < kN; ++i) largest = std::max(largest, std::abs(c.prismatic[i] ? dq[i] / c.length : dq[i]));
    if (largest > kMaxStepRad) dq *= kMaxStepRad / largest;
    for (int i = 0; i < kN; ++i) q[i] += c.prismatic[i] ? dq[i] * c.length : dq[i] / kDeg;
  }
  last_iterations_.store(static_cast<unsigned>(iterations), std::memory_order_relaxed);
  if (last_iterations_pin_.valid()) last_iterations_pin_.set(static_cast<uint32_t>(iterations));

  const double sigma = smallest_singular_value(jac);
  if (!converged) return sigma < threshold ? KinResult::Unreachable : KinResult::NotConverged;
  if (sigma < threshold) return KinResult::Singular;
  for (int i = 0; i < kN; ++i) {
    const auto u = static_cast<std::size_t>(i);
    if (q[i] < p_.min_limit[u].get() || q[i] > p_.max_limit[u].get()) return KinResult::JointLimit;
  }
  std::copy(q, q + kN, joints);
  return KinResult::Ok;
}

}  // namespace cnc::kin
