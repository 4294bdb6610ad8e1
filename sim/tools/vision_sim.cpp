// cnc-vision-sim: synthetic camera images with a known truth, for trying
// cnc-vision without a camera (docs/vision.md) and for recording test
// images. Prints the truth.
//   scale  --out FILE --at MM [--pitch MM] [--line MM] [--um-per-px UM] [--angle DEG] [--blur PX]
//          [--noise GREY] [--gradient F] [--vignetting F] [--k1 K] [--width W] [--height H] [--seed N] [--blank]
//   marker --out FILE --x MM --y MM [--angle DEG] --spindle X,Y --offset DX,DY --um-per-px UM [--rotation DEG]
//          [--id N] [--side MM] [--blur PX] [--noise GREY] [--seed N]
#include <cstdio>
#include <cstring>
#include <map>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "core/util/strings.hpp"
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
               "         --um-per-px UM [--rotation DEG] [--id N] [--side MM] [--blur PX] [--noise GREY] [--seed N]\n",
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

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) usage("a command is needed");
  const std::string cmd = argv[1];
  Opts o;
  for (int i = 2; i < argc; ++i) {
    const std::string s = argv[i];
    if (s == "--blank") {
      o.v["blank"] = "1";
      continue;
    }
    if (s.rfind("--", 0) != 0 || i + 1 >= argc) usage("unexpected '" + s + "'");
    o.v[s.substr(2)] = argv[++i];
  }
  if (!o.has("out")) usage("--out FILE is needed");
  const std::string out = o.v["out"];
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
