#include "commission/comp_camera.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <stdexcept>

#ifdef CNC_COMMISSION_CAMERA
#include "vision/camera.hpp"
#include "vision/scale_reader.hpp"
#endif

namespace cnc::commission {

#ifdef CNC_COMMISSION_CAMERA
StopReader camera_reader(std::shared_ptr<vision::FrameSource> camera, const CameraOptions& o) {
  if (!(o.pitch_mm > 0) || !(o.um_per_px > 0))
    throw std::invalid_argument("camera: the scale's pitch and the pixel scale must be > 0");
  if (o.sign != 1 && o.sign != -1) throw std::invalid_argument("camera: the scale's sign is +1 or -1");
  if (o.frames < 1 || o.frames > 100) throw std::invalid_argument("camera: frames per reading: 1 to 100");
  if (std::string e = camera->check(); !e.empty()) throw std::runtime_error(e);
  struct Track {
    std::optional<double> scale, target;  // the last reading's scale coordinate and its stop's target
  };
  auto track = std::make_shared<Track>();
  vision::ScaleGeometry g;
  g.pitch_mm = o.pitch_mm;
  g.um_per_px = o.um_per_px;
  return [camera, o, g, track](double target_mm) {
    // Expected scale coordinate: from the last reading and the travel
    // commanded since, or at the first from the scale's position at 0.
    const double coarse = track->scale ? *track->scale + o.sign * (target_mm - *track->target)
                                       : o.scale_at_zero_mm + o.sign * target_mm;
    double sum = 0;
    for (int i = 0; i < o.frames; ++i) {
      const vision::Frame f = camera->grab();
      if (!f.ok()) throw std::runtime_error(f.error.empty() ? camera->name() + ": empty frame" : f.error);
      const vision::ScaleReading r = vision::read_scale(f.image);
      if (!r.ok) throw std::runtime_error(camera->name() + ": " + r.reason);
      sum += vision::scale_position_mm(r, g, coarse);
    }
    const double scale = sum / o.frames;
    track->scale = scale;
    track->target = target_mm;
    return o.sign * (scale - o.scale_at_zero_mm);
  };
}

namespace {
// "exec:COMMAND": a program that takes one picture per grab (a camera's
// own capture tool, or the simulated camera), run through the shell with
// the image file to write appended as its last argument.
class CommandSource : public vision::FrameSource {
 public:
  explicit CommandSource(std::string command)
      : command_(std::move(command)),
        file_(std::filesystem::temp_directory_path() /
              ("cnc-commission-camera-" + std::to_string(::getpid()) + ".png")) {}
  ~CommandSource() override {
    std::error_code ec;
    std::filesystem::remove(file_, ec);
  }
  vision::Frame grab() override {
    std::error_code ec;
    std::filesystem::remove(file_, ec);
    const std::string quoted = "'" + file_.string() + "'";
    const int st = std::system((command_ + " " + quoted + " >/dev/null").c_str());
    vision::Frame f;
    if (st != 0) {
      f.error = name() + ": the command ended with status " +
                std::to_string(WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st));
      return f;
    }
    if (!std::filesystem::exists(file_)) {
      f.error = name() + ": the command wrote no image to " + file_.string();
      return f;
    }
    return vision::ImageSource(file_).grab();
  }
  std::string check() const override { return command_.empty() ? name() + ": no command" : ""; }
  std::string name() const override { return "camera exec:" + command_; }

 private:
  std::string command_;
  std::filesystem::path file_;
};
}  // namespace

StopReader camera_reader(const CameraOptions& o) {
  if (o.source.rfind("exec:", 0) == 0) return camera_reader(std::make_shared<CommandSource>(o.source.substr(5)), o);
  return camera_reader(std::shared_ptr<vision::FrameSource>(vision::open_source(o.source)), o);
}
#else
StopReader camera_reader(std::shared_ptr<vision::FrameSource>, const CameraOptions& o) {
  throw std::runtime_error("camera " + o.source + ": this build has no camera support (comp/'s camera library, OpenCV)");
}
StopReader camera_reader(const CameraOptions& o) {
  throw std::runtime_error("camera " + o.source + ": this build has no camera support (comp/'s camera library, OpenCV)");
}
#endif

}  // namespace cnc::commission
