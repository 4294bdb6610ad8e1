// cnc-comp: measurement in, compensation out.
//   report   ISO 230-2 figures of a measurement (text and plot)
//   compare  two measurements' figures side by side (before / after)
//   fit      the error model, compensation tables, exports, report and plots
//   cycle    the measurement programs (ISO 230-2 cycle, periodic runs)
//   camera   the ISO cycle on the running controller, measured by a camera
//            reading a glass scale (built with OpenCV's aruco module)
//   load     hands a COMP_FILE to a running controller (JOINT_LOAD_COMP)
//   synth    a synthetic measurement with known errors (demonstrations)
// See docs/compensation.md. Files are written atomically.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "comp/cycle.hpp"
#ifdef CNC_HAVE_CAMERA
#include "comp/camera_cycle.hpp"
#include "comp/ipc_positioner.hpp"
#endif
#include "comp/exports.hpp"
#include "comp/fit.hpp"
#include "comp/iso230.hpp"
#include "comp/measurement.hpp"
#include "comp/plot.hpp"
#include "comp/report.hpp"
#include "comp/synthetic.hpp"
#include "comp/tables.hpp"
#include "core/ipc/client.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

using namespace cnc;
using namespace cnc::comp;
namespace fs = std::filesystem;

namespace {

struct Usage : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* kUsage =
    "usage: cnc-comp <command> [options]\n"
    "  report  MEAS.csv [--out FILE.txt] [--plot FILE.png] [--max-deviation UM]\n"
    "  compare BEFORE.csv AFTER.csv [--out FILE.txt] [--plot FILE.png] [--max-deviation UM]\n"
    "  fit     MEAS.csv [MORE.csv...] --out-dir DIR [--axis X] [--lead MM] [--harmonics 1|2]\n"
    "          [--knot-spacing MM] [--smoothness UM] [--loss cauchy|huber|none] [--noise UM]\n"
    "          [--no-thermal] [--constant-backlash] [--reference MM] [--range MIN:MAX]\n"
    "          [--spacing MM | --points N] [--tolerance UM] [--type 0|1] [--max-deviation UM]\n"
    "          [--fanuc-axis N] [--fanuc-reference-point P] [--fanuc-unit UM] [--fanuc-magnification M]\n"
    "          [--fanuc-unidirectional]\n"
    "  cycle   --min MM --max MM --out FILE.ngc [--axis X] [--targets N] [--runs 5] [--overshoot MM]\n"
    "          [--dwell S] [--feed MM/MIN] [--seed N] [--output N] [--lead MM --periodic-out FILE.ngc]\n"
    "          [--places N] [--leads N] [--steps-per-lead N] [--periodic-runs N]\n"
    "  camera  --min MM --max MM --out FILE.csv --camera SOURCE --pitch MM --um-per-px UM [--axis X]\n"
    "          [--targets N] [--runs 5] [--overshoot MM] [--dwell S] [--feed MM/MIN] [--seed N]\n"
    "          [--scale-at-zero MM] [--sign 1|-1] [--frames N] [--width W --height H --exposure E]\n"
    "          [-i INSTANCE] [--timeout S]\n"
    "  load    --joint N FILE [--type 0|1] [-i INSTANCE] [--timeout S]\n"
    "  synth   --out FILE.csv [--seed N] [--periodic-out FILE.csv] [--no-temperature]\n";

// Options: --name value pairs and --flags; everything else is positional.
struct Args {
  std::vector<std::string> positional;
  std::map<std::string, std::string> values;
  std::vector<std::string> flags;

