#include "vision/calibration.hpp"

#include <stdexcept>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/camera.hpp"

namespace cnc::vision {

Intrinsics calibrate_intrinsics(const std::vector<cv::Mat>& images, const PatternSpec& p,
                                std::vector<std::string>* notes) {
  const cv::Size pattern(p.cols, p.rows);
  std::vector<cv::Point3f> board;
  for (int r = 0; r < p.rows; ++r) {
    for (int c = 0; c < p.cols; ++c) {
      board.emplace_back(static_cast<float>(c * p.spacing_mm), static_cast<float>(r * p.spacing_mm), 0.f);
    }
  }
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> found;
  cv::Size size;
  std::string missing;
  for (std::size_t i = 0; i < images.size(); ++i) {
    const cv::Mat g = to_grey(images[i]);
    if (size.empty()) size = g.size();
    if (g.size() != size) {
      throw std::runtime_error("calibration image " + std::to_string(i + 1) + " is " + std::to_string(g.cols) + "x" +
                               std::to_string(g.rows) + ", the first is " + std::to_string(size.width) + "x" +
                               std::to_string(size.height));
    }
    std::vector<cv::Point2f> corners;
    bool ok = false;
    if (p.kind == Pattern::Checkerboard) {
      ok = cv::findChessboardCorners(g, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
      if (ok) {
        cv::cornerSubPix(g, corners, cv::Size(5, 5), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
      }
    } else {
      ok = cv::findCirclesGrid(g, pattern, corners, cv::CALIB_CB_SYMMETRIC_GRID);
    }
    if (!ok) {
      missing += (missing.empty() ? "" : ", ") + std::to_string(i + 1);
      continue;
    }
    object.push_back(board);
    found.push_back(corners);
  }
  if (notes && !missing.empty()) notes->push_back("pattern not found in image(s) " + missing);
  if (found.size() < 3) {
    throw std::runtime_error("calibration: the " + std::to_string(p.cols) + "x" + std::to_string(p.rows) +
                             " pattern was found in " + std::to_string(found.size()) + " of " +
                             std::to_string(images.size()) + " images, needs at least 3" +
                             (missing.empty() ? "" : " (not in image(s) " + missing + ")"));
  }
  Intrinsics k;
  std::vector<cv::Mat> rv, tv;
  k.rms_px = cv::calibrateCamera(object, found, size, k.camera, k.distortion, rv, tv);
  k.size = size;
  k.views = static_cast<int>(found.size());
  return k;
}

cv::Mat undistort_image(const cv::Mat& image, const Intrinsics& k) {
  cv::Mat out;
  cv::undistort(image, out, k.camera, k.distortion);
  return out;
}

cv::Point2d undistort_point(const cv::Point2d& px, const Intrinsics& k) {
  std::vector<cv::Point2d> in{px}, out;
  cv::undistortPoints(in, out, k.camera, k.distortion, cv::noArray(), k.camera);
  return out[0];
}

void save_intrinsics(const std::filesystem::path& file, const Intrinsics& k) {
  cv::FileStorage fs(file.string(), cv::FileStorage::WRITE);
  if (!fs.isOpened()) throw std::runtime_error(file.string() + ": cannot be written");
  fs << "camera_matrix" << k.camera << "distortion" << k.distortion << "width" << k.size.width << "height"
     << k.size.height << "rms_px" << k.rms_px << "views" << k.views;
}

Intrinsics load_intrinsics(const std::filesystem::path& file) {
  cv::FileStorage fs;
  try {
    fs.open(file.string(), cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(file.string() + ": not an OpenCV YAML file (" + e.msg + ")");
  }
  if (!fs.isOpened()) throw std::runtime_error(file.string() + ": cannot be read");
  Intrinsics k;
  for (const char* key : {"camera_matrix", "distortion", "width", "height"}) {
    if (fs[key].empty()) throw std::runtime_error(file.string() + ": no key " + key);
  }
  fs["camera_matrix"] >> k.camera;
  fs["distortion"] >> k.distortion;
  fs["width"] >> k.size.width;
  fs["height"] >> k.size.height;
  if (!fs["rms_px"].empty()) fs["rms_px"] >> k.rms_px;
  if (!fs["views"].empty()) fs["views"] >> k.views;
  if (k.camera.rows != 3 || k.camera.cols != 3) throw std::runtime_error(file.string() + ": camera_matrix is not 3x3");
  return k;
}

}  // namespace cnc::vision
