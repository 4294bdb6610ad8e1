// Camera calibration: the intrinsics (camera matrix and lens distortion)
// from views of a checkerboard or a circle grid (cv::calibrateCamera),
// undistortion of images with them, and their file (OpenCV YAML). The
// pixel scale at the measured surface comes from a known pitch
// (scale_reader.hpp, pixel_scale_um). Offline.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace cnc::vision {

enum class Pattern { Checkerboard, Circles };

struct PatternSpec {
  Pattern kind = Pattern::Checkerboard;
  int cols = 9, rows = 6;          // inner corners (checkerboard) or circles
  double spacing_mm = 5;           // square size or circle spacing
};

struct Intrinsics {
  cv::Mat camera;                  // 3x3
  cv::Mat distortion;              // k1 k2 p1 p2 k3
  cv::Size size;                   // image size they belong to
  double rms_px = 0;               // reprojection error of the calibration
  int views = 0;                   // images in which the pattern was found
  bool valid() const { return !camera.empty(); }
};

// Finds the pattern in each image (sub-pixel corners) and calibrates.
// Throws std::runtime_error when fewer than 3 images show it, saying
// which images did not, or when the images differ in size.
Intrinsics calibrate_intrinsics(const std::vector<cv::Mat>& images, const PatternSpec& p,
                                std::vector<std::string>* notes = nullptr);

cv::Mat undistort_image(const cv::Mat& image, const Intrinsics& k);
// A pixel of the distorted image where the undistorted image has it.
cv::Point2d undistort_point(const cv::Point2d& px, const Intrinsics& k);

void save_intrinsics(const std::filesystem::path& file, const Intrinsics& k);
// Throws std::runtime_error naming the file and the missing key.
Intrinsics load_intrinsics(const std::filesystem::path& file);

}  // namespace cnc::vision
