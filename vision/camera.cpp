#include "vision/camera.hpp"

#include <algorithm>
#include <cctype>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace cnc::vision {

namespace fs = std::filesystem;

VideoCaptureSource::VideoCaptureSource(const CameraSettings& s) : s_(s) {
  std::error_code ec;
  const bool numeric = !s.device.empty() && std::all_of(s.device.begin(), s.device.end(), ::isdigit);
  if (!numeric && !fs::exists(s.device, ec)) {
    open_error_ = name() + ": no such device (is the camera plugged in? ls /dev/video*)";
    return;
  }
  const bool opened = numeric ? cap_.open(std::stoi(s.device), cv::CAP_V4L2) : cap_.open(s.device, cv::CAP_V4L2);
  if (!opened || !cap_.isOpened()) {
    open_error_ = name() + ": cannot be opened as a V4L2 camera (busy, no permission: group video?)";
    return;
  }
  if (s.width > 0) cap_.set(cv::CAP_PROP_FRAME_WIDTH, s.width);
  if (s.height > 0) cap_.set(cv::CAP_PROP_FRAME_HEIGHT, s.height);
  if (s.exposure > 0) {
    cap_.set(cv::CAP_PROP_AUTO_EXPOSURE, 1);  // V4L2: 1 = manual
    cap_.set(cv::CAP_PROP_EXPOSURE, s.exposure);
  }
  const int w = static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_WIDTH));
  const int h = static_cast<int>(cap_.get(cv::CAP_PROP_FRAME_HEIGHT));
  if ((s.width > 0 && w != s.width) || (s.height > 0 && h != s.height)) {
    open_error_ = name() + ": asked for " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                  ", the camera gives " + std::to_string(w) + "x" + std::to_string(h);
  }
}

Frame VideoCaptureSource::grab() {
  Frame f;
  if (!open_error_.empty()) {
    f.error = open_error_;
    return f;
  }
  for (int i = 0; i <= s_.discard; ++i) {
    if (!cap_.read(f.image) || f.image.empty()) {
      f.image.release();
      f.error = name() + ": no frame (the camera stopped delivering images: disconnected?)";
      return f;
    }
  }
  return f;
}

namespace {
bool is_image(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), ::tolower);
  return e == ".png" || e == ".jpg" || e == ".jpeg" || e == ".bmp" || e == ".tif" || e == ".tiff" || e == ".pgm";
}
}  // namespace

ImageSource::ImageSource(const fs::path& path) : path_(path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    folder_ = true;
    for (const auto& e : fs::directory_iterator(path, ec)) {
      if (e.is_regular_file() && is_image(e.path())) files_.push_back(e.path());
    }
    std::sort(files_.begin(), files_.end());
    if (files_.empty()) error_ = name() + ": no images (.png, .jpg, .bmp, .tif, .pgm)";
  } else if (fs::is_regular_file(path, ec)) {
    files_.push_back(path);
  } else {
    error_ = name() + ": no such file or folder";
  }
}

std::string ImageSource::name() const { return (folder_ ? "folder " : "image ") + path_.string(); }

Frame ImageSource::grab() {
  Frame f;
  if (!error_.empty()) {
    f.error = error_;
    return f;
  }
  if (folder_ && next_ >= files_.size()) {
    f.error = name() + ": all " + std::to_string(files_.size()) + " images used";
    return f;
  }
  const fs::path& p = files_[folder_ ? next_++ : 0];
  f.image = cv::imread(p.string(), cv::IMREAD_UNCHANGED);
  if (f.image.empty()) f.error = p.string() + ": not an image OpenCV can read";
  return f;
}

std::unique_ptr<FrameSource> open_source(const std::string& spec, const CameraSettings& settings) {
  auto after = [&](const char* prefix) { return spec.substr(std::char_traits<char>::length(prefix)); };
  if (spec.rfind("v4l2:", 0) == 0) {
    CameraSettings s = settings;
    s.device = after("v4l2:");
    return std::make_unique<VideoCaptureSource>(s);
  }
  if (spec.rfind("file:", 0) == 0) return std::make_unique<ImageSource>(after("file:"));
  if (spec.rfind("folder:", 0) == 0) return std::make_unique<ImageSource>(after("folder:"));
  if (spec.rfind("/dev/", 0) == 0) {
    CameraSettings s = settings;
    s.device = spec;
    return std::make_unique<VideoCaptureSource>(s);
  }
  return std::make_unique<ImageSource>(spec);
}

cv::Mat to_grey(const cv::Mat& image) {
  cv::Mat g;
  if (image.channels() == 3) {
    cv::cvtColor(image, g, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, g, cv::COLOR_BGRA2GRAY);
  } else {
    g = image;
  }
  if (g.depth() == CV_16U) {
    cv::Mat e;
    g.convertTo(e, CV_8U, 1.0 / 256);
    return e;
  }
  if (g.depth() != CV_8U) {
    cv::Mat e;
    g.convertTo(e, CV_8U);
    return e;
  }
  return g;
}

}  // namespace cnc::vision
