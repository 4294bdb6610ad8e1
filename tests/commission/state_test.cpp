#include <gtest/gtest.h>

#include "commission/state.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

TEST(CommissionState, SurvivesASaveAndLoad) {
  testing::TempDir dir;
  State s;
  s.interface = "socketcan:can0";
  ScannedNode n;
  n.node_id = 3;
  n.vendor_id = 0xCC1;
  n.supported_modes = 0x3A0;
  n.encoder_increments = 131072;
  n.problems.push_back("something");
  s.nodes.push_back(n);
  Axis a;
  a.letter = 'Y';
  a.joint = 1;
  a.node = 3;
  a.scaling.encoder_counts = 131072;
  a.scaling.screw_lead = 5;
  a.scaling.correction = 0.5;
  a.scaling.reverse = true;
  DirectionTest t;
  t.dial_mm = -2.5;
  t.has_dial = true;
  a.direction = t;
  s.axes.push_back(a);
  s.hal_after_bus.push_back("after.hal");
  save_state(s, dir / "c.json");
  const State r = load_state(dir / "c.json");
  EXPECT_EQ(r.interface, "socketcan:can0");
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_EQ(r.nodes[0].node_id, 3);
  EXPECT_EQ(r.nodes[0].supported_modes.value_or(0), 0x3A0u);
  EXPECT_EQ(r.nodes[0].encoder_increments.value_or(0), 131072u);
  EXPECT_FALSE(r.nodes[0].statusword.has_value());
  ASSERT_EQ(r.axes.size(), 1u);
  EXPECT_EQ(r.axes[0].letter, 'Y');
  EXPECT_TRUE(r.axes[0].scaling.reverse);
  EXPECT_DOUBLE_EQ(r.axes[0].scaling.counts_per_mm(), 131072.0 / 5 * 0.5);
  ASSERT_TRUE(r.axes[0].direction.has_value());
  EXPECT_DOUBLE_EQ(r.axes[0].direction->dial_mm, -2.5);
  EXPECT_EQ(r.hal_after_bus, std::vector<std::string>{"after.hal"});
}

TEST(CommissionState, KeepsAGantryPairsSecondDriveAndRefusesTheOldPartnerName) {
  testing::TempDir dir;
  State s;
  Axis a;
  a.letter = 'Y';
  a.joint = 1;
  a.node = 2;
  a.gantry = GantryDrive{3, 0, 2, true};
  s.axes.push_back(a);
  save_state(s, dir / "g.json");
  const State r = load_state(dir / "g.json");
  ASSERT_EQ(r.axes.size(), 1u);
  ASSERT_TRUE(r.axes[0].gantry.has_value());
  EXPECT_EQ(r.axes[0].gantry->node, 3);
  EXPECT_EQ(r.axes[0].gantry->joint, 2);
  EXPECT_TRUE(r.axes[0].gantry->reverse);
  // A file of the version that only recorded a partner's name: it named no
  // drive, so it is refused saying how to assign the pair.
  const auto old = dir.write("old.json", R"({"version": 1, "axes": [{"letter": "Y", "gantry_with": "Y2"}]})");
  try {
    (void)load_state(old);
    FAIL() << "the partner's name was dropped silently";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("axes[].gantry_with \"Y2\""), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--gantry-node"), std::string::npos) << e.what();
  }
  const auto none = dir.write("none.json", R"({"version": 1, "axes": [{"letter": "Y", "gantry_with": ""}]})");
  EXPECT_FALSE(load_state(none).axes[0].gantry.has_value());
}

TEST(CommissionState, AMissingFileIsAFreshState) {
  testing::TempDir dir;
  const State s = load_state(dir / "none.json");
  EXPECT_TRUE(s.nodes.empty());
  EXPECT_TRUE(s.axes.empty());
}

TEST(CommissionState, ABrokenFileIsRefusedNamingTheFile) {
  testing::TempDir dir;
  const auto p = dir.write("bad.json", "{ not json");
  try {
    (void)load_state(p);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos) << e.what();
  }
}

TEST(CommissionState, AnotherVersionIsRefused) {
  testing::TempDir dir;
  const auto p = dir.write("v.json", "{\"version\": 99}");
  EXPECT_THROW((void)load_state(p), std::runtime_error);
}

}  // namespace
}  // namespace cnc::commission
