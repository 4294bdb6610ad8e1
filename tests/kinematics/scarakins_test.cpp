#include <gtest/gtest.h>

#include "kinematics/scarakins.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;
using cnc::kin::testing::max_error;
using cnc::kin::testing::pose_text;
using cnc::kin::testing::Rng;

// LinuxCNC's default dimensions: d1 490, d2 340, d3 50, d4 250, d5 50, d6 50.
TEST(ScaraKins, KnownPosesWithTheDefaultDimensions) {
  ScaraKins k;
  Pose p;
  const double zero[6] = {0, 0, 0, 0, 0, 0};
  ASSERT_EQ(k.forward(zero, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], 340 + 250 + 50, 1e-12) << "arms and tool in line along X";
  EXPECT_NEAR(p[Axis::Y], 0, 1e-12);
  EXPECT_NEAR(p[Axis::Z], 490 + 50 - 50, 1e-12);
  EXPECT_EQ(p[Axis::C], 0);

  const double turned[6] = {90, 0, 10, 0, 5, 6};
  ASSERT_EQ(k.forward(turned, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], 0, 1e-12);
  EXPECT_NEAR(p[Axis::Y], 640, 1e-12);
  EXPECT_NEAR(p[Axis::Z], 480, 1e-12) << "the quill moves down";
  EXPECT_EQ(p[Axis::C], 90);
  EXPECT_EQ(p[Axis::A], 5);
  EXPECT_EQ(p[Axis::B], 6);

  const double elbow[6] = {0, 90, 0, -90, 0, 0};
  ASSERT_EQ(k.forward(elbow, p), KinResult::Ok);
  EXPECT_NEAR(p[Axis::X], 340 + 50, 1e-12);
  EXPECT_NEAR(p[Axis::Y], 250, 1e-12);
  EXPECT_NEAR(p[Axis::C], 0, 1e-12);
  double j[6];
  ASSERT_EQ(k.inverse(p, elbow, j), KinResult::Ok);
  for (int m = 0; m < 6; ++m) EXPECT_NEAR(j[m], elbow[m], 1e-9) << m;
}

TEST(ScaraKins, InverseKeepsTheHintsElbowAndTurn) {
  ScaraKins k;
  const double left[6] = {30, 60, 5, 10, 0, 0};
  Pose p;
  ASSERT_EQ(k.forward(left, p), KinResult::Ok);
  const double right_hint[6] = {90, -60, 5, 0, 0, 0};
  double j[6];
  ASSERT_EQ(k.inverse(p, right_hint, j), KinResult::Ok);
  EXPECT_LT(j[1], 0) << "the other elbow when the hint has it";
  Pose back;
  ASSERT_EQ(k.forward(j, back), KinResult::Ok);
  EXPECT_LT(max_error(back, p), 1e-9) << "the same pose either way";
  const double turned_hint[6] = {30 + 720, 60, 5, 10, 0, 0};
  ASSERT_EQ(k.inverse(p, turned_hint, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 750, 1e-9) << "whole turns follow the hint";
  EXPECT_NEAR(j[3], 10 - 720, 1e-9) << "and the tool joint keeps C";
}

TEST(ScaraKins, RandomRoundTripsAreExact) {
  Rng rng(0x5CA4A);
  ScaraKins k;
  for (int i = 0; i < 20000; ++i) {
    // Elbow kept 1 degree from straight: there the two branches meet.
    const double elbow = rng.uniform(1, 179) * (rng.uniform(0, 1) < 0.5 ? -1 : 1);
    const double j[6] = {rng.uniform(-180, 180), elbow, rng.uniform(-100, 100), rng.uniform(-360, 360),
                         rng.uniform(-90, 90), rng.uniform(-90, 90)};
    Pose p;
    ASSERT_EQ(k.forward(j, p), KinResult::Ok);
    double out[6];
    ASSERT_EQ(k.inverse(p, j, out), KinResult::Ok) << pose_text(p);
    for (int m = 0; m < 6; ++m) ASSERT_NEAR(out[m], j[m], 1e-9) << "sample " << i << " joint " << m;
    Pose back;
    ASSERT_EQ(k.forward(out, back), KinResult::Ok);
    ASSERT_LT(max_error(back, p), 1e-9);
  }
}

TEST(ScaraKins, OutOfReachAndTheBaseAxisAreReported) {
  ScaraKins k;
  double hint[6] = {10, 20, 0, 0, 0, 0};
  double j[6];
  Pose far;
  far[Axis::X] = 340 + 250 + 50 + 1.0;  // 1 mm beyond full stretch
  EXPECT_EQ(k.inverse(far, hint, j), KinResult::Unreachable);
  EXPECT_EQ(j[0], 10) << "the hint comes back, no jump";
  Pose near;
  near[Axis::X] = 50 + (340 - 250) - 1.0;  // closer than the folded arm reaches
  EXPECT_EQ(k.inverse(near, hint, j), KinResult::Unreachable);

  k.params().d4.set(340);  // equal arms fold onto the base axis
  Pose base;
  base[Axis::X] = 50;  // the tool offset d6 along C = 0: quill on the axis
  EXPECT_EQ(k.inverse(base, hint, j), KinResult::Singular);

  const double stretched[6] = {25, 0, 0, 0, 0, 0};
  Pose edge;
  ASSERT_EQ(k.forward(stretched, edge), KinResult::Ok);
  ASSERT_EQ(k.inverse(edge, stretched, j), KinResult::Ok) << "full stretch is still reachable";
  EXPECT_NEAR(j[0], 25, 1e-3);
  EXPECT_NEAR(j[1], 0, 1e-2);
}
