#include "commission/compensation.hpp"

#include "commission/steps.hpp"

#include <algorithm>
#include <cctype>
#include <memory>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <thread>

#include "comp/comp_table.hpp"
#include "comp/fit.hpp"
#include "comp/iso230.hpp"
#include "comp/measurement.hpp"
#include "comp/report.hpp"
#include "comp/tables.hpp"
#include "core/ipc/admin.hpp"
#include "core/ipc/client.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::commission {

namespace {

std::string axis_name(char l) { return std::string("axis ") + l; }
std::string num(double v, const char* fmt = "%.6g") {
  char b[48];
  std::snprintf(b, sizeof b, fmt, v);
  return b;
}

comp::Measurement to_measurement(char axis, const std::vector<CompPoint>& points) {
  comp::Measurement m;
  m.axis = std::string(1, axis);
  for (const CompPoint& p : points) {
    comp::MeasurementPoint q;
    q.target = p.target;
    q.run = p.run;
    q.direction = p.direction;
    q.deviation_um = p.deviation_um;
    m.points.push_back(q);
  }
  return m;
}

std::vector<CompPoint> to_points(const comp::Measurement& m) {
  std::vector<CompPoint> v;
  for (const comp::MeasurementPoint& p : m.points) v.push_back({p.target, p.run, p.direction, p.deviation_um});
  return v;
}

CompFigures figures(const comp::Iso230Result& r) {
  CompFigures f;
  f.A = r.A;
  f.A_up = r.A_up;
  f.A_down = r.A_down;
  f.E = r.E;
  f.E_up = r.E_up;
  f.E_down = r.E_down;
  f.R = r.R;
  f.B = r.B;
  f.B_mean = r.B_mean;
  f.M = r.M;
  return f;
}

const AxisCompensation& need_comp(const Axis& a) {
  if (!a.compensation)
    throw std::invalid_argument(axis_name(a.letter) + " has no compensation cycle yet: cnc-commission axis " +
                                std::string(1, a.letter) + " comp-program --out FILE.ngc");
  return *a.compensation;
}

// A table belongs to the scaling it was measured with: after a new
// direction test or scaling the axis moves differently, and the table would
// correct errors the axis no longer has.
void check_scaling(const Axis& a, const AxisCompensation& c) {
  const double now = a.scaling.counts_per_mm();
  if (c.scaling_counts_per_mm > 0 &&
      (std::fabs(now / c.scaling_counts_per_mm - 1) > 1e-9 || a.scaling.reverse != c.scaling_reverse))
    throw std::invalid_argument(axis_name(a.letter) + ": the compensation was measured at " +
                                num(c.scaling_counts_per_mm) + " counts/mm" + (c.scaling_reverse ? " REVERSE" : "") + ", the scaling is now " + num(now) +
                                " counts/mm" + (a.scaling.reverse ? " REVERSE" : "") +
                                ": measure again (comp-run), or leave the table out (comp-fit without --install)");
}

}  // namespace

AxisCompensation default_compensation(const Axis& a) {
  AxisCompensation c;
  // Inside the known travel (check_cycle refuses a cycle without one).
  double lo = a.min_limit, hi = a.max_limit;
  try {
    const Travel t = known_travel(a);
    lo = t.min;
    hi = t.max;
  } catch (const std::invalid_argument&) {
  }
  c.x_min = lo + c.overshoot_mm + 1;
  c.x_max = hi - c.overshoot_mm - 1;
  c.feed_mm_min = std::min(3000.0, 0.5 * a.max_velocity * 60);
  return c;
}

