// The serial arm: closed-form forward against hand-computed frames,
// iterative inverse round trips (below 1e-6 mm) from hints as the servo
// cycle gives them, and the failures: singular, out of reach, joint limits,
// no convergence, each without a jump.
#include <gtest/gtest.h>

#include <numbers>

#include "kinematics/genserkins.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;
using cnc::kin::testing::angle_error_deg;
using cnc::kin::testing::linear_error;
using cnc::kin::testing::pose_text;
using cnc::kin::testing::Rng;

namespace {

constexpr double kHalfPi = std::numbers::pi / 2;

// A 6-axis industrial arm in Craig's DH form (the dimensions LinuxCNC's
// genserkins examples use for a small Mitsubishi arm), flange 100 mm.
void set_arm(GenserKins& k) {
  const double a[6] = {0, 85, 380, 100, 0, 0};
  const double alpha[6] = {0, -kHalfPi, 0, -kHalfPi, kHalfPi, -kHalfPi};
  const double d[6] = {350, 0, 0, 425, 0, 100};
  for (std::size_t i = 0; i < 6; ++i) {
    k.params().a[i].set(a[i]);
    k.params().alpha[i].set(alpha[i]);
    k.params().d[i].set(d[i]);
  }
}

bool orientation_near(const Pose& a, const Pose& b, double tol_deg) {
  return angle_error_deg(a[Axis::A], b[Axis::A]) < tol_deg && angle_error_deg(a[Axis::B], b[Axis::B]) < tol_deg &&
         angle_error_deg(a[Axis::C], b[Axis::C]) < tol_deg;
}

}  // namespace

TEST(GenserKins, ForwardMatchesHandComputedFrames) {
  GenserKins k;
  set_arm(k);
  Pose p;
  // All joints 0: base 350 up, shoulder 85 out, upper arm 380 and forearm
  // offset 100 along X, then the forearm (425) and flange (100) point down:
  // (565, 0, 350 - 425 - 100), tool Z down, so roll 180.
  const double zero[6] = {0, 0, 0, 0, 0, 0};
  ASSERT_EQ(k.forward(zero, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], 565, 1e-12);
  EXPECT_NEAR(p[Axis::Y], 0, 1e-12);
  EXPECT_NEAR(p[Axis::Z], -175, 1e-12);
  EXPECT_LT(angle_error_deg(p[Axis::A], 180), 1e-12);
  EXPECT_LT(angle_error_deg(p[Axis::B], 0), 1e-12);
  EXPECT_LT(angle_error_deg(p[Axis::C], 0), 1e-12);

  // The base turned 90 degrees: the same arm along +Y, yaw 90.
  const double base90[6] = {90, 0, 0, 0, 0, 0};
  ASSERT_EQ(k.forward(base90, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], 0, 1e-12);
  EXPECT_NEAR(p[Axis::Y], 565, 1e-12);
  EXPECT_NEAR(p[Axis::Z], -175, 1e-12);
  EXPECT_LT(angle_error_deg(p[Axis::C], 90), 1e-12);

  // Elbow 90: the upper arm end (465, 0, 350), the 100 offset now down to
  // z 250, the forearm and flange back along -X: (465 - 525, 0, 250); the
  // tool points along -X: pitch 90 (gimbal lock: A 0, C 180).
  const double elbow90[6] = {0, 0, 90, 0, 0, 0};
  ASSERT_EQ(k.forward(elbow90, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], -60, 1e-12);
  EXPECT_NEAR(p[Axis::Y], 0, 1e-12);
  EXPECT_NEAR(p[Axis::Z], 250, 1e-12);
  EXPECT_LT(angle_error_deg(p[Axis::B], 90), 1e-9);
  EXPECT_LT(angle_error_deg(p[Axis::A], 0), 1e-9);
  EXPECT_LT(angle_error_deg(p[Axis::C], 180), 1e-9);
}

TEST(GenserKins, RandomRoundTripsFromNearbyHints) {
  Rng rng(0x6E5E2);
  GenserKins k;
  set_arm(k);
  int tested = 0;
  for (int i = 0; tested < 3000; ++i) {
    double q[6];
    for (double& v : q) v = rng.uniform(-170, 170);
    if (k.singularity_measure(q) < 2e-2) continue;  // the workspace away from singularities
    ++tested;
    Pose p;
    ASSERT_EQ(k.forward(q, p), KinResult::Ok);
    double hint[6];
    for (int m = 0; m < 6; ++m) hint[m] = q[m] + rng.uniform(-1, 1);  // one fast servo period away
    double out[6];
    ASSERT_EQ(k.inverse(p, hint, out), KinResult::Ok) << "sample " << i << ": " << pose_text(p);
    Pose back;
    ASSERT_EQ(k.forward(out, back), KinResult::Ok);
    ASSERT_LT(linear_error(back, p), 1e-6) << "sample " << i;
    ASSERT_TRUE(orientation_near(back, p, 1e-8)) << pose_text(back) << " vs " << pose_text(p);
    for (int m = 0; m < 6; ++m) ASSERT_NEAR(out[m], q[m], 1e-6) << "sample " << i << " joint " << m;
  }
}

