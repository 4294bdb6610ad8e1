// Trajectory planner benchmark (docs/tp.md): runs fixed programs through
// tp::LookaheadPlanner (inline: planning and servo work on this thread, the
// way a 1-core machine would run it) under the Mill-S, Mill-F and LC limit
// profiles at 1 ms and 250 us, and prints per program: traverse time,
// worst per-axis |v|, |a|, |j| relative to the limits, worst distance from
// the programmed path relative to the tolerance, share of time at the
// programmed feed, and planner CPU per servo cycle and per queued segment.
// Also short-segment feed attainment for segment lengths 1 um ... 1 mm.
//
//   bench_tp [--quick] [--write-ngc DIR] [--ngc FILE ...] [--only-ngc]
//            [--limits V,A,J] [--linear V,A,J] [--lookahead N] [--period S]
//            [--start X,Y,Z]
//
// --only-ngc runs only the --ngc programs and prints their end positions;
// --limits (per-axis X, Y, Z velocity, acceleration, jerk), --linear (the
// same on the XYZ norm, [TRAJ]MAX_LINEAR_*), --lookahead
// (segments), --period (s) and --start (where --ngc programs start, the
// origin by default) set what a configuration would, e.g. to
// predict what cncd does on it (bench/tp/cncd_program.sh).
// --write-ngc writes the generated programs as G-code (for the LinuxCNC
// side-by-side, bench/tp/compare_linuxcnc.sh); --ngc adds programs read
// through the project's interpreter (e.g. LinuxCNC's 3D_Chips.ngc).
// Figures never fail the run: timing belongs to benchmarks, not tests.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "core/interp/interp.hpp"
#include "core/interp/text_canon.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "core/tp/trajectory_check.hpp"

