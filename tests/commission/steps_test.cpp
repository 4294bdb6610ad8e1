#include <gtest/gtest.h>

#include "commission/state.hpp"
#include "commission/steps.hpp"

namespace cnc::commission {
namespace {

State scanned() {
  State s;
  s.interface = "virtual:t";
  for (int id : {1, 2, 3}) {
    ScannedNode n;
    n.node_id = id;
    n.device_type = 0x20192;
    n.supported_modes = 0x3A0;
    n.cia402 = true;
    n.encoder_increments = 10000;
    n.encoder_motor_revs = 1;
    n.gear_motor_revs = 1;
    n.gear_shaft_revs = 1;
    s.nodes.push_back(n);
  }
  s.nodes[2].fault = true;
  return s;
}

TEST(CommissionSteps, AssignTakesTheEncoderResolutionFromTheDrive) {
  State s = scanned();
  const Axis& a = assign_axis(s, 'X', 0, 1);
  EXPECT_EQ(a.node, 1);
  EXPECT_DOUBLE_EQ(a.scaling.encoder_counts, 10000);
}

TEST(CommissionSteps, AssignRefusesUnknownNodesFaultyDrivesAndDoubleUse) {
  State s = scanned();
  EXPECT_THROW(assign_axis(s, 'X', 0, 9), std::invalid_argument);   // not scanned
  EXPECT_THROW(assign_axis(s, 'X', 0, 3), std::invalid_argument);   // in fault
  assign_axis(s, 'X', 0, 1);
  EXPECT_THROW(assign_axis(s, 'Y', 1, 1), std::invalid_argument);   // node taken
  EXPECT_THROW(assign_axis(s, 'Y', 0, 2), std::invalid_argument);   // joint taken
  EXPECT_THROW(assign_axis(s, 'Q', 1, 2), std::invalid_argument);   // no such axis
  EXPECT_NO_THROW(assign_axis(s, 'Y', 1, 2));
}

TEST(CommissionSteps, ScalingComputesCountsPerMillimetreFromCountsGearAndLead) {
  State s = scanned();
  assign_axis(s, 'X', 0, 1);
  EXPECT_DOUBLE_EQ(set_scaling(s, 'X', 5.0), 2000.0);           // 10000 / 5
  EXPECT_DOUBLE_EQ(set_scaling(s, 'X', 5.0, 0, 3, 1), 6000.0);  // 3:1 gear
  EXPECT_DOUBLE_EQ(set_scaling(s, 'X', 4.0, 131072), 32768.0);
  EXPECT_THROW(set_scaling(s, 'X', 0), std::invalid_argument);
  EXPECT_THROW(set_scaling(s, 'Y', 5), std::invalid_argument);   // no drive
}

TEST(CommissionSteps, DirectionTestFlipsReverseWhenTheTableMovedAgainstTheCommand) {
  State s = scanned();
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5.0);
  const DirectionTest& t = apply_direction_test(s, 'X', 5.0, 5.0, -5.0, true);
  EXPECT_TRUE(t.reversed);
  EXPECT_TRUE(s.axis('X')->scaling.reverse);
  EXPECT_NEAR(s.axis('X')->scaling.counts_per_mm(), 2000.0, 1e-9);
}

TEST(CommissionSteps, DirectionTestCorrectsTheScaleByTheDialTravel) {
  State s = scanned();
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5.0);  // 2000 counts/mm assumed; the screw is really 10 mm: 1000
  apply_direction_test(s, 'X', 5.0, 5.0, 10.0, true);
  EXPECT_FALSE(s.axis('X')->scaling.reverse);
  EXPECT_NEAR(s.axis('X')->scaling.counts_per_mm(), 1000.0, 1e-9);
  // A second test at the corrected scaling finds it right.
  apply_direction_test(s, 'X', 5.0, 5.0, 5.0, true);
  EXPECT_NEAR(s.axis('X')->scaling.counts_per_mm(), 1000.0, 1e-9);
}

TEST(CommissionSteps, DirectionTestWithoutDialOnlyChecksTheDriveFollowed) {
  State s = scanned();
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5.0);
  const DirectionTest& t = apply_direction_test(s, 'X', 5.0, 5.0, 0, false);
  EXPECT_FALSE(t.has_dial);
  EXPECT_DOUBLE_EQ(s.axis('X')->scaling.counts_per_mm(), 2000.0);
}

TEST(CommissionSteps, DirectionTestRefusesAStuckTableOrADriveThatDidNotFollow) {
  State s = scanned();
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5.0);
  EXPECT_THROW(apply_direction_test(s, 'X', 5.0, 1.0, 5.0, true), std::invalid_argument);   // drive did not follow
  EXPECT_THROW(apply_direction_test(s, 'X', 5.0, 5.0, 0.001, true), std::invalid_argument); // table stuck
  EXPECT_DOUBLE_EQ(s.axis('X')->scaling.counts_per_mm(), 2000.0);
  EXPECT_FALSE(s.axis('X')->scaling.reverse);
}

