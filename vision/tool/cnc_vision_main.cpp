// cnc-vision: camera measurement from the command line (docs/vision.md).
//   read       reads the glass scale in images, a folder or a camera
//   calibrate  camera intrinsics from checkerboard / circle-grid images
//   fiducial   a part's origin and rotation from an ArUco marker, as the
//              G10 L2 line; --apply sends it to the running controller
//              after the operator confirms (or --yes)
#include <cstdio>
#include <iostream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "core/ipc/client.hpp"
#include "core/util/strings.hpp"
#include "vision/calibration.hpp"
#include "vision/camera.hpp"
#include "vision/fiducial.hpp"
#include "vision/scale_reader.hpp"

using namespace cnc;
using namespace cnc::vision;

namespace {

struct Usage : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* kUsage =
    "usage: cnc-vision <command> [options]\n"
    "  read      SOURCE [--pitch MM] [--um-per-px UM] [--at MM] [--frames N] [--bright-lines]\n"
    "            [--intrinsics FILE.yml] [--width W] [--height H] [--exposure E]\n"
    "            SOURCE: an image, a folder of images, or a camera (/dev/videoN)\n"
    "  calibrate FOLDER --cols N --rows N --spacing MM [--circles] --out FILE.yml\n"
    "  fiducial  SOURCE --spindle X,Y --offset DX,DY --um-per-px UM [--marker ID] [--rotation DEG]\n"
    "            [--y-up] [--intrinsics FILE.yml] [--p N] [--apply [--yes]] [-i INSTANCE]\n";

struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;
  std::vector<std::string> flags;
  bool flag(const std::string& f) const {
    for (const auto& x : flags) {
      if (x == f) return true;
    }
    return false;
  }
  std::optional<std::string> get(const std::string& k) const {
    const auto it = values.find(k);
    return it == values.end() ? std::nullopt : std::optional<std::string>(it->second);
  }
  double number(const std::string& k, std::optional<double> def = std::nullopt) const {
    const auto v = get(k);
    if (!v) {
      if (!def) throw Usage("--" + k + " is needed");
      return *def;
    }
    const auto d = parse_double(*v);
    if (!d) throw Usage("--" + k + ": '" + *v + "' is not a number");
    return *d;
  }
  std::pair<double, double> pair(const std::string& k) const {
    const auto v = get(k);
    if (!v) throw Usage("--" + k + " X,Y is needed");
    const auto parts = split(*v, ',');
    const auto a = parts.size() == 2 ? parse_double(parts[0]) : std::nullopt;
    const auto b = parts.size() == 2 ? parse_double(parts[1]) : std::nullopt;
    if (!a || !b) throw Usage("--" + k + ": '" + *v + "' is not X,Y");
    return {*a, *b};
  }
};

Args parse(int argc, char** argv, const std::vector<std::string>& flag_names, const std::vector<std::string>& known) {
  Args a;
  for (int i = 2; i < argc; ++i) {
    std::string s = argv[i];
    if (s == "-i") s = "--instance";
    if (s.rfind("--", 0) == 0 && s.size() > 2) {
      const std::string name = s.substr(2);
      bool is_flag = false;
      for (const auto& f : flag_names) is_flag |= f == name;
      if (is_flag) {
        a.flags.push_back(name);
        continue;
      }
      bool ok = false;
      for (const auto& k : known) ok |= k == name;
      if (!ok) throw Usage("unknown option " + s);
      if (i + 1 >= argc) throw Usage(s + " needs a value");
      a.values[name] = argv[++i];
    } else {
      a.positional.push_back(s);
    }
  }
  return a;
}

std::unique_ptr<FrameSource> source_of(const Args& a) {
  if (a.positional.size() != 1) throw Usage("one image, folder or camera is needed");
  CameraSettings s;
  s.width = static_cast<int>(a.number("width", 0));
  s.height = static_cast<int>(a.number("height", 0));
  s.exposure = a.number("exposure", 0);
  return open_source(a.positional[0], s);
}

int cmd_read(const Args& a) {
  auto src = source_of(a);
  const bool folder = dynamic_cast<ImageSource*>(src.get()) && dynamic_cast<ImageSource*>(src.get())->size() > 1;
  const int frames = static_cast<int>(a.number("frames", folder ? 1e9 : 1));
  ScaleReaderOptions ro;
  ro.dark_lines = !a.flag("bright-lines");
  std::optional<Intrinsics> k;
  if (const auto f = a.get("intrinsics")) k = load_intrinsics(*f);
  const bool have_pitch = a.get("pitch").has_value();
  const double pitch = a.number("pitch", 0);
  int refused = 0;
  for (int i = 0; i < frames; ++i) {
    Frame f = src->grab();
    if (!f.ok()) {
      if (folder && i > 0) break;  // the folder is used up
      std::fprintf(stderr, "cnc-vision: %s\n", f.error.c_str());
      return 1;
    }
    if (k) f.image = undistort_image(f.image, *k);
    const ScaleReading r = read_scale(f.image, ro);
    if (!r.ok) {
      std::printf("frame %d: refused: %s\n", i + 1, r.reason.c_str());
      ++refused;
      continue;
    }
    std::printf("frame %d: graduation at %+.4f px from the centre (sigma %.4f px), %d lines, pitch %.3f px, "
                "tilt %.3f deg, edges %.2f px, contrast %.0f\n",
                i + 1, r.offset_px, r.sigma_px, r.lines, r.pitch_px, r.angle_deg, r.edge_px, r.contrast);
    const double um_px = a.get("um-per-px") ? a.number("um-per-px") : have_pitch ? pixel_scale_um(r, pitch * 1000) : 0;
    if (have_pitch) std::printf("  pixel scale from the pitch: %.4f um/px\n", pixel_scale_um(r, pitch * 1000));
    if (have_pitch && a.get("at")) {
      long n = 0;
      const double s = scale_position_mm(r, {pitch, um_px, 1}, a.number("at"), &n);
      std::printf("  scale position under the centre: %.5f mm (graduation %ld)\n", s, n);
    }
  }
  return refused ? 1 : 0;
}

