// Step 8's camera source without a controller: the simulated camera
// (sim/vision) over a glass scale at a known table position at each stop
// of the ISO 230-2 cycle; the readings, made deviations as a laser's are,
// give the table's true deviations, also when the deviation grows beyond
// half the scale's pitch over the travel (the graduations are followed
// from stop to stop) and when the scale's position at 0 is off by
// millimetres; a missing camera, an image without a scale and a capture
// command that fails are named.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "commission/comp_camera.hpp"
#include "commission/compensation.hpp"
#include "sim/vision/camera.hpp"

namespace cnc::commission {
namespace {

Axis axis() {
  Axis a;
  a.letter = 'X';
  a.min_limit = -5;
  a.max_limit = 70;
  a.limits_source = "entered";
  a.max_velocity = 30;
  return a;
}

AxisCompensation cycle() {
  AxisCompensation c;
  c.x_min = 0;
  c.x_max = 60;
  c.targets = 5;
  c.runs = 2;
  c.feed_mm_min = 1200;
  return c;
}

// The table's true position at a stop: 2.037 mm off the scale's nominal
// zero, 0.1 % long (60 um over the cycle: more than half a pitch), 3 um of
// backlash each way and a 4 um wave.
double truth(const CycleStop& s) {
  return 2.037 + s.target * 1.001 + 0.003 * s.direction + 0.004 * std::sin(s.target / 10);
}

vision::sim::ScaleScene scene() {
  vision::sim::ScaleScene sc;
  sc.imaging.width = 320;
  sc.imaging.height = 240;
  sc.imaging.blur_px = 1.2;
  sc.angle_deg = 1.5;
  return sc;
}

TEST(CommissionCompCamera, ReadingsAtTheStopsGiveTheTablesDeviationsBeyondHalfAPitch) {
  const Axis a = axis();
  const auto stops = cycle_stops(a, cycle());
  ASSERT_GE(stops.size(), 20u);
  double table = 0;
  auto camera = std::make_shared<vision::sim::SimulatedScaleCamera>(scene(), [&table] { return table; }, 10.0);
  CameraOptions o;  // pitch 0.1 mm, 2.5 um/px, scale at 10 mm at axis 0: the scene's
  const StopReader read = camera_reader(camera, o);
  std::vector<double> readings;
  for (const CycleStop& s : stops) {
    table = truth(s);
    readings.push_back(read(s.target));
  }
  const auto points = points_from_readings(stops, readings);
  ASSERT_EQ(points.size(), stops.size());
  double worst = 0;
  for (std::size_t i = 0; i < stops.size(); ++i) {
    const double want_um = ((truth(stops[i]) - truth(stops[0])) - (stops[i].target - stops[0].target)) * 1000;
    worst = std::max(worst, std::fabs(points[i].deviation_um - want_um));
  }
  EXPECT_LT(worst, 0.5) << "um, the worst reading against the truth";
  const double last_um = points.back().deviation_um;  // back at the first target: backlash only
  EXPECT_NEAR(last_um, -6, 0.5);
  double largest = 0;
  for (const CompPoint& p : points) largest = std::max(largest, std::fabs(p.deviation_um));
  EXPECT_GT(largest, 50) << "the deviation grew beyond half a pitch";
}

TEST(CommissionCompCamera, AMissingCameraAndAnImageWithoutScaleAreNamed) {
  CameraOptions o;
  o.source = "/nonexistent/commission-camera-folder/";
  try {
    (void)camera_reader(o);
    FAIL() << "a missing camera accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/commission-camera-folder"), std::string::npos) << e.what();
  }
  auto sc = scene();
  sc.blank = true;
  auto camera = std::make_shared<vision::sim::SimulatedScaleCamera>(sc, [] { return 0.0; }, 10.0);
  const StopReader read = camera_reader(camera, CameraOptions{});
  try {
    (void)read(0);
    FAIL() << "an image without a scale read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("simulated camera: "), std::string::npos) << e.what();
  }
  o.frames = 0;
  EXPECT_THROW((void)camera_reader(camera, o), std::invalid_argument);
}

// exec:COMMAND, a program that takes one picture per reading: a command
// that fails or writes no image is named with what went wrong.
TEST(CommissionCompCamera, ACaptureCommandThatFailsOrWritesNoImageIsNamed) {
  CameraOptions o;
  o.source = "exec:exit 3;";
  try {
    (void)camera_reader(o)(0);
    FAIL() << "a failing capture command read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera exec:exit 3;: the command ended with status 3"), std::string::npos)
        << e.what();
  }
  o.source = "exec:true";
  try {
    (void)camera_reader(o)(0);
    FAIL() << "a command without an image read";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera exec:true: the command wrote no image"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cnc::commission
