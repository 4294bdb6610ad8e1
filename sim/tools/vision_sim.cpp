// cnc-vision-sim: synthetic camera images with a known truth, for trying
// cnc-vision without a camera (docs/vision.md) and for recording test
// images. Prints the truth.
//   scale  --out FILE --at MM [--pitch MM] [--line MM] [--um-per-px UM] [--angle DEG] [--blur PX]
//          [--noise GREY] [--gradient F] [--vignetting F] [--k1 K] [--width W] [--height H] [--seed N] [--blank]
//   marker --out FILE --x MM --y MM [--angle DEG] --spindle X,Y --offset DX,DY --um-per-px UM [--rotation DEG]
//          [--id N] [--side MM] [--blur PX] [--noise GREY] [--seed N]
//   camera-cycle --min MM --max MM --out FILE.csv [--axis X] [--targets N] [--runs N] [--dwell S] [--feed MM/MIN]
//          [--pin NAME] [--disconnect-after N] [--blank] [-i INSTANCE]
//          the ISO 230-2 cycle on a running controller (cnc-comp camera's
//          positioner) measured by the simulated camera, which renders the
//          glass scale at the value of the HAL pin NAME (default: the
//          simulated X drive's true table position,
//          cia402-sim.0.node.01.table-position)
#include <cstdio>
#include <cstring>
#include <map>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "comp/ipc_positioner.hpp"
#include "core/ipc/admin.hpp"
#include "core/ipc/client.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/strings.hpp"
#include "sim/vision/camera.hpp"
#include "sim/vision/renderer.hpp"

using namespace cnc;
using namespace cnc::vision::sim;

namespace {

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr,
               "cnc-vision-sim: %s\n"
               "usage: cnc-vision-sim scale --out FILE --at MM [--pitch MM] [--line MM] [--um-per-px UM] [--angle DEG]\n"
               "         [--blur PX] [--noise GREY] [--gradient F] [--vignetting F] [--k1 K] [--width W] [--height H]\n"
               "         [--seed N] [--blank]\n"
               "       cnc-vision-sim marker --out FILE --x MM --y MM [--angle DEG] --spindle X,Y --offset DX,DY\n"
               "         --um-per-px UM [--rotation DEG] [--id N] [--side MM] [--blur PX] [--noise GREY] [--seed N]\n"
               "       cnc-vision-sim camera-cycle --min MM --max MM --out FILE.csv [--axis X] [--targets N] [--runs N]\n"
               "         [--dwell S] [--feed MM/MIN] [--pin NAME] [--disconnect-after N] [--blank] [-i INSTANCE]\n",
               why.c_str());
  std::exit(2);
}

struct Opts {
  std::map<std::string, std::string> v;
  bool has(const std::string& k) const { return v.count(k) > 0; }
  double num(const std::string& k, double def, bool required = false) const {
    const auto it = v.find(k);
    if (it == v.end()) {
      if (required) usage("--" + k + " is needed");
      return def;
    }
    const auto d = parse_double(it->second);
    if (!d) usage("--" + k + ": '" + it->second + "' is not a number");
    return *d;
  }
  std::pair<double, double> pair(const std::string& k) const {
    const auto it = v.find(k);
    if (it == v.end()) usage("--" + k + " X,Y is needed");
    const auto p = split(it->second, ',');
    const auto a = p.size() == 2 ? parse_double(p[0]) : std::nullopt;
    const auto b = p.size() == 2 ? parse_double(p[1]) : std::nullopt;
    if (!a || !b) usage("--" + k + ": '" + it->second + "' is not X,Y");
    return {*a, *b};
  }
};

void imaging(const Opts& o, Imaging& m) {
  m.width = static_cast<int>(o.num("width", m.width));
  m.height = static_cast<int>(o.num("height", m.height));
  m.blur_px = o.num("blur", m.blur_px);
  m.noise = o.num("noise", m.noise);
  m.gradient = o.num("gradient", m.gradient);
  m.vignetting = o.num("vignetting", m.vignetting);
  m.k1 = o.num("k1", m.k1);
  m.seed = static_cast<uint64_t>(o.num("seed", 1));
}