namespace {

using namespace cnc;
using namespace cnc::tp;

// Set by --limits / --lookahead: the "custom" profile and the look-ahead
// of every profile.
AxisLimits g_custom{100, 1000, 50000};
int g_lookahead = 2000;
// Set by --linear: [TRAJ]MAX_LINEAR_* (limits on the XYZ norm), off by default.
double g_linear[3] = {0, 0, 0};
// Set by --start: where --ngc programs start (the machine's position).
double g_start[3] = {0, 0, 0};

PlannerConfig profile(const std::string& name, double cycle_s) {
  PlannerConfig c;
  c.cycle_time_s = cycle_s;
  AxisLimits l{100, 1000, 50000};  // LC
  if (name == "Mill-S") l = {166.7, 2000, 50000};
  if (name == "Mill-F") l = {500, 5000, 200000};
  if (name == "custom") l = g_custom;
  for (int i = 0; i < 3; ++i) c.axes[static_cast<std::size_t>(i)] = l;
  c.axis_mask = 0x7;
  c.lookahead_segments = g_lookahead;
  if (g_linear[0] > 0) {
    c.max_linear_velocity = g_linear[0];
    c.max_linear_acceleration = g_linear[1];
    c.max_linear_jerk = g_linear[2];
  }
  return c;
}

SegmentParams params(double feed_mm_min, double tol, TermCond term = TermCond::Blend) {
  SegmentParams p;
  p.type = MotionType::Feed;
  p.feed = feed_mm_min / 60.0;
  p.term = term;
  p.tolerance = tol;
  // G64 P without Q: LinuxCNC (and the interpreter) take Q = P.
  if (term == TermCond::Blend) p.naive_cam_tolerance = tol;
  return p;
}

// A program both as planner moves and as G-code text.
struct Bench {
  std::string name;
  Program prog;
  std::string gcode;
};

void add_line(Bench& b, double x, double y, double z, const SegmentParams& p) {
  ProgramMove m;
  m.end[0] = x;
  m.end[1] = y;
  m.end[2] = z;
  m.params = p;
  b.prog.moves.push_back(m);
  char buf[128];
  std::snprintf(buf, sizeof buf, "G1 X%.6f Y%.6f Z%.6f\n", x, y, z);
  b.gcode += buf;
}

std::string header(double feed_mm_min, double tol, bool exact = false) {
  char buf[160];
  if (exact) {
    std::snprintf(buf, sizeof buf, "G21 G90 G17 G61\nF%.3f\n", feed_mm_min);
  } else {
    std::snprintf(buf, sizeof buf, "G21 G90 G17 G64 P%g\nF%.3f\n", tol, feed_mm_min);
  }
  return buf;
}

Bench short_lines(double seg, double length, double feed) {
  Bench b{"short " + std::to_string(seg).substr(0, 6) + " mm x" + std::to_string(static_cast<int>(length / seg)), {}, ""};
  b.gcode = header(feed, 0.001);
  const int n = static_cast<int>(std::lround(length / seg));
  for (int i = 1; i <= n; ++i) add_line(b, seg * i, 0, 0, params(feed, 0.001));
  b.gcode += "M2\n";
  return b;
}

Bench zigzag(double seg, double amp, int n, double feed, double tol) {
  char nm[80];
  std::snprintf(nm, sizeof nm, "zigzag %g mm/%g x%d", seg, amp, n);
  Bench b{nm, {}, header(feed, tol)};
  for (int i = 1; i <= n; ++i) add_line(b, seg * i, (i % 2) * amp, 0, params(feed, tol));
  b.gcode += "M2\n";
  return b;
}

Bench polygon_circles(double r, double seg, int turns, double feed, double tol) {
  char nm[80];
  std::snprintf(nm, sizeof nm, "circle r%g by %g mm lines", r, seg);
  Bench b{nm, {}, header(feed, tol)};
  const int n = static_cast<int>(2 * std::numbers::pi * r / seg);
  add_line(b, r, 0, 0, params(feed, tol));
  for (int t = 0; t < turns; ++t) {
    for (int i = 1; i <= n; ++i) {
      const double a = 2 * std::numbers::pi * i / n;
      add_line(b, r * std::cos(a), r * std::sin(a), 0, params(feed, tol));
    }
  }
  b.gcode += "M2\n";
  return b;
}

Bench random_lines(uint32_t seed, int n, double feed, double tol) {
  Bench b{"random lines 0.05-5 mm", {}, header(feed, tol)};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  double x = 0, y = 0, z = 0;
  for (int i = 0; i < n; ++i) {
    const double len = 0.05 * std::pow(100.0, (u(rng) + 1) / 2);
    double dx = u(rng), dy = u(rng), dz = 0.3 * u(rng);
    const double nn = std::sqrt(dx * dx + dy * dy + dz * dz) + 1e-12;
    x = std::clamp(x + dx / nn * len, -50.0, 50.0);
    y = std::clamp(y + dy / nn * len, -50.0, 50.0);
    z = std::clamp(z + dz / nn * len, -10.0, 10.0);
    add_line(b, x, y, z, params(feed, tol));
  }
  b.gcode += "M2\n";
  return b;
}

Bench arcs_and_helices(double feed, double tol) {
  Bench b{"circles and helices", {}, header(feed, tol)};
  add_line(b, 20, 0, 0, params(feed, tol));
  auto arc = [&](double x, double y, double z, double cx, double cy, int turns, const char* g) {
    ProgramMove m;
    m.kind = ProgramMove::Kind::Circle;
    m.end[0] = x;
    m.end[1] = y;
    m.end[2] = z;
    m.center = {cx, cy, b.prog.moves.empty() ? 0.0 : b.prog.moves.back().end[2]};
    m.normal = {0, 0, std::strcmp(g, "G3") == 0 ? 1.0 : -1.0};
    m.turns = turns;
    m.params = params(feed, tol);
    m.params.type = MotionType::Arc;
    b.prog.moves.push_back(m);
    char buf[160];
    std::snprintf(buf, sizeof buf, "%s X%.6f Y%.6f Z%.6f I%.6f J%.6f P%d\n", g, x, y, z, cx - b.prog.moves[b.prog.moves.size() - 2].end[0],
                  cy - b.prog.moves[b.prog.moves.size() - 2].end[1], turns + 1);
    b.gcode += buf;
  };
  for (int k = 0; k < 6; ++k) {
    const double r = 2 + 3 * k;
    const double z = -1.0 * k;
    arc(20, 0, z, 20 - r, 0, 1, "G3");          // full circles (two turns)
    arc(20, 0, z - 1, 20 - r, 0, 2, "G2");      // helix down
    add_line(b, 20, 0, z - 1, params(feed, tol));
  }
  b.gcode += "M2\n";
  return b;
}

Bench corner(TermCond term, double tol) {
  char nm[80];
  if (term == TermCond::Blend) std::snprintf(nm, sizeof nm, "corner 90 deg G64 P%g", tol);
  else std::snprintf(nm, sizeof nm, "corner 90 deg G61");
  Bench b{nm, {}, header(6000, tol, term != TermCond::Blend)};
  add_line(b, 100, 0, 0, params(6000, tol, term));
  add_line(b, 100, 100, 0, params(6000, tol, term));
  b.gcode += "M2\n";
  return b;
}

// Program moves from G-code, through the project's interpreter.
class MoveCanon : public interp::TextCanon {
 public:
  MoveCanon(Program& prog, tooltable::ToolTable tools) : TextCanon(nullptr, std::move(tools), interp::Units::Mm), prog_(prog) {}
  void select_plane(interp::Plane p) override {
    TextCanon::select_plane(p);
    plane_ = p;
  }
  void set_feed_rate(double rate) override {
    TextCanon::set_feed_rate(rate);
    feed_ = rate / 60.0;
  }
  void set_motion_control_mode(interp::MotionMode mode, double tolerance) override {
    TextCanon::set_motion_control_mode(mode, tolerance);
    term_ = mode == interp::MotionMode::ExactStop   ? TermCond::ExactStop
            : mode == interp::MotionMode::ExactPath ? TermCond::ExactPath
                                                    : TermCond::Blend;
    tol_ = tolerance;
  }
  void set_naivecam_tolerance(double tolerance) override {
    TextCanon::set_naivecam_tolerance(tolerance);
    naive_tol_ = tolerance;
  }
  void straight_traverse(int line, const Pose& end) override {
    TextCanon::straight_traverse(line, end);
    push(ProgramMove::Kind::Line, end, line, MotionType::Traverse);
  }
  void straight_feed(int line, const Pose& end) override {
    TextCanon::straight_feed(line, end);
    push(ProgramMove::Kind::Line, end, line, MotionType::Feed);
  }
  void arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis, int rotation,
                double axis_end, const Pose& end) override {
    TextCanon::arc_feed(line, first_end, second_end, first_axis, second_axis, rotation, axis_end, end);
    int a0 = 0, a1 = 1, an = 2;  // G17
    if (plane_ == interp::Plane::XZ) a0 = 2, a1 = 0, an = 1;
    if (plane_ == interp::Plane::YZ) a0 = 1, a1 = 2, an = 0;
    ProgramMove& m = push(ProgramMove::Kind::Circle, end, line, MotionType::Arc);
    m.center = {pos_[0], pos_[1], pos_[2]};
    m.center[static_cast<std::size_t>(a0)] = first_axis;
    m.center[static_cast<std::size_t>(a1)] = second_axis;
    m.normal = {0, 0, 0};
    m.normal[static_cast<std::size_t>(an)] = rotation > 0 ? 1 : -1;
    m.turns = std::abs(rotation) - 1;
    pos_ = end;
  }
  void dwell(double seconds) override {
    TextCanon::dwell(seconds);
    ProgramMove m;
    m.kind = ProgramMove::Kind::Dwell;
    m.seconds = seconds;
    m.params.type = MotionType::Dwell;
    prog_.moves.push_back(m);
  }

