#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "commission/config_writer.hpp"
#include "commission/steps.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

State machine() {
  State s;
  s.interface = "virtual:w";
  for (int id : {1, 2}) {
    ScannedNode n;
    n.node_id = id;
    n.cia402 = true;
    n.encoder_increments = 10000;
    s.nodes.push_back(n);
  }
  assign_axis(s, 'X', 0, 1);
  assign_axis(s, 'Z', 1, 2);
  set_scaling(s, 'X', 5);
  set_scaling(s, 'Z', 4);
  apply_direction_test(s, 'Z', 5, 5, -2.5, true);  // reversed, half the counts
  return s;
}

std::string read(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(CommissionWriter, GeneratesDrivesWithTheMeasuredScalingAndDirection) {
  testing::TempDir dir;
  const auto files = generate_config(machine(), dir.path(), "m");
  ASSERT_GE(files.size(), 2u);
  const std::string& ini = files[0].content;
  EXPECT_NE(ini.find("COORDINATES = X Z"), std::string::npos);
  EXPECT_NE(ini.find("NODE = 1 2"), std::string::npos);
  // Z: 10000 counts per rev on a 4 mm lead; the table moved half as far as
  // the encoder said: twice the counts per mm, written as a 2 mm lead.
  EXPECT_NE(ini.find("[CIA402_DRIVE_1]"), std::string::npos);
  EXPECT_NE(ini.find("SCREW_LEAD = 2\nREVERSE = YES"), std::string::npos) << ini;
  EXPECT_NE(ini.find("SCREW_LEAD = 5\nREVERSE = NO"), std::string::npos) << ini;
  EXPECT_NE(files[1].content.find("net z-pos-fb cia402.0.drive.01.pos-fb => joint.1.motor-pos-fb"), std::string::npos);
}

TEST(CommissionWriter, WritesDisabledAxesAsDisabledOptionalDrivesAndRefusesGapsInTheJoints) {
  State s = machine();
  s.axis('Z')->enabled = false;
  testing::TempDir dir;
  const auto files = generate_config(s, dir.path(), "m");
  const std::string& ini = files[0].content;
  const auto z = ini.find("[CIA402_DRIVE_1]");
  ASSERT_NE(z, std::string::npos);
  EXPECT_NE(ini.find("DISABLED = YES", z), std::string::npos) << ini;
  EXPECT_EQ(ini.find("DISABLED = YES"), ini.find("DISABLED = YES", z)) << "X is not disabled";
  EXPECT_NE(ini.find("MANDATORY = NO", ini.find("[CANOPEN_NODE_2]")), std::string::npos);
  s.axes.erase(s.axes.begin());  // Z alone on joint 1: no joint 0
  EXPECT_THROW(generate_config(s, dir.path(), "m"), std::invalid_argument);
}

TEST(CommissionWriter, KeepsTheOldFilesAsBackupAndSkipsUnchangedOnes) {
  testing::TempDir dir;
  dir.write("m.ini", "old ini\n");
  const auto files = generate_config(machine(), dir.path(), "m");
  auto changed = write_config(files);
  EXPECT_EQ(changed.size(), files.size());
  EXPECT_EQ(read(dir / "m.ini.bak"), "old ini\n");
  EXPECT_EQ(read(dir / "m.ini"), files[0].content);
  changed = write_config(files);
  EXPECT_TRUE(changed.empty());
}

TEST(CommissionWriter, DiffShowsRemovedAndAddedLines) {
  const std::string d = diff_text("f.ini", "a\nb\nc\n", "a\nB\nc\nd\n");
  EXPECT_EQ(d, "--- f.ini\n+++ f.ini\n-b\n+B\n+d\n");
  EXPECT_EQ(diff_text("f.ini", "same\n", "same\n"), "");
}

TEST(CommissionWriter, TheWrittenConfigurationPassesTheStrictCheck) {
  const auto cncd = testing::binary_dir() / "bin/cncd";
  if (!std::filesystem::exists(cncd)) GTEST_SKIP() << "cncd not built";
  testing::TempDir dir;
  State s = machine();
  // The drives: simulated ones on the same in-process bus, as a site file.
  s.interface = "virtual:w";
  dir.write("drives.ini",
            "[CIA402_SIM]\nINTERFACE = virtual:w\nCLOCK = SERVO\nNODE = 1 2\n"
            "[CIA402_SIM_NODE_1]\nENCODER_COUNTS = 10000\n[CIA402_SIM_NODE_2]\nENCODER_COUNTS = 10000\n");
  dir.write("drives.hal", "loadrt cia402_sim sections=CIA402_SIM\n");
  dir.write("drives-run.hal", "addf cia402-sim.0.update servo-thread\n");
  s.ini_includes = {"drives.ini"};
  s.hal_before_bus = {"drives.hal"};
  s.hal_after_bus = {"drives-run.hal"};
  write_config(generate_config(s, dir.path(), "m"));
  std::string out;
  EXPECT_EQ(check_config(cncd, dir / "m.ini", out), 0) << out;
}

}  // namespace
}  // namespace cnc::commission