TEST(GenserKins, ACycleStartedFromThePreviousJointsConvergesInFewIterations) {
  GenserKins k;
  set_arm(k);
  double prev[6] = {10, -30, 60, 20, 45, -10};
  unsigned worst = 0;
  for (int cycle = 1; cycle <= 2000; ++cycle) {
    const double t = cycle * 0.001;  // 1 ms cycles, up to 60 deg/s per joint
    const double q[6] = {10 + 30 * std::sin(t), -30 + 20 * std::sin(2 * t), 60 - 25 * std::sin(1.5 * t),
                         20 + 40 * std::sin(t), 45 + 20 * std::sin(3 * t), -10 + 60 * std::sin(t)};
    Pose p;
    ASSERT_EQ(k.forward(q, p), KinResult::Ok);
    double out[6];
    ASSERT_EQ(k.inverse(p, prev, out), KinResult::Ok) << "cycle " << cycle;
    for (int m = 0; m < 6; ++m) ASSERT_NEAR(out[m], q[m], 1e-6);
    worst = std::max(worst, k.last_iterations());
    std::copy(out, out + 6, prev);
  }
  EXPECT_LE(worst, 3u) << "Newton from the previous cycle: two steps, then the check";
}

TEST(GenserKins, TheWristSingularityIsReportedNotJumpedThrough) {
  GenserKins k;
  set_arm(k);
  // Joint 4 (the wrist bend) runs to 0, where joints 3 and 5 line up.
  double prev[6] = {20, -10, 30, 15, 8, 5};
  bool singular = false;
  for (int step = 0; step <= 800; ++step) {
    const double q[6] = {20 + step * 0.01, -10, 30, 15, 8 - step * 0.01, 5};
    Pose p;
    ASSERT_EQ(k.forward(q, p), KinResult::Ok);
    double out[6];
    const KinResult r = k.inverse(p, prev, out);
    if (r == KinResult::Singular) {
      singular = true;
      for (int m = 0; m < 6; ++m) EXPECT_EQ(out[m], prev[m]) << "the hint comes back";
      EXPECT_LT(std::abs(q[4]), 0.2) << "reported only next to the singularity, at q4 = " << q[4];
      break;
    }
    ASSERT_EQ(r, KinResult::Ok) << "step " << step;
    for (int m = 0; m < 6; ++m) ASSERT_LT(std::abs(out[m] - prev[m]), 1.0) << "no jump, joint " << m;
    std::copy(out, out + 6, prev);
  }
  EXPECT_TRUE(singular);

  const double zero[6] = {0, 0, 0, 0, 0, 0};
  Pose at;
  ASSERT_EQ(k.forward(zero, at), KinResult::Ok);
  double out[6];
  EXPECT_EQ(k.inverse(at, zero, out), KinResult::Singular) << "exactly on it";
  EXPECT_LT(k.singularity_measure(zero), 1e-5) << "zero up to damping and rounding";
}

TEST(GenserKins, OutOfReachIsReported) {
  GenserKins k;
  set_arm(k);
  const double hint[6] = {10, -20, 30, 0, 40, 0};
  double out[6];
  Pose far;
  far[Axis::X] = 5000;
  EXPECT_EQ(k.inverse(far, hint, out), KinResult::Unreachable) << "beyond the sum of the links";
  EXPECT_EQ(out[0], 10);
  Pose below;  // within the links' sum but 1350 mm from the shoulder, which reaches ~920
  below[Axis::Z] = -1000;
  below[Axis::A] = 180;
  EXPECT_EQ(k.inverse(below, hint, out), KinResult::Unreachable);
}

TEST(GenserKins, JointLimitsFromThePinsAreEnforced) {
  GenserKins k;
  set_arm(k);
  const double q[6] = {30, -20, 40, 10, 50, -15};
  Pose p;
  ASSERT_EQ(k.forward(q, p), KinResult::Ok);
  double out[6];
  ASSERT_EQ(k.inverse(p, q, out), KinResult::Ok);
  k.params().max_limit[0].set(25);
  EXPECT_EQ(k.inverse(p, q, out), KinResult::JointLimit);
  k.params().max_limit[0].set(1e9);
  k.params().min_limit[4].set(55);
  EXPECT_EQ(k.inverse(p, q, out), KinResult::JointLimit);
}