void check_cycle(const Axis& a, const AxisCompensation& c) {
  const std::string n = axis_name(a.letter);
  if (!(c.x_max > c.x_min))
    throw std::invalid_argument(n + ": the cycle's last target (" + num(c.x_max) + " mm) must lie above its first (" +
                                num(c.x_min) + " mm)");
  const Travel t = known_travel(a);  // throws when the travel is not known
  if (c.x_min - c.overshoot_mm < t.min - 1e-9 || c.x_max + c.overshoot_mm > t.max + 1e-9)
    throw std::invalid_argument(n + ": the cycle " + num(c.x_min) + ".." + num(c.x_max) + " mm with its overshoot of " +
                                num(c.overshoot_mm) + " mm leaves the travel " + num(t.min) + ".." + num(t.max) +
                                " mm (" + t.source + "): narrow it (--min, --max) or set the limits first");
  if (c.runs < 2)
    throw std::invalid_argument(n + ": " + std::to_string(c.runs) +
                                " run(s): ISO 230-2 needs at least two runs each way (the standard test five)");
  if (c.targets != 0 && c.targets < 2) throw std::invalid_argument(n + ": at least two targets");
  if (!(c.feed_mm_min > 0) || c.feed_mm_min > a.max_velocity * 60 + 1e-9)
    throw std::invalid_argument(n + ": feed " + num(c.feed_mm_min) + " mm/min: expected above 0 and at most the axis's " +
                                num(a.max_velocity * 60) + " mm/min (MAX_VELOCITY)");
  if (!(c.dwell_s >= 0.2) || c.dwell_s > 60)
    throw std::invalid_argument(n + ": dwell " + num(c.dwell_s) + " s: expected 0.2..60 s (the reading settles, then is averaged)");
  if (!(c.overshoot_mm >= 0) || c.overshoot_mm > 50)
    throw std::invalid_argument(n + ": overshoot " + num(c.overshoot_mm) + " mm: expected 0..50 mm");
}

comp::CycleOptions cycle_options(const Axis& a, const AxisCompensation& c) {
  comp::CycleOptions o;
  o.axis = a.letter;
  o.x_min = c.x_min;
  o.x_max = c.x_max;
  o.targets = c.targets;
  o.runs = c.runs;
  o.overshoot_mm = c.overshoot_mm;
  o.dwell_s = c.dwell_s;
  o.feed_mm_min = c.feed_mm_min;
  o.seed = c.seed;
  return o;
}

std::vector<CycleStop> cycle_stops(const Axis& a, const AxisCompensation& c) {
  const std::vector<double> t = comp::iso_targets(cycle_options(a, c));
  std::vector<CycleStop> v;
  for (int run = 1; run <= c.runs; ++run) {
    for (double x : t) v.push_back({x, 1, run});
    for (auto it = t.rbegin(); it != t.rend(); ++it) v.push_back({*it, -1, run});
  }
  return v;
}

std::string describe_stops(char axis, const std::vector<CycleStop>& stops) {
  std::string s;
  for (std::size_t i = 0; i < stops.size(); ++i)
    s += "stop " + std::to_string(i + 1) + ": " + std::string(1, axis) + " " + num(stops[i].target, "%.3f") +
         " moving " + (stops[i].direction > 0 ? "+" : "-") + ", run " + std::to_string(stops[i].run) + "\n";
  return s;
}

std::vector<CompPoint> points_from_readings(const std::vector<CycleStop>& stops, const std::vector<double>& r) {
  if (r.size() != stops.size() || stops.empty())
    throw std::invalid_argument(std::to_string(r.size()) + " reading(s) for " + std::to_string(stops.size()) +
                                " stops of the cycle");
  std::vector<CompPoint> v;
  for (std::size_t i = 0; i < stops.size(); ++i) {
    if (!std::isfinite(r[i])) throw std::invalid_argument("reading " + std::to_string(i + 1) + " is not a number");
    const double dev_mm = (r[i] - r[0]) - (stops[i].target - stops[0].target);
    // As comp/'s measurement files: a deviation above 1 mm is a mistake
    // (scaling, units, a laser that lost its beam), not an error to trim.
    if (std::fabs(dev_mm) > 1.0)
      throw std::invalid_argument("stop " + std::to_string(i + 1) + " (" + num(stops[i].target, "%.3f") + " mm moving " +
                                  (stops[i].direction > 0 ? "+" : "-") + "): the reading is " + num(dev_mm, "%.4f") +
                                  " mm off the target (relative to the first stop): more than 1 mm; check the axis's "
                                  "scaling and direction (step 4), and that the readings are in mm");
    v.push_back({stops[i].target, stops[i].run, stops[i].direction, dev_mm * 1000});
  }
  return v;
}

