// The vision module on synthetic images with a known truth (sim/vision):
// glass-scale reading and its refusals, pixel scale, graduation numbering,
// ArUco fiducials into machine coordinates and the G10 line, image and
// camera sources and their errors, intrinsic calibration.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sim/vision/renderer.hpp"
#include "tests/support/testing.hpp"
#include "vision/calibration.hpp"
#include "vision/camera.hpp"
#include "vision/fiducial.hpp"
#include "vision/scale_reader.hpp"

using namespace cnc::vision;
using cnc::vision::sim::ScaleScene;

namespace {

ScaleScene clean_scene(double centre_mm) {
  ScaleScene s;
  s.centre_mm = centre_mm;
  s.imaging.noise = 1;
  s.imaging.blur_px = 1;
  return s;
}

}  // namespace

TEST(ScaleReader, CleanImagesGiveTheGraduationWithinFiveHundredthsOfAPixel) {
  double ss = 0;
  int n = 0;
  for (int i = 0; i < 20; ++i) {
    ScaleScene s = clean_scene(12.3 + i * 0.0173);
    s.imaging.seed = i + 1;
    const ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
    ASSERT_TRUE(r.ok) << r.reason;
    const double e = r.offset_px - cnc::vision::sim::true_offset_px(s);
    EXPECT_LT(std::abs(e), 0.1) << "centre " << s.centre_mm;
    ss += e * e;
    ++n;
  }
  EXPECT_LT(std::sqrt(ss / n), 0.05);
}

TEST(ScaleReader, RotationGradientVignettingAndDistortionStayWithinATenthOfAPixel) {
  for (int i = 0; i < 10; ++i) {
    ScaleScene s = clean_scene(40.0 + i * 0.0231);
    s.angle_deg = -3 + 0.7 * i;
    s.imaging.noise = 3;
    s.imaging.blur_px = 1.5;
    s.imaging.gradient = 0.3;
    s.imaging.vignetting = 0.2;
    s.imaging.k1 = 0.03;
    s.imaging.seed = 100 + i;
    const ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
    ASSERT_TRUE(r.ok) << r.reason;
    EXPECT_NEAR(r.offset_px, cnc::vision::sim::true_offset_px(s), 0.1) << "angle " << s.angle_deg;
    EXPECT_NEAR(r.angle_deg, s.angle_deg, 0.2);
    EXPECT_GT(r.sigma_px, 0);
    EXPECT_LT(r.sigma_px, 0.1);
  }
}

TEST(ScaleReader, PixelScaleComesFromTheKnownPitch) {
  ScaleScene s = clean_scene(3.0);
  s.um_per_px = 2.5;
  s.angle_deg = 2;
  const ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
  ASSERT_TRUE(r.ok) << r.reason;
  EXPECT_NEAR(pixel_scale_um(r, 100), 2.5, 0.005);
}

TEST(ScaleReader, GraduationNumberComesFromTheCoarsePosition) {
  ScaleScene s = clean_scene(57.3042);
  const ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
  ASSERT_TRUE(r.ok) << r.reason;
  const ScaleGeometry g{0.1, 2.5, 1};
  long n = 0;
  // Coarse positions off by up to 0.04 mm (less than half a pitch) give the same answer.
  for (double coarse : {57.3042, 57.27, 57.34}) {
    EXPECT_NEAR(scale_position_mm(r, g, coarse, &n), 57.3042, 0.0002);
    EXPECT_EQ(n, 573);
  }
}

TEST(ScaleReader, RefusesABlurredImageSayingSo) {
  ScaleScene s = clean_scene(5.0);
  s.imaging.blur_px = 9;
  s.imaging.background = 250;
  s.imaging.dark = 0;
  const ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.reason.find("blurred"), std::string::npos) << r.reason;
}

TEST(ScaleReader, RefusesOverAndUnderExposure) {
  ScaleScene s = clean_scene(5.0);
  s.imaging.background = 400;  // clipped at 255
  s.imaging.dark = 200;
  ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.reason.find("over-exposed"), std::string::npos) << r.reason;
  s.imaging.background = 12;
  s.imaging.dark = 2;
  r = read_scale(cnc::vision::sim::render_scale(s));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.reason.find("under-exposed"), std::string::npos) << r.reason;
}