// A gantry pair (issue 21): each drive's direction and scale are found on
// its own; a random machine may have its second motor turn the same way or
// the other way whatever the assignment said.
State gantry_pair() {
  State s = scanned();
  s.nodes[2].fault = false;
  assign_axis(s, 'Y', 0, 1, GantryDrive{2, 0, 1, false});
  set_scaling(s, 'Y', 5);
  return s;
}

TEST(CommissionSteps, GantrySecondDriveAgainstTheCommandFlipsOnlyItsOwnReverse) {
  State s = gantry_pair();
  // First side right, 0.5 % short of the command; second side moved the other way.
  apply_direction_test(s, 'Y', 2, 2, 1.99, true);
  apply_direction_test(s, 'Y', 2, 2, -2.0, true, true);
  const Axis& y = *s.axis('Y');
  EXPECT_FALSE(y.scaling.reverse);
  ASSERT_TRUE(y.gantry);
  EXPECT_TRUE(y.gantry->reverse);
  EXPECT_NEAR(y.scaling.correction, 2 / 1.99, 1e-12);
  EXPECT_DOUBLE_EQ(y.gantry->correction, 1.0);
  EXPECT_TRUE(y.gantry->dial_checked);
  const auto joints = machine_joints(s);
  ASSERT_EQ(joints.size(), 2u);
  EXPECT_FALSE(joints[0].axis.scaling.reverse);
  EXPECT_TRUE(joints[1].axis.scaling.reverse);
  EXPECT_NEAR(joints[0].axis.scaling.counts_per_mm(), 2000 * 2 / 1.99, 1e-9);
  EXPECT_DOUBLE_EQ(joints[1].axis.scaling.counts_per_mm(), 2000);
}

TEST(CommissionSteps, GantryFirstDriveFlippedKeepsTheSecondDrivesDirection) {
  State s = gantry_pair();
  s.axis('Y')->gantry->reverse = true;  // assigned --gantry-reverse: the second joint REVERSE YES
  apply_direction_test(s, 'Y', 2, 2, -2.02, true);  // the first drive ran backwards and 1 % long
  const auto joints = machine_joints(s);
  EXPECT_TRUE(joints[0].axis.scaling.reverse);
  EXPECT_TRUE(joints[1].axis.scaling.reverse) << "the second drive's direction was not tested: it stays";
  apply_direction_test(s, 'Y', 2, 2, 2.0, true, true);  // and it was right
  EXPECT_TRUE(machine_joints(s)[1].axis.scaling.reverse);
  EXPECT_NEAR(machine_joints(s)[0].axis.scaling.correction, 2 / 2.02, 1e-12);
  // A new nominal scaling starts both sides over.
  set_scaling(s, 'Y', 5);
  EXPECT_FALSE(s.axis('Y')->gantry->dial_checked);
  EXPECT_DOUBLE_EQ(s.axis('Y')->gantry->correction, 1.0);
  // The second side of a single-drive axis is refused.
  assign_axis(s, 'X', 2, 3);
  EXPECT_THROW(apply_direction_test(s, 'X', 2, 2, 2, true, true), std::invalid_argument);
}

TEST(CommissionSteps, GantryFindingsOfEachSideSurviveTheStateFile) {
  State s = gantry_pair();
  apply_direction_test(s, 'Y', 2, 2, -2.01, true, true);
  GantryDrive& g = *s.axis('Y')->gantry;
  g.switches = AxisSwitches{};
  g.switches->home.seen = true;
  g.switches->home.position = 12.5;
  g.homing = AxisHoming{};
  g.homing->home_offset = 12.75;
  g.squaring = 0.25;
  const State back = from_json_text(to_json_text(s), "test");
  const GantryDrive& b = *back.axis('Y')->gantry;
  EXPECT_TRUE(b.reverse);
  EXPECT_NEAR(b.correction, 2 / 2.01, 1e-12);
  ASSERT_TRUE(b.direction && b.switches && b.homing);
  EXPECT_DOUBLE_EQ(b.switches->home.position, 12.5);
  EXPECT_DOUBLE_EQ(b.homing->home_offset, 12.75);
  EXPECT_DOUBLE_EQ(b.squaring, 0.25);
  const Axis v = gantry_view(*back.axis('Y'));
  EXPECT_EQ(v.joint, 1);
  EXPECT_EQ(v.node, 2);
  EXPECT_DOUBLE_EQ(v.homing->home_offset, 12.75);
}

TEST(CommissionSteps, TheDrivesTorqueLimitComesFromTheScan) {
  State s = scanned();
  const Axis& x = assign_axis(s, 'X', 0, 1);
  EXPECT_FALSE(drive_max_torque_pct(s, x));
  s.nodes[0].max_torque = 2500;  // per thousand of rated
  EXPECT_DOUBLE_EQ(*drive_max_torque_pct(s, x), 250);
  EXPECT_EQ(from_json_text(to_json_text(s), "t").nodes[0].max_torque, std::optional<uint16_t>(2500));
}

}  // namespace
}  // namespace cnc::commission
