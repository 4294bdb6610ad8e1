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

}  // namespace
}  // namespace cnc::commission