 private:
  ProgramMove& push(ProgramMove::Kind kind, const Pose& end, int line, MotionType type) {
    ProgramMove m;
    m.kind = kind;
    m.end = end;
    m.params.type = type;
    m.params.line = line;
    m.params.feed = type == MotionType::Traverse ? 0 : feed_;
    m.params.term = term_;
    m.params.tolerance = tol_;
    m.params.naive_cam_tolerance = term_ == TermCond::Blend ? naive_tol_ : 0.0;
    prog_.moves.push_back(m);
    if (kind == ProgramMove::Kind::Line) pos_ = end;
    return prog_.moves.back();
  }
  Program& prog_;
  interp::Plane plane_ = interp::Plane::XY;
  double feed_ = 0;
  TermCond term_ = TermCond::Blend;
  double tol_ = 0;
  double naive_tol_ = 0;
  Pose pos_;
};

bool load_ngc(const std::string& path, Bench& b, double default_tol) {
  b.name = std::filesystem::path(path).filename().string();
  // Tools 1..9 (LinuxCNC's sample programs change tools).
  const auto tbl = std::filesystem::temp_directory_path() / "bench_tp_tools.tbl";
  {
    std::ofstream t(tbl);
    for (int i = 1; i < 10; ++i) t << "T" << i << " P" << i << " D10 ;\n";
  }
  MoveCanon canon(b.prog, tooltable::ToolTable::load(tbl, tooltable::ChangerKind::NonRandom));
  interp::Config cfg;
  char startup[80];
  std::snprintf(startup, sizeof startup, "G21 G90 G17 G40 G49 G80 G94 G64 P%g", default_tol);
  cfg.startup_code = startup;
  interp::Interpreter in(canon, cfg);
  try {
    in.init();
    in.open(path);
    in.run_to_end();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), e.what());
    return false;
  }
  // Programs start at the origin (LinuxCNC's driver starts every program
  // there too), or where --start says.
  for (int i = 0; i < 3; ++i) b.prog.start[i] = g_start[i];
  return !b.prog.moves.empty();
}

