#include "vision/fiducial.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include <opencv2/aruco.hpp>

#include "vision/camera.hpp"

namespace cnc::vision {

namespace {

// Image offset (px) to a machine vector (mm).
cv::Point2d to_machine(const cv::Point2d& d_px, const CameraMount& m) {
  const double s = m.um_per_px / 1000;
  const double x = d_px.x * s, y = (m.y_down ? -d_px.y : d_px.y) * s;
  const double a = m.rotation_deg * M_PI / 180;
  return {x * std::cos(a) - y * std::sin(a), x * std::sin(a) + y * std::cos(a)};
}

}  // namespace

FiducialPose locate_fiducial(const cv::Mat& image, int id, const CameraMount& mount, double spindle_x_mm,
                             double spindle_y_mm, const Intrinsics* intrinsics, int dictionary) {
  FiducialPose r;
  if (image.empty()) {
    r.reason = "empty image";
    return r;
  }
  const cv::Mat grey = to_grey(image);
  const auto dict = cv::aruco::getPredefinedDictionary(
      static_cast<cv::aruco::PREDEFINED_DICTIONARY_NAME>(dictionary == 0 ? cv::aruco::DICT_4X4_50 : dictionary));
  auto params = cv::aruco::DetectorParameters::create();
  params->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  params->cornerRefinementWinSize = 5;
  params->cornerRefinementMinAccuracy = 0.01;
  std::vector<std::vector<cv::Point2f>> corners, rejected;
  std::vector<int> ids;
  cv::aruco::detectMarkers(grey, dict, corners, ids, params, rejected);
  int which = -1;
  if (id < 0) {
    if (ids.size() != 1) {
      r.reason = std::to_string(ids.size()) + " markers in view; name the one to use";
      return r;
    }
    which = 0;
  } else {
    for (std::size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] == id) which = static_cast<int>(i);
    }
    if (which < 0) {
      std::string seen;
      for (int i : ids) seen += (seen.empty() ? "" : " ") + std::to_string(i);
      r.reason = "marker " + std::to_string(id) + " not in view" + (seen.empty() ? " (no markers found)" : " (seen: " + seen + ")");
      return r;
    }
  }
  std::vector<cv::Point2d> c;
  for (const cv::Point2f& p : corners[which]) {
    c.push_back(intrinsics && intrinsics->valid() ? undistort_point(p, *intrinsics) : cv::Point2d(p));
  }
  r.id = ids[which];
  // Centre: where the diagonals cross (exact under perspective too).
  const cv::Point2d d1 = c[2] - c[0], d2 = c[3] - c[1];
  const double den = d1.x * d2.y - d1.y * d2.x;
  const double t = ((c[1].x - c[0].x) * d2.y - (c[1].y - c[0].y) * d2.x) / den;
  r.centre_px = c[0] + t * d1;
  const cv::Point2d centre(static_cast<double>(grey.cols - 1) / 2, static_cast<double>(grey.rows - 1) / 2);
  const cv::Point2d pos = to_machine(r.centre_px - centre, mount);
  r.x_mm = spindle_x_mm + mount.offset_x_mm + pos.x;
  r.y_mm = spindle_y_mm + mount.offset_y_mm + pos.y;
  // Top edge (corner 0 to 1) and bottom edge (3 to 2), averaged.
  const cv::Point2d top = to_machine((c[1] - c[0]) + (c[2] - c[3]), mount);
  r.angle_deg = std::atan2(top.y, top.x) * 180 / M_PI;
  r.side_mm = (cv::norm(c[1] - c[0]) + cv::norm(c[2] - c[1]) + cv::norm(c[3] - c[2]) + cv::norm(c[0] - c[3])) / 4 *
              mount.um_per_px / 1000;
  r.ok = true;
  return r;
}

std::string g10_line(int coordinate_system, const FiducialPose& p) {
  if (coordinate_system < 1 || coordinate_system > 9) {
    throw std::invalid_argument("coordinate system " + std::to_string(coordinate_system) + ": expected 1 (G54) to 9 (G59.3)");
  }
  char buf[128];
  std::snprintf(buf, sizeof buf, "G10 L2 P%d X%.4f Y%.4f R%.4f", coordinate_system, p.x_mm, p.y_mm, p.angle_deg);
  return buf;
}

}  // namespace cnc::vision
