#include "commission/comp_camera.hpp"

#include <cmath>
#include <optional>
#include <stdexcept>

#ifdef CNC_COMMISSION_CAMERA
#include "vision/camera.hpp"
#include "vision/scale_reader.hpp"
#endif
#ifdef CNC_COMMISSION_SIM_CAMERA
#include "core/ipc/admin.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/strings.hpp"
#include "sim/vision/camera.hpp"
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

StopReader camera_reader(const CameraOptions& o) {
  if (o.source.rfind("sim:", 0) == 0) {
#ifdef CNC_COMMISSION_SIM_CAMERA
    const std::string pin = o.source.substr(4);
    auto hal = std::make_shared<ipc::AdminClient>(ipc::default_instance());
    vision::sim::ScaleScene scene;
    scene.pitch_mm = o.pitch_mm;
    scene.um_per_px = o.um_per_px;
    scene.imaging.width = 320;  // enough graduations (80 at 0.1 mm, 2.5 um/px), quick to render and read
    scene.imaging.height = 240;
    auto camera = std::make_shared<vision::sim::SimulatedScaleCamera>(
        scene,
        [hal, pin]() {
          const ipc::AdminReply r = hal->request("getp " + pin);
          const auto v = r.ok ? parse_double(trim(r.text)) : std::nullopt;
          if (!v) throw std::runtime_error("getp " + pin + ": " + r.text);
          return *v;
        },
        o.scale_at_zero_mm, o.sign);
    // The pin named now rather than at the first stop.
    if (const vision::Frame f = camera->grab(); !f.ok()) throw std::runtime_error(f.error);
    return camera_reader(camera, o);
#else
    throw std::runtime_error("camera " + o.source + ": this build has no camera simulator (sim/vision)");
#endif
  }
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
