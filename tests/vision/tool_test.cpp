// cnc-vision and cnc-vision-sim as a user runs them: a synthetic scale
// image read back with its position, a refused image, a missing camera, a
// fiducial turned into the G10 line, the operator declining to apply it,
// applying with --yes and no controller running.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include "tests/support/testing.hpp"

namespace {

using Output = cnc::testing::CommandOutput;

Output run(const std::string& tool, const std::string& args, const std::string& input = "") {
  std::string cmd = (cnc::testing::binary_dir() / "bin" / tool).string() + " " + args;
  if (!input.empty()) cmd = "printf '" + input + "' | " + cmd;
  return cnc::testing::run_shell(cmd);
}

}  // namespace

TEST(VisionTool, ReadsASyntheticScaleImageAndItsPosition) {
  cnc::testing::TempDir dir;
  const std::string img = (dir.path() / "scale.png").string();
  auto r = run("cnc-vision-sim", "scale --at 12.3456 --out " + img);
  ASSERT_EQ(r.code, 0) << r.text;
  r = run("cnc-vision", "read " + img + " --pitch 0.1 --at 12.3");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("pixel scale from the pitch: 2.500"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("scale position under the centre: 12.345"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("(graduation 123)"), std::string::npos) << r.text;
}

TEST(VisionTool, AnImageWithoutAScaleIsRefusedWithTheReason) {
  cnc::testing::TempDir dir;
  const std::string img = (dir.path() / "blank.png").string();
  ASSERT_EQ(run("cnc-vision-sim", "scale --at 1 --blank --out " + img).code, 0);
  const auto r = run("cnc-vision", "read " + img);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("frame 1: refused: no scale in view"), std::string::npos) << r.text;
}

TEST(VisionTool, AMissingCameraIsNamed) {
  const auto r = run("cnc-vision", "read /dev/video-not-there");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("camera /dev/video-not-there: no such device"), std::string::npos) << r.text;
}

TEST(VisionTool, FiducialGivesTheG10LineAndAppliesOnlyWhenConfirmed) {
  cnc::testing::TempDir dir;
  const std::string img = (dir.path() / "part.png").string();
  ASSERT_EQ(run("cnc-vision-sim", "marker --x 135.4 --y 37.7 --angle 12.5 --spindle 100,50 --offset 35,-12 "
                                  "--um-per-px 20 --out " + img)
                .code,
            0);
  const std::string args = "fiducial " + img + " --marker 7 --spindle 100,50 --offset 35,-12 --um-per-px 20 --p 2";
  auto r = run("cnc-vision", args);
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("G10 L2 P2 X135.400"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find(" Y37.700"), std::string::npos) << r.text;
  EXPECT_NE(r.text.find(" R12.5"), std::string::npos) << r.text;
  // The operator says no: nothing is sent.
  r = run("cnc-vision", args + " --apply -i vision-tool-test-none", "n\\n");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("to the controller? [y/N] not applied"), std::string::npos) << r.text;
  // --yes skips the question; no controller runs under this instance.
  r = run("cnc-vision", args + " --apply --yes -i vision-tool-test-none");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("controller not running"), std::string::npos) << r.text;
  EXPECT_EQ(r.text.find("[y/N]"), std::string::npos) << r.text;
}

TEST(VisionTool, AMissingMarkerIsNamed) {
  cnc::testing::TempDir dir;
  const std::string img = (dir.path() / "part.png").string();
  ASSERT_EQ(run("cnc-vision-sim", "marker --x 0 --y 0 --id 3 --spindle 0,0 --offset 0,0 --um-per-px 20 --out " + img)
                .code,
            0);
  const auto r = run("cnc-vision", "fiducial " + img + " --marker 7 --spindle 0,0 --offset 0,0 --um-per-px 20");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("marker 7 not in view (seen: 3)"), std::string::npos) << r.text;
}

TEST(VisionTool, CncCompCameraNamesAMissingCameraBeforeItNeedsTheController) {
  cnc::testing::TempDir dir;
  const std::string out = (dir.path() / "camera.csv").string();
  const auto r = run("cnc-comp", "camera --min 5 --max 45 --out " + out +
                                     " --camera /dev/video-not-there --pitch 0.1 --um-per-px 2.5 -i vision-tool-test-none");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("cnc-comp: camera /dev/video-not-there: no such device"), std::string::npos) << r.text;
  EXPECT_EQ(r.text.find("controller not running"), std::string::npos) << r.text;
}

TEST(VisionTool, CncCompCameraWithoutAControllerSaysSo) {
  cnc::testing::TempDir dir;
  const std::string img = (dir.path() / "scale.png").string();
  ASSERT_EQ(run("cnc-vision-sim", "scale --at 10 --out " + img).code, 0);
  const auto r = run("cnc-comp", "camera --min 5 --max 45 --out " + (dir.path() / "c.csv").string() + " --camera " +
                                     img + " --pitch 0.1 --um-per-px 2.5 -i vision-tool-test-none");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("controller not running"), std::string::npos) << r.text;
}
