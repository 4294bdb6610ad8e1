#include <gtest/gtest.h>

#include "core/hal/types.hpp"
#include "kinematics/trivkins.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const hal::HalError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(JointMap, GantryGivesTwoJointsToOneAxis) {
  const JointMap m = JointMap::parse("xyyz", "trivkins", true);
  EXPECT_EQ(m.num_joints(), 4);
  EXPECT_EQ(m.letters(), "XYYZ");
  EXPECT_EQ(m.axis_of(0), 0);
  EXPECT_EQ(m.axis_of(1), 1);
  EXPECT_EQ(m.axis_of(2), 1);
  EXPECT_EQ(m.axis_of(3), 2);
  EXPECT_EQ(m.axis_of(4), -1);
  EXPECT_EQ(m.first_joint(1), 1) << "forward kinematics read the first Y joint";
  EXPECT_EQ(m.first_joint(3), -1);
  EXPECT_EQ(m.axis_mask(), 0x7u);
}

TEST(JointMap, AxisMaskAsTheManualCountsIt) {
  // Manual 3.25.1: X and Z -> 0x5, XYZ -> 0x7, XYZB -> 0x17.
  EXPECT_EQ(JointMap::parse("XZ", "t", false).axis_mask(), 0x5u);
  EXPECT_EQ(JointMap::parse("XYZ", "t", false).axis_mask(), 0x7u);
  EXPECT_EQ(JointMap::parse("XYZB", "t", false).axis_mask(), 0x17u);
}

TEST(JointMap, BadCoordinatesAreRefusedWithTheReason) {
  EXPECT_EQ(error_of([] { JointMap::parse("XYQ", "trivkins", true); }),
            "trivkins: coordinates=XYQ: 'Q' is not an axis letter; expected letters from XYZABCUVW");
  EXPECT_EQ(error_of([] { JointMap::parse("", "trivkins", true); }),
            "trivkins: coordinates= is empty; expected letters from XYZABCUVW");
  EXPECT_EQ(error_of([] { JointMap::parse("XYYZ", "scarakins", false); }),
            "scarakins: coordinates=XYYZ: Y appears twice; this module gives each axis one joint");
  EXPECT_EQ(error_of([] { JointMap::parse("XYZA", "xyzac-trt-kins", true, "XYZAC"); }),
            "xyzac-trt-kins: coordinates=XYZA lacks C; this module needs XYZAC");
  EXPECT_NE(error_of([] { JointMap::parse("XYZABCUVWXYZABCUV", "trivkins", true); }).find("at most 16"),
            std::string::npos);
}

TEST(TrivKins, InverseCopiesEachAxisToItsJointsAndForwardReadsTheFirst) {
  TrivKins k(JointMap::parse("XYYZA", "trivkins", true), KinematicsType::Both);
  Pose p;
  p[Axis::X] = 1;
  p[Axis::Y] = 2;
  p[Axis::Z] = 3;
  p[Axis::A] = 45;
  p[Axis::B] = 7;  // not on this machine
  double j[5] = {};
  ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_EQ(j[0], 1);
  EXPECT_EQ(j[1], 2);
  EXPECT_EQ(j[2], 2);
  EXPECT_EQ(j[3], 3);
  EXPECT_EQ(j[4], 45);

  const double fb[5] = {1, 2, 2.001, 3, 45};  // the second Y lags while squaring
  Pose out;
  ASSERT_EQ(k.forward(fb, out), KinResult::Ok);
  EXPECT_EQ(out[Axis::Y], 2);
  EXPECT_EQ(out[Axis::B], 0) << "absent axes read 0";
  EXPECT_EQ(out[Axis::A], 45);
}

TEST(TrivKins, TypeAndJointAxesFollowTheArguments) {
  TrivKins k(JointMap::parse("XYYZ", "trivkins", true), KinematicsType::Both);
  EXPECT_EQ(k.type(), KinematicsType::Both);
  EXPECT_TRUE(k.requires_homing());
  EXPECT_EQ(k.num_joints(), 4);
  EXPECT_EQ(k.joint_axis(2), 1);
  EXPECT_EQ(k.joint_coordinate(2), 1);
  EXPECT_FALSE(k.switch_to(1)) << "trivkins has no second type";
  EXPECT_TRUE(k.switch_to(0));
  EXPECT_EQ(k.active_switch(), 0);

  TrivKins id(JointMap::parse("XYZ", "trivkins", false), KinematicsType::Identity);
  EXPECT_FALSE(id.requires_homing());
  EXPECT_STREQ(id.name(), "trivkins");
}

TEST(TrivKins, KinstypeReadsLinuxCncLettersAndWords) {
  EXPECT_EQ(parse_kinstype("1", "t"), KinematicsType::Identity);
  EXPECT_EQ(parse_kinstype("identity", "t"), KinematicsType::Identity);
  EXPECT_EQ(parse_kinstype("B", "t"), KinematicsType::Both);
  EXPECT_EQ(parse_kinstype("both", "t"), KinematicsType::Both);
  EXPECT_EQ(parse_kinstype("f", "t"), KinematicsType::ForwardOnly);
  EXPECT_EQ(parse_kinstype("I", "t"), KinematicsType::InverseOnly);
  EXPECT_EQ(error_of([] { parse_kinstype("x", "trivkins"); }),
            "trivkins: kinstype=x: expected 1 (identity), B (both), F (forward only) or I (inverse only)");
}

TEST(KinResult, EveryResultReads) {
  for (KinResult r : {KinResult::Ok, KinResult::Unreachable, KinResult::Singular, KinResult::JointLimit,
                      KinResult::NotConverged}) {
    EXPECT_STRNE(to_string(r), "unknown kinematics result");
  }
}