TEST(GenserKins, AnIterationBudgetTooSmallIsReported) {
  GenserKins k;
  set_arm(k);
  const double q[6] = {30, -20, 40, 10, 50, -15};
  Pose p;
  ASSERT_EQ(k.forward(q, p), KinResult::Ok);
  k.params().max_iterations.set(1);
  const double far_hint[6] = {60, 10, 10, 40, 80, 20};
  double out[6];
  EXPECT_EQ(k.inverse(p, far_hint, out), KinResult::NotConverged);
  k.params().max_iterations.set(100);
  EXPECT_EQ(k.inverse(p, far_hint, out), KinResult::Ok);
  for (int m = 0; m < 6; ++m) EXPECT_NEAR(out[m], q[m], 1e-6);
}

TEST(GenserKins, PrismaticJointsSlide) {
  // A cylindrical arm: base turn, vertical slide, radial slide, then a
  // spherical wrist.
  GenserKins k({false, true, true, false, false, false});
  const double alpha[6] = {0, 0, -kHalfPi, 0, -kHalfPi, kHalfPi};
  const double d[6] = {200, 0, 0, 50, 0, 80};
  for (std::size_t i = 0; i < 6; ++i) {
    k.params().alpha[i].set(alpha[i]);
    k.params().d[i].set(d[i]);
    k.params().min_limit[i].set(-400);
    k.params().max_limit[i].set(400);
  }
  Rng rng(0x9A1);
  int tested = 0;
  while (tested < 500) {
    const double q[6] = {rng.uniform(-170, 170), rng.uniform(0, 300), rng.uniform(100, 300),
                         rng.uniform(-170, 170), rng.uniform(10, 170), rng.uniform(-170, 170)};
    if (k.singularity_measure(q) < 2e-2) continue;
    ++tested;
    Pose p;
    ASSERT_EQ(k.forward(q, p), KinResult::Ok);
    double hint[6];
    for (int m = 0; m < 6; ++m) hint[m] = q[m] + rng.uniform(-0.5, 0.5);
    double out[6];
    ASSERT_EQ(k.inverse(p, hint, out), KinResult::Ok) << pose_text(p);
    for (int m = 0; m < 6; ++m) ASSERT_NEAR(out[m], q[m], 1e-6) << "joint " << m;
  }
}

TEST(GenserKins, WithoutAHintItStartsFromZeroAndStillLandsOnThePose) {
  GenserKins k;
  set_arm(k);
  const double q[6] = {20, -15, 35, 10, 40, -5};
  Pose p;
  ASSERT_EQ(k.forward(q, p), KinResult::Ok);
  double out[6];
  ASSERT_EQ(k.inverse(p, nullptr, out), KinResult::Ok) << "from the singular all-zero posture";
  Pose back;
  ASSERT_EQ(k.forward(out, back), KinResult::Ok);
  EXPECT_LT(linear_error(back, p), 1e-6);
  EXPECT_TRUE(orientation_near(back, p, 1e-8));
}

TEST(GenserKins, ANonFinitePoseIsUnreachable) {
  GenserKins k;
  set_arm(k);
  const double hint[6] = {20, -15, 35, 10, 40, -5};
  Pose p;
  ASSERT_EQ(k.forward(hint, p), KinResult::Ok);
  double out[6];
  const double near[6] = {21, -14, 36, 11, 41, -4};
  ASSERT_EQ(k.inverse(p, near, out), KinResult::Ok);
  const unsigned before = k.last_iterations();
  ASSERT_GT(before, 0u);
  p[Axis::X] = std::nan("");
  EXPECT_EQ(k.inverse(p, hint, out), KinResult::Unreachable);
  EXPECT_EQ(out[5], -5) << "the hint comes back";
  EXPECT_EQ(k.last_iterations(), before) << "the iteration never ran";
}

TEST(GenserKins, IdentityForSetup) {
  GenserKins k;
  set_arm(k);
  ASSERT_TRUE(k.switch_to(1));
  Pose p;
  p[Axis::X] = 1;
  p[Axis::C] = 6;
  double out[6];
  ASSERT_EQ(k.inverse(p, nullptr, out), KinResult::Ok);
  EXPECT_EQ(out[0], 1);
  EXPECT_EQ(out[5], 6);
}