std::vector<double> parse_laser_csv(const std::string& text, const std::string& file, const std::vector<CycleStop>& stops) {
  std::vector<double> out;
  int col_reading = -1, col_target = -1, col_direction = -1;
  std::size_t ncols = 0;
  bool decided = false, header = false;
  int line_no = 0, last_line = 0;
  for (const std::string& raw : split(text, '\n')) {
    ++line_no;
    const std::string_view body = trim(raw);
    if (body.empty() || body.front() == '#') continue;
    const std::vector<std::string> cells = split(body, ',');
    if (!decided) {
      decided = true;
      if (!parse_double(trim(cells[0]))) {
        header = true;
        for (std::size_t k = 0; k < cells.size(); ++k) {
          const std::string name = to_lower(trim(cells[k]));
          if (name == "reading_mm" || name == "position_mm") col_reading = static_cast<int>(k);
          else if (name == "target") col_target = static_cast<int>(k);
          else if (name == "direction") col_direction = static_cast<int>(k);
        }
        if (col_reading < 0)
          throw ConfigError(file, line_no,
                            "no reading_mm (or position_mm) column: the first line that is not a comment is either a "
                            "reading or a header naming the columns (reading_mm, and target, direction to check)");
        ncols = cells.size();
        continue;
      }
      col_reading = 0;
      ncols = 1;
    }
    if (cells.size() != ncols)
      throw ConfigError(file, line_no, "expected " + std::to_string(ncols) + " value(s), found " + std::to_string(cells.size()));
    const std::size_t k = out.size();
    if (k >= stops.size())
      throw ConfigError(file, line_no, "more readings than the cycle's " + std::to_string(stops.size()) + " stops");
    const auto v = parse_double(trim(cells[static_cast<std::size_t>(col_reading)]));
    if (!v || !std::isfinite(*v))
      throw ConfigError(file, line_no, "reading '" + std::string(trim(cells[static_cast<std::size_t>(col_reading)])) +
                                           "' is not a number (mm)");
    if (col_target >= 0) {
      const auto t = parse_double(trim(cells[static_cast<std::size_t>(col_target)]));
      if (!t || std::fabs(*t - stops[k].target) > 0.001)
        throw ConfigError(file, line_no, "target '" + std::string(trim(cells[static_cast<std::size_t>(col_target)])) +
                                             "': stop " + std::to_string(k + 1) + " of the cycle is at " +
                                             num(stops[k].target, "%.3f") + " mm (readings in the cycle's order)");
    }
    if (col_direction >= 0) {
      const std::string d(trim(cells[static_cast<std::size_t>(col_direction)]));
      const int dir = d == "+" ? 1 : d == "-" ? -1 : 0;
      if (dir != stops[k].direction)
        throw ConfigError(file, line_no, "direction '" + d + "': stop " + std::to_string(k + 1) + " is approached moving " +
                                             (stops[k].direction > 0 ? "+" : "-"));
    }
    if (std::fabs(*v) > 1e5) throw ConfigError(file, line_no, "reading " + num(*v) + " is not a position in mm");
    out.push_back(*v);
    last_line = line_no;
  }
  if (out.size() != stops.size())
    throw ConfigError(file, out.empty() ? line_no : last_line,
                      std::to_string(out.size()) + " reading(s) for the cycle's " + std::to_string(stops.size()) +
                          " stops" + (header ? "" : " (one reading per line, mm)"));
  return out;
}

std::vector<double> load_laser_csv(const std::filesystem::path& file, const std::vector<CycleStop>& stops) {
  std::string text;
  try {
    text = read_file(file);
  } catch (const std::exception& e) {
    throw ConfigError(file.string(), 0, std::string("cannot read the laser's file: ") + e.what());
  }
  return parse_laser_csv(text, file.string(), stops);
}

std::vector<CompPoint> points_from_values(const std::vector<CycleStop>& stops, const std::string& values) {
  const std::vector<std::string> cells = split(values, ',');
  if (cells.size() != stops.size())
    throw std::invalid_argument(std::to_string(cells.size()) + " value(s) for the cycle's " + std::to_string(stops.size()) +
                                " stops (deviations in um, position reached minus target, in the order of the stops)");
  std::vector<CompPoint> v;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const auto d = parse_double(trim(cells[i]));
    if (!d || !std::isfinite(*d))
      throw std::invalid_argument("value " + std::to_string(i + 1) + " '" + std::string(trim(cells[i])) + "' is not a number");
    if (std::fabs(*d) > 1000)
      throw std::invalid_argument("value " + std::to_string(i + 1) + ": " + num(*d) +
                                  " um is more than 1 mm: deviations are in micrometres (are these nanometres?)");
    v.push_back({stops[i].target, stops[i].run, stops[i].direction, *d});
  }
  return v;
}