int cmd_calibrate(const Args& a) {
  if (a.positional.size() != 1) throw Usage("calibrate: one folder of images is needed");
  const auto out = a.get("out");
  if (!out) throw Usage("calibrate: --out FILE.yml is needed");
  ImageSource src(a.positional[0]);
  std::vector<cv::Mat> images;
  for (;;) {
    const Frame f = src.grab();
    if (!f.ok()) {
      if (images.empty()) throw std::runtime_error(f.error);
      break;
    }
    images.push_back(f.image);
  }
  PatternSpec p;
  p.kind = a.flag("circles") ? Pattern::Circles : Pattern::Checkerboard;
  p.cols = static_cast<int>(a.number("cols"));
  p.rows = static_cast<int>(a.number("rows"));
  p.spacing_mm = a.number("spacing");
  std::vector<std::string> notes;
  const Intrinsics k = calibrate_intrinsics(images, p, &notes);
  for (const auto& n : notes) std::printf("note: %s\n", n.c_str());
  save_intrinsics(*out, k);
  std::printf("%d views, reprojection error %.3f px, fx %.1f fy %.1f cx %.1f cy %.1f px, written to %s\n", k.views,
              k.rms_px, k.camera.at<double>(0, 0), k.camera.at<double>(1, 1), k.camera.at<double>(0, 2),
              k.camera.at<double>(1, 2), out->c_str());
  return 0;
}

int cmd_fiducial(const Args& a) {
  auto src = source_of(a);
  const Frame f = src->grab();
  if (!f.ok()) {
    std::fprintf(stderr, "cnc-vision: %s\n", f.error.c_str());
    return 1;
  }
  CameraMount m;
  std::tie(m.offset_x_mm, m.offset_y_mm) = a.pair("offset");
  m.um_per_px = a.number("um-per-px");
  m.rotation_deg = a.number("rotation", 0);
  m.y_down = !a.flag("y-up");
  const auto [sx, sy] = a.pair("spindle");
  std::optional<Intrinsics> k;
  if (const auto file = a.get("intrinsics")) k = load_intrinsics(*file);
  const FiducialPose p =
      locate_fiducial(f.image, static_cast<int>(a.number("marker", -1)), m, sx, sy, k ? &*k : nullptr);
  if (!p.ok) {
    std::fprintf(stderr, "cnc-vision: %s: %s\n", src->name().c_str(), p.reason.c_str());
    return 1;
  }
  const std::string line = g10_line(static_cast<int>(a.number("p", 1)), p);
  std::printf("marker %d at X %.4f Y %.4f mm, rotation %.4f deg, side %.3f mm\n%s\n", p.id, p.x_mm, p.y_mm,
              p.angle_deg, p.side_mm, line.c_str());
  if (!a.flag("apply")) return 0;
  if (!a.flag("yes")) {
    std::printf("Apply \"%s\" to the controller? [y/N] ", line.c_str());
    std::fflush(stdout);
    std::string answer;
    std::getline(std::cin, answer);
    if (answer != "y" && answer != "Y" && answer != "yes") {
      std::printf("not applied\n");
      return 1;
    }
  }
  ipc::Client c(a.get("instance").value_or(ipc::default_instance()));
  ipc::Command cmd;
  cmd.type = ipc::CommandType::TaskPlanExecute;
  cmd.i[0] = -1;
  cmd.text.assign(line);
  const ipc::CommandResult r = c.execute(cmd, std::chrono::seconds(10));
  if (r.state != ipc::CommandState::Done) {
    std::fprintf(stderr, "cnc-vision: the controller did not apply it: %s\n",
                 r.reason.empty() ? "no answer within 10 s" : r.reason.c_str());
    return 1;
  }
  std::printf("applied\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  const std::string cmd = argv[1];
  try {
    if (cmd == "read") {
      return cmd_read(parse(argc, argv, {"bright-lines"},
                            {"pitch", "um-per-px", "at", "frames", "intrinsics", "width", "height", "exposure"}));
    }
    if (cmd == "calibrate") return cmd_calibrate(parse(argc, argv, {"circles"}, {"cols", "rows", "spacing", "out"}));
    if (cmd == "fiducial") {
      return cmd_fiducial(parse(argc, argv, {"apply", "yes", "y-up"},
                                {"spindle", "offset", "um-per-px", "marker", "rotation", "intrinsics", "p", "instance",
                                 "width", "height", "exposure"}));
    }
    if (cmd == "-h" || cmd == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    throw Usage("unknown command '" + cmd + "'");
  } catch (const Usage& e) {
    std::fprintf(stderr, "cnc-vision: %s\n%s", e.what(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-vision: %s\n", e.what());
    return 1;
  }
}