TEST(ScaleReader, RefusesAnImageWithoutAScale) {
  ScaleScene s = clean_scene(5.0);
  s.blank = true;
  ScaleReading r = read_scale(cnc::vision::sim::render_scale(s));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.reason.find("no scale in view"), std::string::npos) << r.reason;
  // Random texture: contrast but no graduations.
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG(5).fill(noise, cv::RNG::UNIFORM, 30, 220);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 4);
  cv::normalize(noise, noise, 30, 220, cv::NORM_MINMAX);
  r = read_scale(noise);
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.reason.empty());
}

TEST(Fiducial, MarkerPoseInMachineCoordinatesWithinMicrometresAndHundredthsOfADegree) {
  cnc::vision::sim::MarkerScene s;
  s.mount = {35.0, -12.0, 90.0, true, 20.0};
  s.spindle_x_mm = 100;
  s.spindle_y_mm = 50;
  s.x_mm = 135.4;
  s.y_mm = 37.7;
  s.angle_deg = 12.5;
  s.imaging.noise = 2;
  const FiducialPose p = locate_fiducial(cnc::vision::sim::render_marker(s), 7, s.mount, 100, 50);
  ASSERT_TRUE(p.ok) << p.reason;
  EXPECT_EQ(p.id, 7);
  EXPECT_NEAR(p.x_mm, 135.4, 0.005);
  EXPECT_NEAR(p.y_mm, 37.7, 0.005);
  EXPECT_NEAR(p.angle_deg, 12.5, 0.1);
  EXPECT_NEAR(p.side_mm, 4.0, 0.02);
  EXPECT_EQ(g10_line(1, p).substr(0, 12), "G10 L2 P1 X1");
}

TEST(Fiducial, TheG10LineCarriesPositionAndRotation) {
  FiducialPose p;
  p.x_mm = 12.5;
  p.y_mm = -3.25;
  p.angle_deg = 1.5;
  EXPECT_EQ(g10_line(2, p), "G10 L2 P2 X12.5000 Y-3.2500 R1.5000");
  EXPECT_THROW(g10_line(10, p), std::invalid_argument);
}

TEST(Fiducial, AMissingMarkerIsNamed) {
  cnc::vision::sim::MarkerScene s;
  s.id = 3;
  const FiducialPose p = locate_fiducial(cnc::vision::sim::render_marker(s), 7, s.mount, 0, 0);
  EXPECT_FALSE(p.ok);
  EXPECT_EQ(p.reason, "marker 7 not in view (seen: 3)");
}

TEST(ImageSource, AFolderGivesItsImagesInNameOrderThenSaysTheyAreUsedUp) {
  cnc::testing::TempDir dir;
  cv::imwrite((dir.path() / "b.png").string(), cv::Mat(4, 4, CV_8U, cv::Scalar(20)));
  cv::imwrite((dir.path() / "a.png").string(), cv::Mat(4, 4, CV_8U, cv::Scalar(10)));
  std::ofstream(dir.path() / "notes.txt") << "not an image";
  ImageSource src(dir.path());
  ASSERT_EQ(src.size(), 2u);
  EXPECT_EQ(src.grab().image.at<uint8_t>(0, 0), 10);
  EXPECT_EQ(src.grab().image.at<uint8_t>(0, 0), 20);
  const Frame f = src.grab();
  EXPECT_FALSE(f.ok());
  EXPECT_NE(f.error.find("all 2 images used"), std::string::npos) << f.error;
}

TEST(ImageSource, AMissingPathAndAnUnreadableFileAreNamed) {
  cnc::testing::TempDir dir;
  EXPECT_NE(ImageSource(dir.path() / "nothing").grab().error.find("no such file or folder"), std::string::npos);
  std::ofstream(dir.path() / "broken.png") << "not a png";
  const Frame f = ImageSource(dir.path() / "broken.png").grab();
  EXPECT_NE(f.error.find("broken.png: not an image OpenCV can read"), std::string::npos) << f.error;
}