std::vector<CompPoint> points_from_measurement_file(const Axis& a, const std::filesystem::path& file) {
  const comp::Measurement m = comp::load_measurement(file);
  if (!m.axis.empty() && !(m.axis.size() == 1 && std::toupper(static_cast<unsigned char>(m.axis[0])) == a.letter))
    throw ConfigError(file.string(), 0, "the file measures axis " + m.axis + ", not " + std::string(1, a.letter));
  for (const comp::MeasurementPoint& p : m.points)
    if (p.target < a.min_limit || p.target > a.max_limit)
      throw ConfigError(file.string(), 0, "target " + num(p.target) + " mm lies outside " + axis_name(a.letter) +
                                              "'s soft limits " + num(a.min_limit) + ".." + num(a.max_limit) + " mm");
  return to_points(m);
}

CompFigures figures_of(const std::vector<CompPoint>& points) {
  return figures(comp::evaluate_iso230(to_measurement('X', points)));
}

std::string describe(const CompFigures& f) {
  char b[200];
  std::snprintf(b, sizeof b, "A %.3f um (up %.3f, down %.3f), E %.3f um, R %.3f um, B %.3f um (mean %.3f), M %.3f um",
                f.A, f.A_up, f.A_down, f.E, f.R, f.B, f.B_mean, f.M);
  return b;
}

const CompFigures& set_measurement(State& s, char letter, std::vector<CompPoint> points, const std::string& source,
                                   bool check) {
  Axis* a = s.axis(letter);
  if (!a) throw std::invalid_argument(axis_name(letter) + " has no drive yet");
  if (!a->compensation) a->compensation = default_compensation(*a);
  AxisCompensation& c = *a->compensation;
  CompFigures f;
  try {
    f = figures_of(points);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(axis_name(letter) + ": " + e.what());
  }
  if (check) {
    c.check_points = std::move(points);
    c.checked = f;
    return *c.checked;
  }
  c.points = std::move(points);
  c.source = source;
  c.scaling_counts_per_mm = a->scaling.counts_per_mm();
  c.scaling_reverse = a->scaling.reverse;
  c.measured = f;
  c.fitted = false;  // a new measurement: the old fit no longer belongs to it
  c.install = false;
  c.nominal.clear();
  c.forward.clear();
  c.reverse.clear();
  c.check_points.clear();
  c.checked.reset();
  return *c.measured;
}

std::string fit_compensation(State& s, char letter, const std::filesystem::path& out_dir, bool install) {
  Axis* a = s.axis(letter);
  if (!a) throw std::invalid_argument(axis_name(letter) + " has no drive yet");
  need_comp(*a);
  AxisCompensation& c = *a->compensation;
  if (c.points.empty())
    throw std::invalid_argument(axis_name(letter) + " has no measurement: comp-run, or comp-measurements, first");
  check_scaling(*a, c);
  const comp::Measurement m = to_measurement(letter, c.points);
  comp::FitOptions fo;
  fo.lead_mm = 0;        // the ISO cycle's targets alias a lead-periodic error: no periodic term
  fo.thermal = false;    // no temperatures measured
  const comp::FitResult fit = comp::fit_error_model({m}, fo);
  comp::TableOptions to;
  double first = c.points.front().target;
  for (const CompPoint& p : c.points) first = std::min(first, p.target);
  to.reference_mm = first;
  const comp::CompTable table = comp::make_comp_table(fit.model, to);
  const comp::Iso230Result before = comp::evaluate_iso230(m);
  const comp::Iso230Result after = comp::evaluate_iso230(comp::predicted_after(m, table));
  const double interp = comp::interpolation_error_um(table, fit.model, comp::reference_offset_um(fit.model, to));

  std::string report = "Axis " + std::string(1, letter) + ": " + std::to_string(m.points.size()) + " points (" +
                       c.source + "), measured and predicted with the table\n";
  report += comp::iso230_comparison(before, after, "measured", "predicted") + "\n";
  report += comp::iso230_report(before, "Measured, axis " + std::string(1, letter)) + "\n";
  report += comp::iso230_report(after, "Predicted after compensation, axis " + std::string(1, letter)) + "\n";
  report += comp::fit_report(fit);
  const std::vector<std::string> notes = {
      "COMP_FILE_TYPE = 1: fitted by cnc-commission (comp/) from " + std::to_string(fit.points) + " points of the ISO 230-2 cycle",
      std::to_string(table.size()) + " entries; linear interpolation within " + num(interp, "%.3f") +
          " um of the model; mean correction 0 at " + num(first, "%.3f") + " mm"};
  std::filesystem::create_directories(out_dir);
  write_file_atomically(out_dir / "measurement.csv", comp::format_measurement(m));
  write_file_atomically(out_dir / (std::string(1, letter) + ".comp"),
                        comp::format_comp_table(table, comp::CompFileType::Trims, notes));
  write_file_atomically(out_dir / "report.txt", report);

  c.fitted = true;
  c.before = figures(before);
  c.predicted = figures(after);
  c.nominal = table.nominal;
  c.forward = table.forward;
  c.reverse = table.reverse;
  c.fit_dir = std::filesystem::absolute(out_dir).string();
  c.install = install;
  return report;
}

