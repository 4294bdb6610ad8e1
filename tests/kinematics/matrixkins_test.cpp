#include <gtest/gtest.h>

#include "kinematics/matrixkins.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;
using cnc::kin::testing::max_error;
using cnc::kin::testing::Rng;

namespace {
MatrixKins make(const char* letters = "XYZ") { return MatrixKins(JointMap::parse(letters, "matrixkins", true, "XYZ")); }
}  // namespace

TEST(MatrixKins, StartsAsTheIdentity) {
  MatrixKins k = make();
  Pose p;
  p[Axis::X] = 10;
  p[Axis::Y] = 20;
  p[Axis::Z] = 30;
  double j[3];
  ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_EQ(j[0], 10);
  EXPECT_EQ(j[1], 20);
  EXPECT_EQ(j[2], 30);
}

TEST(MatrixKins, ScaleAndSkewAsLinuxCncDefinesThem) {
  MatrixKins k = make();
  k.c(0, 0).set(0.99);
  k.c(1, 1).set(1.01);
  k.c(2, 2).set(1.05);
  k.c(0, 1).set(0.01);  // X error per unit of Y
  k.c(0, 2).set(0.03);
  Pose p;
  p[Axis::X] = 10;
  p[Axis::Y] = 20;
  p[Axis::Z] = 30;
  double j[3];
  ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 10 * 0.99 + 20 * 0.01 + 30 * 0.03, 1e-12);
  EXPECT_NEAR(j[1], 20 * 1.01, 1e-12);
  EXPECT_NEAR(j[2], 30 * 1.05, 1e-12);
  Pose back;
  ASSERT_EQ(k.forward(j, back), KinResult::Ok);
  EXPECT_LT(max_error(back, p), 1e-12);
}

TEST(MatrixKins, RandomRoundTripsAreExact) {
  Rng rng(0x3A7);
  MatrixKins k = make("XYYZA");
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) k.c(r, c).set((r == c ? 1.0 : 0.0) + rng.uniform(-0.01, 0.01));
  }
  for (int i = 0; i < 20000; ++i) {
    Pose p;
    p[Axis::X] = rng.uniform(-1000, 1000);
    p[Axis::Y] = rng.uniform(-1000, 1000);
    p[Axis::Z] = rng.uniform(-500, 500);
    p[Axis::A] = rng.uniform(-360, 360);
    double j[5];
    ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
    ASSERT_EQ(j[1], j[2]) << "gantry Y joints";
    Pose back;
    ASSERT_EQ(k.forward(j, back), KinResult::Ok);
    ASSERT_LT(max_error(back, p), 1e-9) << "sample " << i;
  }
}

TEST(MatrixKins, ASingularMatrixIsReportedAndLeavesThePose) {
  MatrixKins k = make();
  k.c(1, 0).set(1.0);
  k.c(1, 1).set(0.0);  // joint Y = pose X, like joint X: no inverse
  const double j[3] = {1, 2, 3};
  Pose p;
  p[Axis::X] = 42;
  EXPECT_EQ(k.forward(j, p), KinResult::Singular);
  EXPECT_EQ(p[Axis::X], 42) << "no new output on failure";
  double out[3] = {0, 0, 0};
  const double hint[3] = {7, 8, 9};
  EXPECT_EQ(k.inverse(p, hint, out), KinResult::Singular);
  EXPECT_EQ(out[0], 7) << "inverse failures hand back the hint";
}