TEST(VideoCaptureSource, AMissingDeviceSaysSoAtTheFirstGrab) {
  CameraSettings s;
  s.device = "/dev/video-not-there";
  VideoCaptureSource cam(s);
  const Frame f = cam.grab();
  EXPECT_FALSE(f.ok());
  EXPECT_EQ(f.error, "camera /dev/video-not-there: no such device (is the camera plugged in? ls /dev/video*)");
}

namespace {
// A checkerboard seen through a pinhole camera (no distortion) from a pose.
cv::Mat checkerboard_view(const cv::Matx33d& K, const cv::Vec3d& rvec, const cv::Vec3d& tvec) {
  const int squares_x = 10, squares_y = 7, px = 40;
  cv::Mat board(squares_y * px + 2 * px, squares_x * px + 2 * px, CV_8U, cv::Scalar(255));
  for (int y = 0; y < squares_y; ++y) {
    for (int x = 0; x < squares_x; ++x) {
      if ((x + y) % 2 == 0) board(cv::Rect(px + x * px, px + y * px, px, px)).setTo(0);
    }
  }
  // Board pixel -> board mm (5 mm squares) -> image: a homography.
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  const double mm = 5.0 / px;
  cv::Matx33d H(R(0, 0), R(0, 1), tvec[0], R(1, 0), R(1, 1), tvec[1], R(2, 0), R(2, 1), tvec[2]);
  const cv::Matx33d S(mm, 0, -px * mm, 0, mm, -px * mm, 0, 0, 1);  // inner corner (0,0) at the origin
  cv::Mat img;
  cv::warpPerspective(board, img, cv::Mat(K * H * S), cv::Size(640, 480), cv::INTER_AREA, cv::BORDER_CONSTANT,
                      cv::Scalar(128));
  return img;
}
}  // namespace

TEST(Calibration, CheckerboardViewsGiveTheFocalLengthAndTheFileLoadsBack) {
  const cv::Matx33d K(800, 0, 320, 0, 800, 240, 0, 0, 1);
  std::vector<cv::Mat> views;
  for (int i = 0; i < 6; ++i) {
    const cv::Vec3d r(0.25 * std::sin(i), 0.25 * std::cos(i * 1.3), 0.1 * i);
    views.push_back(checkerboard_view(K, r, cv::Vec3d(-20 + 2 * i, -15 + i, 160 + 10 * i)));
  }
  views.push_back(cv::Mat(480, 640, CV_8U, cv::Scalar(128)));  // a view without the board
  std::vector<std::string> notes;
  const Intrinsics k = calibrate_intrinsics(views, {Pattern::Checkerboard, 9, 6, 5.0}, &notes);
  EXPECT_EQ(k.views, 6);
  EXPECT_LT(k.rms_px, 0.5);
  EXPECT_NEAR(k.camera.at<double>(0, 0), 800, 16);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0], "pattern not found in image(s) 7");
  cnc::testing::TempDir dir;
  save_intrinsics(dir.path() / "camera.yml", k);
  const Intrinsics back = load_intrinsics(dir.path() / "camera.yml");
  EXPECT_DOUBLE_EQ(back.camera.at<double>(0, 0), k.camera.at<double>(0, 0));
  EXPECT_EQ(back.size, k.size);
  std::ofstream(dir.path() / "empty.yml") << "%YAML:1.0\n---\nwidth: 3\n";
  try {
    load_intrinsics(dir.path() / "empty.yml");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("empty.yml: no key camera_matrix"), std::string::npos) << e.what();
  }
}

TEST(Calibration, TooFewViewsSayWhichImagesLackedThePattern) {
  std::vector<cv::Mat> views(2, cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
  try {
    calibrate_intrinsics(views, {Pattern::Checkerboard, 9, 6, 5.0});
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("found in 0 of 2 images, needs at least 3 (not in image(s) 1, 2)"),
              std::string::npos)
        << e.what();
  }
}