  bool flag(const std::string& f) const { return std::find(flags.begin(), flags.end(), f) != flags.end(); }
  std::optional<std::string> get(const std::string& k) const {
    const auto it = values.find(k);
    if (it == values.end()) return std::nullopt;
    return it->second;
  }
  double number(const std::string& k, double def) const {
    const auto v = get(k);
    if (!v) return def;
    const auto d = parse_double(*v);
    if (!d) throw Usage("--" + k + ": '" + *v + "' is not a number");
    return *d;
  }
  int integer(const std::string& k, int def) const {
    const auto v = get(k);
    if (!v) return def;
    const auto d = parse_int(*v);
    if (!d) throw Usage("--" + k + ": '" + *v + "' is not a whole number");
    return static_cast<int>(*d);
  }
  std::string text(const std::string& k, const std::string& def = {}) const { return get(k).value_or(def); }
};

Args parse(int argc, char** argv, int first, const std::vector<std::string>& flag_names) {
  Args a;
  for (int i = first; i < argc; ++i) {
    std::string s = argv[i];
    if (s == "-i") s = "--instance";
    if (s.rfind("--", 0) == 0 && s.size() > 2) {
      const std::string name = s.substr(2);
      if (std::find(flag_names.begin(), flag_names.end(), name) != flag_names.end()) {
        a.flags.push_back(name);
      } else {
        if (i + 1 >= argc) throw Usage(s + " needs a value");
        a.values[name] = argv[++i];
      }
    } else {
      a.positional.push_back(s);
    }
  }
  return a;
}

void check_known(const Args& a, const std::vector<std::string>& known) {
  for (const auto& [k, v] : a.values) {
    if (std::find(known.begin(), known.end(), k) == known.end()) throw Usage("unknown option --" + k);
  }
}

// --max-deviation: measured deviations larger than this (um) are refused
// as a unit mistake (docs/compensation.md, section 2).
MeasurementLimits limits_of(const Args& a) {
  MeasurementLimits l;
  l.max_abs_deviation_um = a.number("max-deviation", l.max_abs_deviation_um);
  if (!(l.max_abs_deviation_um > 0) || l.max_abs_deviation_um > 1e6) {
    throw Usage("--max-deviation: micrometres, more than 0 and at most 1000000");
  }
  return l;
}

void write_text(const std::optional<std::string>& path, const std::string& text) {
  if (path) write_file_atomically(*path, text);
  else std::fputs(text.c_str(), stdout);
}

int cmd_report(const Args& a) {
  check_known(a, {"out", "plot", "max-deviation"});
  if (a.positional.size() != 1) throw Usage("report takes one measurement file");
  const Measurement m = load_measurement(a.positional[0], limits_of(a));
  const Iso230Result r = evaluate_iso230(m);
  write_text(a.get("out"), iso230_report(r, "Measurement " + a.positional[0] + (m.axis.empty() ? "" : ", axis " + m.axis)));
  if (const auto p = a.get("plot")) write_plot(*p, {PlotPanel{"Measured: " + a.positional[0], &m, &r}});
  return 0;
}

int cmd_compare(const Args& a) {
  check_known(a, {"out", "plot", "max-deviation"});
  if (a.positional.size() != 2) throw Usage("compare takes two measurement files: before and after");
  const MeasurementLimits limits = limits_of(a);
  const Measurement b = load_measurement(a.positional[0], limits), c = load_measurement(a.positional[1], limits);
  const Iso230Result rb = evaluate_iso230(b), rc = evaluate_iso230(c);
  std::string text = iso230_comparison(rb, rc, "before", "after") + "\n";
  text += iso230_report(rb, "Before: " + a.positional[0]) + "\n" + iso230_report(rc, "After: " + a.positional[1]);
  write_text(a.get("out"), text);
  if (const auto p = a.get("plot")) {
    write_plot(*p, {PlotPanel{"Before: " + a.positional[0], &b, &rb}, PlotPanel{"After: " + a.positional[1], &c, &rc}});
  }
  return 0;
}

int cmd_fit(const Args& a) {
  check_known(a, {"out-dir", "axis", "lead", "harmonics", "knot-spacing", "smoothness", "loss", "noise", "reference",
                  "range", "spacing", "points", "tolerance", "type", "max-deviation", "fanuc-axis",
                  "fanuc-reference-point", "fanuc-unit", "fanuc-magnification"});
  if (a.positional.empty()) throw Usage("fit needs at least one measurement file");
  const auto dir = a.get("out-dir");
  if (!dir) throw Usage("fit needs --out-dir DIR");
  const MeasurementLimits limits = limits_of(a);
  ExportOptions eo;
  eo.fanuc_axis = a.integer("fanuc-axis", 0);
  if (a.get("fanuc-axis") && (eo.fanuc_axis < 1 || eo.fanuc_axis > 32)) throw Usage("--fanuc-axis: 1..32");
  eo.fanuc_reference_point = a.integer("fanuc-reference-point", -1);
  if (a.get("fanuc-reference-point") && eo.fanuc_reference_point < 0) throw Usage("--fanuc-reference-point: 0 or more");
  eo.fanuc_unit_um = a.number("fanuc-unit", 1);
  if (!(eo.fanuc_unit_um > 0) || eo.fanuc_unit_um > 1000) throw Usage("--fanuc-unit: the detection unit in um, above 0");
  eo.fanuc_magnification = a.integer("fanuc-magnification", 1);
  if (eo.fanuc_magnification < 1 || eo.fanuc_magnification > 100) throw Usage("--fanuc-magnification: 1..100");
  eo.fanuc_bidirectional = !a.flag("fanuc-unidirectional");
  std::vector<Measurement> data;
  for (const std::string& f : a.positional) data.push_back(load_measurement(f, limits));
  FitOptions fo;
  fo.lead_mm = a.number("lead", 0);
  fo.harmonics = a.integer("harmonics", 1);
  fo.knot_spacing_mm = a.number("knot-spacing", 0);
  fo.smoothness_um = a.number("smoothness", fo.smoothness_um);
  fo.noise_um = a.number("noise", 0);
  fo.thermal = !a.flag("no-thermal");
  fo.backlash_varies = !a.flag("constant-backlash");
  const std::string loss = to_lower(a.text("loss", "cauchy"));
  if (loss == "cauchy") fo.loss = RobustLoss::Cauchy;
  else if (loss == "huber") fo.loss = RobustLoss::Huber;
  else if (loss == "none") fo.loss = RobustLoss::None;
  else throw Usage("--loss: cauchy, huber or none");
  if (const auto r = a.get("range")) {
    const auto parts = split(*r, ':');
    const auto lo = parts.size() == 2 ? parse_double(parts[0]) : std::nullopt;
    const auto hi = parts.size() == 2 ? parse_double(parts[1]) : std::nullopt;
    if (!lo || !hi || !(*hi > *lo)) throw Usage("--range MIN:MAX");
    fo.x_min = *lo;
    fo.x_max = *hi;
  }
  const int type = a.integer("type", 1);
  if (type != 0 && type != 1) throw Usage("--type 0 or 1");
  const std::string axis = a.text("axis", data[0].axis.empty() ? "X" : data[0].axis);

  const auto t0 = std::chrono::steady_clock::now();
  const FitResult fit = fit_error_model(data, fo);
  if (!fit.model.backlash_measured) {
    std::fprintf(stderr,
                 "cnc-comp: warning: no target was approached from both directions: backlash is not measured, the "
                 "tables' forward and reverse trims are equal (and a COMP_FILE replaces BACKLASH)\n");
  }
  const double fit_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  TableOptions to;
  to.spacing_mm = a.number("spacing", 0);
  to.points = a.integer("points", 0);
  to.tolerance_um = a.number("tolerance", to.tolerance_um);
  to.reference_mm = a.number("reference", data[0].points.front().target);
  const CompTable table = make_comp_table(fit.model, to);
  const double offset = reference_offset_um(fit.model, to);
  const double interp = interpolation_error_um(table, fit.model, offset);

  fs::create_directories(*dir);
  const fs::path out(*dir);
  std::vector<std::string> notes = {
      "COMP_FILE_TYPE = " + std::to_string(type) + ": compensation fitted by cnc-comp from " +
          std::to_string(fit.points) + " points",
      std::to_string(table.size()) + " entries; linear interpolation within " + std::to_string(interp) +
          " um of the model; mean correction 0 at " + std::to_string(to.reference_mm) + " mm"};
  if (!fit.model.backlash_measured) {
    notes.push_back("backlash not measured (no target approached from both directions): forward and reverse trims "
                    "are equal, and this table replaces BACKLASH");
  }
  write_file_atomically(out / "comp.txt", format_comp_table(table, type == 0 ? CompFileType::Positions : CompFileType::Trims, notes));
  eo.axis = axis;
  eo.reference_mm = to.reference_mm;
  eo.x_min = fo.x_min;
  eo.x_max = fo.x_max;
  write_file_atomically(out / "linuxcnc.comp", export_linuxcnc(fit.model, eo, type));
  write_file_atomically(out / "siemens_lec.spf", export_siemens_lec(fit.model, eo));
  write_file_atomically(out / (axis + ".COM"), export_heidenhain_com(fit.model, eo));
  std::string report = fit_report(fit);
  // The Fanuc tape needs the axis's number on the control; without it the
  // tape is not written rather than written over another axis's points.
  std::string fanuc = "fanuc_pitch.txt";
  try {
    FanucPoints used;
    write_file_atomically(out / "fanuc_pitch.txt", export_fanuc_pitch(fit.model, eo, &used));
    char b[240];
    std::snprintf(b, sizeof b,
                  "  Fanuc tape: axis %d, reference point %d (3620), points %d..%d moving +%s; check that no other "
                  "axis uses them\n",
                  used.axis, used.reference, used.first, used.last,
                  used.neg_first >= 0 ? (", " + std::to_string(used.neg_first) + ".." + std::to_string(used.neg_last) +
                                         " moving -").c_str()
                                      : "");
    report += b;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "cnc-comp: fanuc_pitch.txt not written: %s\n", e.what());
    report += std::string("  fanuc_pitch.txt not written: ") + e.what() + "\n";
    fanuc.clear();
  }
  char b[200];
  std::snprintf(b, sizeof b, "  fit time %.1f ms\n\n", fit_ms);
  report += b;
  std::vector<PlotPanel> panels;
  std::vector<Iso230Result> before, after, referred;
  std::vector<Measurement> predicted, predicted_ref;
  before.reserve(data.size());
  after.reserve(data.size());
  referred.reserve(data.size());
  predicted.reserve(data.size());
  predicted_ref.reserve(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) {
    try {
      before.push_back(evaluate_iso230(data[i]));
      predicted.push_back(predicted_after(data[i], table));
      after.push_back(evaluate_iso230(predicted.back()));
    } catch (const std::exception& e) {
      report += "(" + a.positional[i] + ": no ISO 230-2 figures: " + e.what() + ")\n";
      continue;
    }
    report += "Measurement " + a.positional[i] + ": measured, and predicted with the table applied\n";
    report += iso230_comparison(before.back(), after.back(), "measured", "predicted") + "\n";
    report += iso230_report(before.back(), "Measured: " + a.positional[i]) + "\n";
    report += iso230_report(after.back(), "Predicted after compensation: " + a.positional[i]) + "\n";
    if (fit.model.has_thermal) {
      // The table holds at the reference temperature; what is left of the
      // measurement's warm-up is thermal. Referred to the reference
      // temperature, as ISO 230-2 reports results:
      Measurement ref = predicted.back();
      for (MeasurementPoint& q : ref.points) q.deviation_um -= fit.model.thermal_um(q.target, q.temperature_c);
      predicted_ref.push_back(ref);
      referred.push_back(evaluate_iso230(predicted_ref.back()));
      report += "Referred to " + std::to_string(fit.model.reference_temperature_c).substr(0, 4) +
                " C (the fitted thermal expansion removed):\n" +
                iso230_comparison(before.back(), referred.back(), "measured", "predicted") + "\n";
    }
    panels.push_back(PlotPanel{"Measured: " + fs::path(a.positional[i]).filename().string(), &data[i], &before.back(),
                               &fit.model, 0});
    panels.push_back(PlotPanel{"Predicted after compensation", &predicted.back(), &after.back()});
  }
  write_file_atomically(out / "report.txt", report);
  if (!panels.empty()) write_plot(out / "iso230.png", panels);
  std::fputs(report.c_str(), stdout);
  std::printf("wrote %s: comp.txt (%zu entries), linuxcnc.comp, siemens_lec.spf, %s.COM, %sreport.txt%s\n", out.c_str(),
              table.size(), axis.c_str(), fanuc.empty() ? "" : (fanuc + ", ").c_str(),
              panels.empty() ? "" : ", iso230.png");
  return 0;
}

