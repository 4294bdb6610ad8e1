// The ISO 230-2 cycle with the camera as the measurement source, on one
// axis of the drive simulator's plant read by the simulated camera: the
// closed loop (measure, fit, compensate, measure again) beside the same
// loop with perfect measurements, and the cycle stopping with a reason and
// keeping what it measured when the camera fails.
#include <gtest/gtest.h>

#include <cstdio>

#include "tests/vision/camera_loop.hpp"

using namespace cnc;

TEST(CameraCycle, ClosedLoopOnThePlantCompensatesAsWellAsPerfectMeasurements) {
  const auto r = cnc::testing::run_camera_loop();
  ASSERT_EQ(r.error, "");
  std::printf("ISO 230-2 (um)            A      E      B\n");
  std::printf("perfect before      %6.2f %6.2f %6.2f\n", r.true_before.A, r.true_before.E, r.true_before.B);
  std::printf("camera before       %6.2f %6.2f %6.2f\n", r.before.A, r.before.E, r.before.B);
  std::printf("camera after        %6.2f %6.2f %6.2f\n", r.after.A, r.after.E, r.after.B);
  std::printf("true after (camera) %6.2f %6.2f %6.2f\n", r.true_after.A, r.true_after.E, r.true_after.B);
  std::printf("perfect after       %6.2f %6.2f %6.2f\n", r.perfect_after.A, r.perfect_after.E, r.perfect_after.B);
  std::printf("worst reading sigma %.3f px, %d frames\n", r.worst_sigma_px, r.frames);
  // The camera sees what the perfect measurement sees.
  EXPECT_NEAR(r.before.A, r.true_before.A, 1.0);
  EXPECT_NEAR(r.before.E, r.true_before.E, 1.0);
  EXPECT_GT(r.true_before.A, 10) << "the plant starts visibly inaccurate";
  // Compensated from camera readings: as good as from perfect ones, within a micrometre.
  EXPECT_LE(r.true_after.A, 0.3 * r.true_before.A);
  EXPECT_LE(r.true_after.A, r.perfect_after.A + 1.0);
  EXPECT_LE(r.true_after.E, r.perfect_after.E + 1.0);
}

namespace {
struct Rig {
  comp::CameraCycleOptions o = cnc::testing::camera_loop_options();
  vision::sim::PlantAxis axis{cnc::testing::camera_loop_plant(), {}};
  vision::sim::SimulatedScaleCamera camera{cnc::testing::camera_loop_scene(), [this] { return axis.table_mm(); },
                                           o.scale_at_zero_mm};
};
}  // namespace

TEST(CameraCycle, ACameraDisconnectingMidCycleStopsTheCycleAndKeepsWhatItMeasured) {
  Rig rig;
  rig.camera.disconnect_after(17);
  const auto r = comp::run_camera_cycle(rig.axis, rig.camera, rig.o);
  EXPECT_EQ(r.measurement.points.size(), 17u);
  EXPECT_GT(r.planned, 17);
  EXPECT_NE(r.error.find("run 1 down: simulated camera: no frame (the camera stopped delivering images: disconnected?)"),
            std::string::npos)
      << r.error;
  // What it kept is a valid measurement file.
  EXPECT_EQ(comp::parse_measurement(comp::format_measurement(r.measurement), "kept.csv").points.size(), 17u);
}

TEST(CameraCycle, AnImageWithoutAScaleStopsTheCycleWithTheReaderReason) {
  Rig rig;
  rig.camera.set_blank(true);
  const auto r = comp::run_camera_cycle(rig.axis, rig.camera, rig.o);
  EXPECT_TRUE(r.measurement.points.empty());
  EXPECT_NE(r.error.find("target 5.000, run 1 up: simulated camera: no scale in view"), std::string::npos) << r.error;
}

TEST(CameraCycle, NoCameraStopsTheCycleBeforeAnythingMoves) {
  Rig rig;
  vision::CameraSettings s;
  s.device = "/dev/video-not-there";
  vision::VideoCaptureSource none(s);
  const auto r = comp::run_camera_cycle(rig.axis, none, rig.o);
  EXPECT_TRUE(r.measurement.points.empty());
  EXPECT_EQ(r.error,
            "before the first move: camera /dev/video-not-there: no such device (is the camera plugged in? ls "
            "/dev/video*)");
  EXPECT_EQ(rig.axis.seconds(), 0) << "the axis moved";
}

namespace {
// A move that fails half-way through the cycle (a following error, the
// machine switched off).
struct FailingAxis : comp::Positioner {
  comp::Positioner& inner;
  int moves_left;
  FailingAxis(comp::Positioner& p, int n) : inner(p), moves_left(n) {}
  std::string move_to(double x) override { return moves_left-- > 0 ? inner.move_to(x) : "the machine is off or in E-stop"; }
  void settle(double s) override { inner.settle(s); }
};
}  // namespace

TEST(CameraCycle, AFailingMoveStopsTheCycleNamingTheTargetAndKeepsWhatItMeasured) {
  Rig rig;
  FailingAxis axis(rig.axis, 4);  // the approach and three targets
  const auto r = comp::run_camera_cycle(axis, rig.camera, rig.o);
  EXPECT_EQ(r.measurement.points.size(), 3u);
  EXPECT_NE(r.error.find("run 1 up: move: the machine is off or in E-stop"), std::string::npos) << r.error;
}