std::string comp_file_name(const Axis& a, const std::string& name) {
  return name + "-" + std::string(1, static_cast<char>(std::tolower(static_cast<unsigned char>(a.letter)))) + ".comp";
}

std::string comp_ini_keys(const Axis& a, const std::string& name) {
  if (!a.compensation || !a.compensation->install || !a.compensation->fitted || !a.enabled) return {};
  const AxisCompensation& c = *a.compensation;
  char b[160];
  std::snprintf(b, sizeof b, "# Screw compensation (ISO 230-2 A %.3f um measured, %.3f um predicted)\n", c.before.A,
                c.predicted.A);
  return b + std::string("COMP_FILE = ") + comp_file_name(a, name) + "\nCOMP_FILE_TYPE = 1\n";
}

bool any_compensation(const State& s) {
  for (const Axis& a : s.axes)
    if (a.compensation && a.compensation->install && a.compensation->fitted && a.enabled) return true;
  return false;
}

std::vector<GeneratedFile> compensation_files(const State& s, const std::filesystem::path& dir, const std::string& name) {
  std::vector<GeneratedFile> out;
  for (const Axis& a : s.axes) {
    if (comp_ini_keys(a, name).empty()) continue;
    const AxisCompensation& c = *a.compensation;
    check_scaling(a, c);
    comp::CompTable t;
    t.nominal = c.nominal;
    t.forward = c.forward;
    t.reverse = c.reverse;
    out.push_back({dir / comp_file_name(a, name),
                   comp::format_comp_table(t, comp::CompFileType::Trims,
                                           {"axis " + std::string(1, a.letter) + ", joint " + std::to_string(a.joint) +
                                                ": written by cnc-commission from its state (" + describe(c.before) + ")"})});
  }
  return out;
}

CompRunResult run_comp_cycle(const Controller& ctl, const Axis& a, const AxisCompensation& c,
                             const std::filesystem::path& program, const std::string& laser_pin,
                             const Progress& progress) {
  StopReader read;
  if (!laser_pin.empty()) {
    auto admin = std::make_shared<ipc::AdminClient>(ipc::Client().instance());
    const std::string n = axis_name(a.letter);
    read = [admin, laser_pin, n](double) {
      const ipc::AdminReply rep = admin->request("getp " + laser_pin);
      const auto v = rep.ok ? parse_double(trim(rep.text)) : std::nullopt;
      if (!v) throw std::runtime_error(n + ": the laser's pin " + laser_pin + " cannot be read: " + rep.text);
      return *v;
    };
    read(0);  // named now rather than at the first stop
  }
  return run_comp_cycle(ctl, a, c, program, read, progress);
}