// The ISO cycle's options, shared by `cycle` and `camera`.
CycleOptions cycle_options(const Args& a, const char* command) {
  CycleOptions o;
  if (!a.get("min") || !a.get("max")) throw Usage(std::string(command) + " needs --min and --max (the first and last target)");
  o.x_min = a.number("min", 0);
  o.x_max = a.number("max", 0);
  const std::string axis = a.text("axis", "X");
  if (axis.size() != 1 || !std::isalpha(static_cast<unsigned char>(axis[0]))) throw Usage("--axis: one letter");
  o.axis = static_cast<char>(std::toupper(static_cast<unsigned char>(axis[0])));
  o.targets = a.integer("targets", 0);
  o.runs = a.integer("runs", 5);
  o.overshoot_mm = a.number("overshoot", o.overshoot_mm);
  o.dwell_s = a.number("dwell", o.dwell_s);
  o.feed_mm_min = a.number("feed", o.feed_mm_min);
  o.seed = static_cast<uint64_t>(a.integer("seed", 1));
  return o;
}

int cmd_cycle(const Args& a) {
  check_known(a, {"min", "max", "out", "axis", "targets", "runs", "overshoot", "dwell", "feed", "seed", "output", "lead",
                  "periodic-out", "places", "leads", "steps-per-lead", "periodic-runs"});
  CycleOptions o = cycle_options(a, "cycle");
  o.digital_out = a.integer("output", 0);
  o.lead_mm = a.number("lead", o.lead_mm);
  o.periodic_places = a.integer("places", o.periodic_places);
  o.periodic_leads = a.number("leads", o.periodic_leads);
  o.periodic_steps_per_lead = a.integer("steps-per-lead", o.periodic_steps_per_lead);
  o.periodic_runs = a.integer("periodic-runs", o.periodic_runs);
  const auto out = a.get("out");
  if (!out) throw Usage("cycle needs --out FILE.ngc");
  write_file_atomically(*out, iso_cycle_gcode(o));
  if (const auto p = a.get("periodic-out")) write_file_atomically(*p, periodic_cycle_gcode(o));
  std::printf("wrote %s (%zu targets)\n", out->c_str(), iso_targets(o).size());
  return 0;
}