// The ISO cycle through the running controller, seen by the simulated camera.
int camera_cycle(const Opts& o) {
  comp::CameraCycleOptions c;
  c.cycle.x_min = o.num("min", 0, true);
  c.cycle.x_max = o.num("max", 0, true);
  const std::string axis = o.has("axis") ? o.v.at("axis") : "X";
  if (axis.size() != 1) usage("--axis: one letter");
  c.cycle.axis = axis[0];
  c.cycle.targets = static_cast<int>(o.num("targets", 0));
  c.cycle.runs = static_cast<int>(o.num("runs", 5));
  c.cycle.dwell_s = o.num("dwell", 0.2);
  c.cycle.feed_mm_min = o.num("feed", 3000);
  ScaleScene scene;
  scene.imaging.width = 320;
  scene.imaging.height = 240;
  scene.imaging.blur_px = 1.2;
  scene.imaging.gradient = 0.2;
  scene.imaging.vignetting = 0.15;
  scene.angle_deg = 1.5;
  scene.blank = o.has("blank");
  c.scale.pitch_mm = scene.pitch_mm;
  c.scale.um_per_px = scene.um_per_px;
  c.scale_at_zero_mm = 10;
  const std::string instance = o.has("instance") ? o.v.at("instance") : ipc::default_instance();
  const std::string pin = o.has("pin") ? o.v.at("pin") : "cia402-sim.0.node.01.table-position";
  ipc::Client client(instance);
  ipc::AdminClient hal(instance);
  std::string pin_error;
  SimulatedScaleCamera camera(
      scene,
      [&]() {
        const ipc::AdminReply r = hal.request("getp " + pin);
        const auto v = r.ok ? parse_double(trim(r.text)) : std::nullopt;
        if (!v) throw std::runtime_error("getp " + pin + ": " + r.text);
        return *v;
      },
      c.scale_at_zero_mm);
  if (o.has("disconnect-after")) camera.disconnect_after(static_cast<int>(o.num("disconnect-after", 0)));
  comp::IpcPositioner positioner(client, c.cycle.axis, c.cycle.feed_mm_min);
  return comp::report_camera_cycle(comp::run_camera_cycle(positioner, camera, c), o.v.at("out"));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) usage("a command is needed");
  const std::string cmd = argv[1];
  Opts o;
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "-i" && i + 1 < argc) {
      o.v["instance"] = argv[++i];
      continue;
    }
    if (s == "--blank") {
      o.v["blank"] = "1";
      continue;
    }
    if (s.rfind("--", 0) != 0 || i + 1 >= argc) usage("unexpected '" + s + "'");
    o.v[s.substr(2)] = argv[++i];
  }
  if (!o.has("out")) usage("--out FILE is needed");
  const std::string out = o.v["out"];
  if (cmd == "camera-cycle") {
    try {
      return camera_cycle(o);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "cnc-vision-sim: %s\n", e.what());
      return 1;
    }
  }
  cv::Mat img;
  if (cmd == "scale") {
    ScaleScene s;
    imaging(o, s.imaging);
    s.centre_mm = o.num("at", 0, true);
    s.pitch_mm = o.num("pitch", s.pitch_mm);
    s.line_mm = o.num("line", s.line_mm);
    s.um_per_px = o.num("um-per-px", s.um_per_px);
    s.angle_deg = o.num("angle", 0);
    s.blank = o.has("blank");
    img = render_scale(s);
    std::printf("truth: scale %.5f mm under the centre, graduation at %+.4f px from it\n", s.centre_mm,
                true_offset_px(s));
  } else if (cmd == "marker") {
    MarkerScene s;
    imaging(o, s.imaging);
    s.x_mm = o.num("x", 0, true);
    s.y_mm = o.num("y", 0, true);
    s.angle_deg = o.num("angle", 0);
    std::tie(s.spindle_x_mm, s.spindle_y_mm) = o.pair("spindle");
    std::tie(s.mount.offset_x_mm, s.mount.offset_y_mm) = o.pair("offset");
    s.mount.um_per_px = o.num("um-per-px", 0, true);
    s.mount.rotation_deg = o.num("rotation", 0);
    s.id = static_cast<int>(o.num("id", s.id));
    s.side_mm = o.num("side", s.side_mm);
    img = render_marker(s);
    std::printf("truth: marker %d at X %.4f Y %.4f mm, rotation %.4f deg\n", s.id, s.x_mm, s.y_mm, s.angle_deg);
  } else {
    usage("unknown command '" + cmd + "'");
  }
  if (!cv::imwrite(out, img)) {
    std::fprintf(stderr, "cnc-vision-sim: %s: cannot be written\n", out.c_str());
    return 1;
  }
  return 0;
}