CompRunResult run_comp_cycle(const Controller& ctl, const Axis& a, const AxisCompensation& c,
                             const std::filesystem::path& program, const StopReader& read,
                             const Progress& progress, int readings_per_stop) {
  using clock = std::chrono::steady_clock;
  check_cycle(a, c);
  CompRunResult r;
  r.stops = cycle_stops(a, c);
  const std::string n = axis_name(a.letter);
  const int joint = a.joint;
  clear_abort();
  ipc::Client client;
  // The cycle's time at its feed: each run twice over the range and the
  // overshoots, a dwell per stop.
  const double travel = c.runs * 2 * (c.x_max - c.x_min + 2 * c.overshoot_mm) + (c.x_max - c.x_min) + 2 * c.overshoot_mm;
  const double expected_s = travel / (c.feed_mm_min / 60) + r.stops.size() * (c.dwell_s + 0.2);
  const auto limit = std::chrono::duration<double>(2 * expected_s + 60);
  const double settle_s = 0.4 * c.dwell_s;
  try {
    ctl.cnc({"estop-reset"});
    if (!ctl.estop_chain_ok())
      throw std::runtime_error(n + ": the E-stop chain is open: close it before the measurement cycle");
    ctl.cnc({"on"});
    // Every joint homed (auto mode needs them all; the table applies once homed).
    home_all(ctl, n);
    ctl.cnc({"mode", "auto"});
    ctl.cnc({"open", std::filesystem::absolute(program).string()});
    if (progress) progress(0, static_cast<int>(r.stops.size()), "cycle started: " + program.string());
    ctl.cnc({"run"});
    const auto start = clock::now();
    double last_cmd = client.status().joints[joint].pos_cmd;
    int last_dir = 0;               // sign of the command's last move (0: not moved yet)
    auto still_since = clock::now();
    double sum = 0;
    int samples = 0;
    bool seen_running = false;
    bool at_stop = false;           // the command stands at stop k, settled
    std::size_t k = 0;
    while (k < r.stops.size()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const ipc::Status st = client.status();
      const double cmd = st.joints[joint].pos_cmd;
      const auto now = clock::now();
      const bool running = st.task.interp_state != ipc::InterpState::Idle;
      seen_running = seen_running || running;
      if (abort_requested()) throw std::runtime_error(n + ": the measurement cycle was aborted");
      if (now - start > limit)
        throw std::runtime_error(n + ": the measurement cycle did not end within " + num(limit.count(), "%.0f") +
                                 " s (" + std::to_string(k) + " of " + std::to_string(r.stops.size()) + " stops)");
      if (st.task.state != ipc::TaskState::On)
        throw std::runtime_error(n + ": the machine went off during the cycle (E-stop, drive fault?) after " +
                                 std::to_string(k) + " of " + std::to_string(r.stops.size()) + " stops");
      if (!running && (seen_running || now - start > std::chrono::seconds(5)))
        throw std::runtime_error(n + ": the program ended after " + std::to_string(k) + " of " +
                                 std::to_string(r.stops.size()) + " stops (see cnc messages)");
      const CycleStop& stop = r.stops[k];
      if (std::fabs(cmd - last_cmd) > 1e-9) {
        // The command moves: a stop being read ends here.
        if (at_stop && samples == 0)
          throw std::runtime_error(n + ": no reading at stop " + std::to_string(k + 1) + " (" + std::string(1, a.letter) +
                                   " " + num(stop.target, "%.3f") + "): the dwell (" + num(c.dwell_s, "%.2f") +
                                   " s) ended before a reading did: give a longer --dwell to comp-program");
        at_stop = false;
        if (samples > 0) {
          r.readings_mm.push_back(!read ? std::numeric_limits<double>::quiet_NaN() : sum / samples);
          ++k;
          if (progress)
            progress(static_cast<int>(k), static_cast<int>(r.stops.size()),
                     std::string(1, a.letter) + " " + num(stop.target, "%.3f") + (stop.direction > 0 ? " +" : " -") +
                         (!read ? "" : " reading " + num(r.readings_mm.back(), "%.6f") + " mm"));
        }
        last_dir = cmd > last_cmd ? 1 : -1;
        last_cmd = cmd;
        still_since = now;
        sum = 0;
        samples = 0;
        continue;
      }
      const double still = std::chrono::duration<double>(now - still_since).count();
      if (still >= settle_s && last_dir == stop.direction && std::fabs(cmd - stop.target) < 1e-4) {
        at_stop = true;
        if (readings_per_stop > 0 && samples >= readings_per_stop) continue;
        double v = 0;
        if (read) {
          const auto where = [&] {
            return std::string(1, a.letter) + " " + num(stop.target, "%.3f") + (stop.direction > 0 ? " +" : " -") +
                   ", run " + std::to_string(stop.run);
          };
          try {
            v = read(stop.target);
          } catch (const std::exception& e) {
            throw std::runtime_error(n + ": no reading at stop " + std::to_string(k + 1) + " (" + where() + "): " + e.what());
          }
          // A reading that took long (a camera's frame) may end after the
          // command moved on: dropped, the stop keeps the earlier ones.
          if (std::fabs(client.status().joints[joint].pos_cmd - cmd) > 1e-9) continue;
        }
        sum += v;
        ++samples;
      }
    }
    // The program ends at the first target; the machine goes off.
    const auto t_end = clock::now();
    while (client.status().task.interp_state != ipc::InterpState::Idle) {
      if (abort_requested()) throw std::runtime_error(n + ": the measurement cycle was aborted");
      if (clock::now() - t_end > std::chrono::seconds(60)) throw std::runtime_error(n + ": the program did not end after its last stop");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what() + switch_off_after_failure(ctl, /*abort_program=*/true));
  }
  ctl.cnc({"off"});
  return r;
}

}  // namespace cnc::commission