double pct(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}
double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}
double vmax(const std::vector<double>& v) { return v.empty() ? 0 : *std::max_element(v.begin(), v.end()); }

bool g_print_end = false;

void run_one(const Bench& b, const std::string& prof, double T) {
  const PlannerConfig cfg = profile(prof, T);
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  RunOptions opt;
  opt.measure_cpu = true;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 64;  // an interpreter that keeps up
  const RunResult r = run_program(*planner, cfg, b.prog, opt);
  std::printf("%-34s %-6s %4.0f %s %9.3f  %5.3f %5.3f %5.3f  %6.3f  %5.1f%%  %6.1f %6.1f %7.1f %7.1f  %6.2f %7.1f\n",
              b.name.c_str(), prof.c_str(), T * 1e6, r.completed ? "ok" : "NOT DONE", r.stats.time_s, r.stats.ratio_v,
              r.stats.ratio_a, r.stats.ratio_j, r.stats.deviation_ratio, 100 * r.stats.at_feed_fraction,
              mean(r.cycle_ns) / 1e3, pct(r.cycle_ns, 0.99) / 1e3, pct(r.cycle_ns, 0.999) / 1e3, vmax(r.cycle_ns) / 1e3,
              mean(r.add_ns) / 1e3, pct(r.add_ns, 0.999) / 1e3);
  if (g_print_end) {
    std::printf("  end position X%.6f Y%.6f Z%.6f, end error %.3g\n", r.last.position[0], r.last.position[1],
                r.last.position[2], r.stats.end_error);
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string write_dir;
  std::vector<std::string> ngc;
  bool only_ngc = false;
  double period = 0;
  bool custom = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") quick = true;
    else if (a == "--write-ngc" && i + 1 < argc) write_dir = argv[++i];
    else if (a == "--ngc" && i + 1 < argc) ngc.push_back(argv[++i]);
    else if (a == "--only-ngc") only_ngc = true;
    else if (a == "--lookahead" && i + 1 < argc) g_lookahead = std::atoi(argv[++i]);
    else if (a == "--period" && i + 1 < argc) period = std::atof(argv[++i]);
    else if (a == "--limits" && i + 1 < argc &&
             std::sscanf(argv[++i], "%lf,%lf,%lf", &g_custom.max_velocity, &g_custom.max_acceleration,
                         &g_custom.max_jerk) == 3) custom = true;
    else if (a == "--start" && i + 1 < argc &&
             std::sscanf(argv[++i], "%lf,%lf,%lf", &g_start[0], &g_start[1], &g_start[2]) == 3) {}
    else if (a == "--linear" && i + 1 < argc &&
             std::sscanf(argv[++i], "%lf,%lf,%lf", &g_linear[0], &g_linear[1], &g_linear[2]) == 3) {}
    else {
      std::fprintf(stderr,
                   "usage: bench_tp [--quick] [--write-ngc DIR] [--ngc FILE ...] [--only-ngc]\n"
                   "                [--limits V,A,J] [--linear V,A,J] [--lookahead N] [--period S] [--start X,Y,Z]\n"
                   "  --only-ngc: only the --ngc programs (with their end positions), no attainment table\n"
                   "  --limits: per-axis velocity, acceleration, jerk of X, Y, Z (units/s...) instead of the profiles\n"
                   "  --linear: limits on the XYZ norm ([TRAJ]MAX_LINEAR_VELOCITY, _ACCELERATION, _JERK)\n");
      return 2;
    }
  }
  if (g_lookahead < 1 || (period != 0 && !(period > 0))) {
    std::fprintf(stderr, "bench_tp: --lookahead must be at least 1 and --period positive\n");
    return 2;
  }
  g_print_end = only_ngc;
  std::vector<Bench> progs;
  if (!only_ngc) {
  progs.push_back(short_lines(0.01, 50, 6000));
  progs.push_back(zigzag(0.1, 0.01, 2000, 6000, 0.01));
  progs.push_back(polygon_circles(10, 0.05, 2, 6000, 0.01));
  progs.push_back(random_lines(7, quick ? 300 : 2000, 6000, 0.01));
  progs.push_back(arcs_and_helices(3000, 0.01));
  progs.push_back(corner(TermCond::ExactPath, 0));
  for (double p : {0.001, 0.01, 0.1}) progs.push_back(corner(TermCond::Blend, p));
  }
  for (const std::string& f : ngc) {
    Bench b;
    if (load_ngc(f, b, 0.01)) progs.push_back(std::move(b));
  }
  if (!write_dir.empty()) {
    std::filesystem::create_directories(write_dir);
    int k = 0;
    for (const Bench& b : progs) {
      if (b.gcode.empty()) continue;
      char fn[64];
      std::snprintf(fn, sizeof fn, "tp%02d.ngc", k++);
      std::ofstream(std::filesystem::path(write_dir) / fn) << "(" << b.name << ")\n" << b.gcode;
      std::printf("wrote %s/%s  (%s)\n", write_dir.c_str(), fn, b.name.c_str());
    }
  }

  std::printf("\n== traverse time, limits, tolerance, CPU (inline planner; CPU in us)\n");
  std::printf("%-34s %-6s %4s %s %9s  %5s %5s %5s  %6s  %6s  %6s %6s %7s %7s  %6s %7s\n", "program", "limits", "T_us",
              "ok", "time_s", "v/V", "a/A", "j/J", "dev/P", "@feed", "cyc_mn", "p99", "p99.9", "max", "seg_mn",
              "seg999");
  std::vector<std::string> profs = quick ? std::vector<std::string>{"LC"} : std::vector<std::string>{"LC", "Mill-S", "Mill-F"};
  std::vector<double> periods = quick ? std::vector<double>{0.001} : std::vector<double>{0.001, 0.00025};
  if (custom) profs = {"custom"};
  if (period > 0) periods = {period};
  for (const Bench& b : progs) {
    for (const std::string& pr : profs) {
      for (double T : periods) run_one(b, pr, T);
    }
  }

  if (only_ngc) return 0;
  std::printf("\n== short-segment feed attainment: collinear segments over 100 mm (20 mm for 1 um; F6000 = 100 mm/s, LC limits)\n");
  std::printf("%-10s %5s %10s %10s %9s %12s\n", "segment", "T_us", "mean/F", "peak/F", "@feed", "LinuxCNC cap");
  for (double seg : {0.001, 0.01, 0.1, 1.0}) {
    for (double T : {0.001, 0.00025}) {
      const double len = seg < 0.005 ? 20.0 : 100.0;
      Bench b = short_lines(seg, len, 6000);
      PlannerConfig cfg = profile("LC", T);
      // Look-ahead over 12 mm: more than the 6 mm a stop from 100 mm/s needs.
      cfg.lookahead_segments = std::max(2000, static_cast<int>(12.0 / seg));
      auto planner = make_planner(cfg, PlannerThreading::Inline);
      RunOptions opt;
      opt.flush_at_end = true;
      opt.moves_per_cycle = 1 << 20;
      const RunResult r = run_program(*planner, cfg, b.prog, opt);
      // LinuxCNC 2.9: every segment lasts at least 1.02 servo periods.
      const double cap = std::min(1.0, seg / (1.02 * T) / 100.0);
      std::printf("%-10g %5.0f %9.1f%% %9.1f%% %8.1f%% %11.1f%%\n", seg, T * 1e6, 100 * r.stats.mean_feed_ratio,
                  100 * r.stats.max_v[0] / 100.0, 100 * r.stats.at_feed_fraction, 100 * cap);
    }
  }
  return 0;
}