#ifdef CNC_HAVE_CAMERA
// The ISO cycle on the running controller with a camera reading a glass
// scale as the measurement source (docs/vision.md). What was measured is
// written also when the cycle stops.
int cmd_camera(const Args& a) {
  check_known(a, {"min", "max", "out", "axis", "targets", "runs", "overshoot", "dwell", "feed", "seed", "camera",
                  "pitch", "um-per-px", "scale-at-zero", "sign", "frames", "width", "height", "exposure", "instance",
                  "timeout"});
  CameraCycleOptions o;
  o.cycle = cycle_options(a, "camera");
  const auto out = a.get("out");
  if (!out) throw Usage("camera needs --out FILE.csv");
  const auto source = a.get("camera");
  if (!source) throw Usage("camera needs --camera SOURCE (/dev/videoN, an image folder)");
  if (!a.get("pitch") || !a.get("um-per-px")) throw Usage("camera needs --pitch MM and --um-per-px UM");
  o.scale.pitch_mm = a.number("pitch", 0);
  o.scale.um_per_px = a.number("um-per-px", 0);
  o.scale_at_zero_mm = a.number("scale-at-zero", 0);
  o.sign = a.integer("sign", 1);
  if (o.sign != 1 && o.sign != -1) throw Usage("--sign: 1 or -1");
  o.frames = a.integer("frames", 1);
  vision::CameraSettings cs;
  cs.width = a.integer("width", 0);
  cs.height = a.integer("height", 0);
  cs.exposure = a.number("exposure", 0);
  auto camera = vision::open_source(*source, cs);
  if (std::string e = camera->check(); !e.empty()) throw std::runtime_error(e);
  ipc::Client client(a.text("instance", ipc::default_instance()));
  IpcPositioner axis(client, o.cycle.axis, o.cycle.feed_mm_min, a.number("timeout", 120));
  const CameraCycleResult r = run_camera_cycle(axis, *camera, o);
  return report_camera_cycle(r, *out);
}
#endif

