// The round trips of the unit tests over many more seeded random poses
// (label slow). CNC_TEST_SEED repeats a failing run.
#include <gtest/gtest.h>

#include <numbers>

#include "kinematics/five_axis.hpp"
#include "kinematics/genserkins.hpp"
#include "kinematics/scarakins.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;
using cnc::kin::testing::linear_error;
using cnc::kin::testing::max_error;
using cnc::kin::testing::pose_text;
using cnc::kin::testing::Rng;

TEST(SlowRoundTrip, TableTableAndHeadTableMillionPoses) {
  Rng rng(0xF1FE);
  TableTableKins trt("xyzac-trt-kins", TiltAxis::A, JointMap::parse("XYZAC", "t", false));
  trt.params().z_rot_point.set(-110);
  trt.params().y_offset.set(4);
  trt.params().z_offset.set(-35);
  trt.params().tool_offset.set(60);
  HeadTableKins ht("headtable-kins", TiltAxis::B, JointMap::parse("XYZBC", "t", false));
  ht.params().pivot_length.set(180);
  ht.params().tool_offset.set(60);
  for (int i = 0; i < 1'000'000; ++i) {
    Pose p;
    p[Axis::X] = rng.uniform(-500, 500);
    p[Axis::Y] = rng.uniform(-500, 500);
    p[Axis::Z] = rng.uniform(-300, 300);
    p[Axis::A] = rng.uniform(-130, 130);
    p[Axis::B] = rng.uniform(-130, 130);
    p[Axis::C] = rng.uniform(-1080, 1080);
    for (Kinematics* k : {static_cast<Kinematics*>(&trt), static_cast<Kinematics*>(&ht)}) {
      Pose q = p;
      q[k == &trt ? Axis::B : Axis::A] = 0;
      double j[5];
      ASSERT_EQ(k->inverse(q, nullptr, j), KinResult::Ok);
      Pose back;
      ASSERT_EQ(k->forward(j, back), KinResult::Ok);
      ASSERT_LT(max_error(back, q), 1e-9) << k->name() << " sample " << i << ": " << pose_text(q);
    }
  }
}

TEST(SlowRoundTrip, ScaraMillionPoses) {
  Rng rng(0x5CA);
  ScaraKins k;
  for (int i = 0; i < 1'000'000; ++i) {
    const double elbow = rng.uniform(0.5, 179.5) * (rng.uniform(0, 1) < 0.5 ? -1 : 1);
    const double j[6] = {rng.uniform(-360, 360), elbow, rng.uniform(-200, 200), rng.uniform(-720, 720), 0, 0};
    Pose p;
    ASSERT_EQ(k.forward(j, p), KinResult::Ok);
    double out[6];
    ASSERT_EQ(k.inverse(p, j, out), KinResult::Ok) << pose_text(p);
    for (int m = 0; m < 4; ++m) ASSERT_NEAR(out[m], j[m], 1e-9) << "sample " << i << " joint " << m;
  }
}

TEST(SlowRoundTrip, SerialArmHundredThousandPoses) {
  Rng rng(0xA2A);
  GenserKins k;
  constexpr double h = std::numbers::pi / 2;
  const double a[6] = {0, 85, 380, 100, 0, 0}, alpha[6] = {0, -h, 0, -h, h, -h}, d[6] = {350, 0, 0, 425, 0, 100};
  for (std::size_t i = 0; i < 6; ++i) {
    k.params().a[i].set(a[i]);
    k.params().alpha[i].set(alpha[i]);
    k.params().d[i].set(d[i]);
  }
  int tested = 0;
  for (int i = 0; tested < 100'000; ++i) {
    double q[6];
    for (double& v : q) v = rng.uniform(-175, 175);
    if (k.singularity_measure(q) < 1e-2) continue;
    ++tested;
    Pose p;
    ASSERT_EQ(k.forward(q, p), KinResult::Ok);
    double hint[6];
    for (int m = 0; m < 6; ++m) hint[m] = q[m] + rng.uniform(-2, 2);
    double out[6];
    ASSERT_EQ(k.inverse(p, hint, out), KinResult::Ok) << "sample " << i << ": " << pose_text(p);
    Pose back;
    ASSERT_EQ(k.forward(out, back), KinResult::Ok);
    ASSERT_LT(linear_error(back, p), 1e-6) << "sample " << i;
  }
}
