// Where images come from: a camera through cv::VideoCapture on a V4L2
// device (resolution and exposure set when it opens), an image file, or a
// folder of images taken in order (offline work, recorded cycles). Every
// source says why a frame is missing: a camera that cannot be opened, one
// that stops delivering frames (unplugged mid-cycle), a folder that ran
// out of images. Offline: never called from the servo thread.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

namespace cnc::vision {

// One grab: an image (8-bit, grey or BGR) or, when empty, the reason.
struct Frame {
  cv::Mat image;
  std::string error;
  bool ok() const noexcept { return error.empty() && !image.empty(); }
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual Frame grab() = 0;
  // Why the source cannot deliver, when that is known before a grab (a
  // camera that did not open, a missing folder); "" otherwise.
  virtual std::string check() const { return ""; }
  // What the source is, for messages ("camera /dev/video0", "folder shots/").
  virtual std::string name() const = 0;
};

struct CameraSettings {
  std::string device = "/dev/video0";  // or a number: /dev/videoN
  int width = 0, height = 0;           // 0: the camera's default
  double exposure = 0;                 // > 0: manual exposure, in the driver's units (V4L2: 100 us)
  int discard = 2;                     // frames thrown away after opening and before each grab (stale buffers)
};

// A V4L2 camera. Opening failures are reported by the first grab() (and
// by error()), so that a cycle can stop with the reason.
class VideoCaptureSource : public FrameSource {
 public:
  explicit VideoCaptureSource(const CameraSettings& s);
  Frame grab() override;
  std::string name() const override { return "camera " + s_.device; }
  std::string check() const override { return open_error_; }

 private:
  CameraSettings s_;
  cv::VideoCapture cap_;
  std::string open_error_;
};

// An image file (every grab returns it) or a folder (its .png/.jpg/.bmp/
// .tif files in name order, one per grab; an error once they are used up).
class ImageSource : public FrameSource {
 public:
  explicit ImageSource(const std::filesystem::path& path);
  Frame grab() override;
  std::string name() const override;
  std::string check() const override { return error_; }
  std::size_t size() const noexcept { return files_.size(); }

 private:
  std::filesystem::path path_;
  bool folder_ = false;
  std::vector<std::filesystem::path> files_;
  std::size_t next_ = 0;
  std::string error_;
};

// "file:PATH", "folder:PATH", "v4l2:/dev/videoN" or a bare path (a
// directory: folder; a /dev/ path: camera; else a file).
std::unique_ptr<FrameSource> open_source(const std::string& spec, const CameraSettings& settings = {});

// 8-bit single channel (converting colour and 16-bit images).
cv::Mat to_grey(const cv::Mat& image);

}  // namespace cnc::vision