int cmd_load(const Args& a) {
  check_known(a, {"joint", "type", "instance", "timeout"});
  if (a.positional.size() != 1 || !a.get("joint")) throw Usage("load needs --joint N and one COMP_FILE");
  ipc::Client client(a.text("instance", ipc::default_instance()));
  ipc::Command c = ipc::make_command(ipc::CommandType::JointLoadComp);
  c.i[0] = a.integer("joint", 0);
  c.i[1] = a.integer("type", 1);
  const std::string path = fs::absolute(a.positional[0]).string();
  c.text.assign(path);
  const auto timeout = std::chrono::milliseconds(static_cast<int64_t>(a.number("timeout", 10) * 1000));
  const ipc::CommandResult r = client.execute(c, timeout);
  if (r.state != ipc::CommandState::Done) {
    std::fprintf(stderr, "cnc-comp: load rejected: %s\n", r.reason.c_str());
    return 1;
  }
  std::printf("%s\n", r.reason.c_str());
  return 0;
}

int cmd_synth(const Args& a) {
  check_known(a, {"out", "seed", "periodic-out"});
  const auto out = a.get("out");
  if (!out) throw Usage("synth needs --out FILE.csv");
  const uint64_t seed = static_cast<uint64_t>(a.integer("seed", 1));
  const bool temp = !a.flag("no-temperature");
  SyntheticAxis axis;
  CycleOptions co;
  co.x_min = axis.x_min;
  co.x_max = axis.x_max;
  co.seed = seed;
  const Measurement m = synthesize_cycle(axis, iso_targets(co), 5, seed, temp);
  write_file_atomically(*out, format_measurement(m));
  if (const auto p = a.get("periodic-out")) {
    Measurement all;
    all.axis = "X";
    double t = m.points.back().time_s;
    for (int place = 0; place < co.periodic_places; ++place) {
      Measurement part = synthesize_cycle(axis, periodic_targets(co, place), co.periodic_runs, seed + 1 + place, temp, t);
      t = part.points.back().time_s;
      all.points.insert(all.points.end(), part.points.begin(), part.points.end());
    }
    write_file_atomically(*p, format_measurement(all));
  }
  std::printf("wrote %s (seed %llu)\n", out->c_str(), static_cast<unsigned long long>(seed));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "help") {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const std::string cmd = argv[1];
  try {
    const Args a = parse(argc, argv, 2, {"no-thermal", "constant-backlash", "no-temperature", "fanuc-unidirectional"});
    if (cmd == "report") return cmd_report(a);
    if (cmd == "compare") return cmd_compare(a);
    if (cmd == "fit") return cmd_fit(a);
    if (cmd == "cycle") return cmd_cycle(a);
    if (cmd == "load") return cmd_load(a);
    if (cmd == "synth") return cmd_synth(a);
#ifdef CNC_HAVE_CAMERA
    if (cmd == "camera") return cmd_camera(a);
#endif
    throw Usage("unknown command '" + cmd + "'");
  } catch (const Usage& e) {
    std::fprintf(stderr, "cnc-comp: %s\n%s", e.what(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-comp: %s\n", e.what());
    return 1;
  }
}
