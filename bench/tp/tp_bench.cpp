// Trajectory planner benchmark (docs/tp.md): runs fixed programs through
// tp::LookaheadPlanner (inline: planning and servo work on this thread, the
// way a 1-core machine would run it) and prints per program: traverse time,
// a lower bound of it where one is computable, worst per-axis |v|, |a|, |j|
// relative to the limits, worst distance from the programmed path relative
// to the tolerance, share of time at the programmed feed, and planner CPU
// per servo cycle and per queued segment. Also short-segment feed
// attainment for segment lengths 1 um ... 1 mm.
//
// Every program, generated or read (--ngc), is G-code read by the
// project's interpreter through the task controller's canon and run with
// the limits the motion controller would have in force, by the same code
// as `cnc-estimate` (core/task/estimate.hpp): G20, work offsets (G5x with
// the INI's parameter file), G92, XY rotation and tool length offsets act
// exactly as under cncd, and programs stop where cncd's task waits for
// motion (M6, M66, probes...). The limits come from an INI file (--ini, as
// cncd reads it) or from the built-in profiles (Mill-S, Mill-F, LC), which
// are INI files too, written from the options and read by the same owners.
//
//   bench_tp [--quick] [--ini FILE] [--write-ngc DIR] [--ngc FILE ...] [--only-ngc]
//            [--limits [L:]V,A,J ...] [--linear V,A,J] [--lookahead N] [--period S]
//            [--start X,Y,Z] [--profile FILE]
//
// --ini: the limits, [TRAJ]LOOKAHEAD_SEGMENTS, [EMCMOT]SERVO_PERIOD,
// units, parameter file, tool table and start-up code of a configuration;
// --ngc programs start where "home all" leaves that machine.
// --only-ngc runs only the --ngc programs and prints their end positions
// (machine coordinates); --limits V,A,J sets velocity, acceleration, jerk of
// X, Y and Z, --limits X:V,A,J of one axis (repeatable); --linear the same on
// the XYZ norm ([TRAJ]MAX_LINEAR_*); --lookahead (moves), --period (s) and
// --start (machine coordinates where --ngc programs start) override the
// INI's or the profiles'. bench/tp/cncd_program.sh compares the prediction
// with cncd on configs/sim.
// --profile FILE appends, per servo cycle of each --ngc program, the time,
// path speed and program line (as LinuxCNC's halsampler profile has them),
// to see line by line where a program spends its time.
// --write-ngc writes the generated programs as G-code (for the LinuxCNC
// side-by-side, bench/tp/compare_linuxcnc.sh).
// Figures never fail the run: timing belongs to benchmarks, not tests.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "core/ini/ini_file.hpp"
#include "core/task/estimate.hpp"
#include "core/tp/curve.hpp"
#include "core/util/error.hpp"

namespace {

using namespace cnc;
using namespace cnc::tp;

// --- options ---
// --limits: per-axis X, Y, Z velocity, acceleration, jerk (the "custom" profile).
AxisLimits g_custom[3] = {{100, 1000, 50000}, {100, 1000, 50000}, {100, 1000, 50000}};
std::optional<int> g_lookahead;
std::optional<double> g_period;
// --linear: [TRAJ]MAX_LINEAR_* (limits on the XYZ norm), off by default.
double g_linear[3] = {0, 0, 0};
std::optional<Pose> g_start;

// A profile as the INI file a machine would have: trivkins XYZ, each axis
// and joint with the profile's limits, homed at the origin (where
// LinuxCNC's simulated machine starts every program too), tools 1..9
// (LinuxCNC's sample programs change tools), G64 P0.01 by default.
estimate::Machine profile_machine(const std::string& name, double cycle_s) {
  AxisLimits l[3];
  for (auto& x : l) x = {100, 1000, 50000};  // LC
  for (auto& x : l) {
    if (name == "Mill-S") x = {166.7, 2000, 50000};
    if (name == "Mill-F") x = {500, 5000, 200000};
  }
  if (name == "custom") std::copy(g_custom, g_custom + 3, l);
  const auto tbl = std::filesystem::temp_directory_path() / "bench_tp_tools.tbl";
  if (!std::filesystem::exists(tbl)) {
    std::ofstream t(tbl);
    for (int i = 1; i < 10; ++i) t << "T" << i << " P" << i << " D10 ;\n";
  }
  std::string ini;
  char buf[256];
  std::snprintf(buf, sizeof buf, "[EMCMOT]\nSERVO_PERIOD = %lld\n", static_cast<long long>(std::llround(cycle_s * 1e9)));
  ini += buf;
  ini += "[TRAJ]\nCOORDINATES = X Y Z\nLINEAR_UNITS = mm\nANGULAR_UNITS = degree\n";
  std::snprintf(buf, sizeof buf, "LOOKAHEAD_SEGMENTS = %d\n", g_lookahead.value_or(2000));
  ini += buf;
  if (g_linear[0] > 0) {
    std::snprintf(buf, sizeof buf, "MAX_LINEAR_VELOCITY = %.17g\nMAX_LINEAR_ACCELERATION = %.17g\nMAX_LINEAR_JERK = %.17g\n",
                  g_linear[0], g_linear[1], g_linear[2]);
    ini += buf;
  }
  ini += "[KINS]\nKINEMATICS = trivkins coordinates=XYZ\nJOINTS = 3\n";
  for (int i = 0; i < 3; ++i) {
    for (const char* sec : {"AXIS_", "JOINT_"}) {
      std::snprintf(buf, sizeof buf, "[%s%c]\nMAX_VELOCITY = %.17g\nMAX_ACCELERATION = %.17g\nMAX_JERK = %.17g\n", sec,
                    std::strcmp(sec, "AXIS_") == 0 ? "XYZ"[i] : "012"[i], l[i].max_velocity, l[i].max_acceleration,
                    l[i].max_jerk);
      ini += buf;
    }
  }
  ini += "[RS274NGC]\nRS274NGC_STARTUP_CODE = G21 G90 G17 G40 G49 G80 G94 G64 P0.01\n";
  ini += "[EMCIO]\nTOOL_TABLE = " + tbl.string() + "\n";
  return estimate::load_machine(ini::IniFile::parse(ini, "bench_tp:" + name + ".ini"));
}

// --ini, with --lookahead / --period on top.
estimate::Machine ini_machine(const std::string& path) {
  estimate::Machine m = estimate::load_machine(path);
  if (g_lookahead) m.planner.lookahead_segments = *g_lookahead;
  if (g_period) m.planner.cycle_time_s = *g_period;
  return m;
}

// --- generated programs (G-code text) ---
struct Bench {
  std::string name;
  std::string gcode;                // generated programs
  std::filesystem::path file;       // --ngc programs
};

std::string header(double feed_mm_min, double tol, bool exact = false) {
  char buf[160];
  if (exact) {
    std::snprintf(buf, sizeof buf, "G21 G90 G17 G61\nF%.3f\n", feed_mm_min);
  } else {
    std::snprintf(buf, sizeof buf, "G21 G90 G17 G64 P%g\nF%.3f\n", tol, feed_mm_min);
  }
  return buf;
}

void line(std::string& g, double x, double y, double z) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "G1 X%.6f Y%.6f Z%.6f\n", x, y, z);
  g += buf;
}

Bench short_lines(double seg, double length, double feed) {
  Bench b{"short " + std::to_string(seg).substr(0, 6) + " mm x" + std::to_string(static_cast<int>(length / seg)), "", {}};
  b.gcode = header(feed, 0.001);
  const int n = static_cast<int>(std::lround(length / seg));
  for (int i = 1; i <= n; ++i) line(b.gcode, seg * i, 0, 0);
  b.gcode += "M2\n";
  return b;
}

Bench zigzag(double seg, double amp, int n, double feed, double tol) {
  char nm[80];
  std::snprintf(nm, sizeof nm, "zigzag %g mm/%g x%d", seg, amp, n);
  Bench b{nm, header(feed, tol), {}};
  for (int i = 1; i <= n; ++i) line(b.gcode, seg * i, (i % 2) * amp, 0);
  b.gcode += "M2\n";
  return b;
}

Bench polygon_circles(double r, double seg, int turns, double feed, double tol) {
  char nm[80];
  std::snprintf(nm, sizeof nm, "circle r%g by %g mm lines", r, seg);
  Bench b{nm, header(feed, tol), {}};
  const int n = static_cast<int>(2 * std::numbers::pi * r / seg);
  line(b.gcode, r, 0, 0);
  for (int t = 0; t < turns; ++t) {
    for (int i = 1; i <= n; ++i) {
      const double a = 2 * std::numbers::pi * i / n;
      line(b.gcode, r * std::cos(a), r * std::sin(a), 0);
    }
  }
  b.gcode += "M2\n";
  return b;
}

Bench random_lines(uint32_t seed, int n, double feed, double tol) {
  Bench b{"random lines 0.05-5 mm", header(feed, tol), {}};
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
    line(b.gcode, x, y, z);
  }
  b.gcode += "M2\n";
  return b;
}

Bench arcs_and_helices(double feed, double tol) {
  Bench b{"circles and helices", header(feed, tol), {}};
  line(b.gcode, 20, 0, 0);
  char buf[160];
  for (int k = 0; k < 6; ++k) {
    const double r = 2 + 3 * k;
    const double z = -1.0 * k;
    // Full circles (two turns), then a helix down (three turns), from X20 Y0.
    std::snprintf(buf, sizeof buf, "G3 X20 Y0 Z%.6f I%.6f J0 P2\n", z, -r);
    b.gcode += buf;
    std::snprintf(buf, sizeof buf, "G2 X20 Y0 Z%.6f I%.6f J0 P3\n", z - 1, -r);
    b.gcode += buf;
    line(b.gcode, 20, 0, z - 1);
  }
  b.gcode += "M2\n";
  return b;
}

Bench corner(TermCond term, double tol) {
  char nm[80];
  if (term == TermCond::Blend) std::snprintf(nm, sizeof nm, "corner 90 deg G64 P%g", tol);
  else std::snprintf(nm, sizeof nm, "corner 90 deg G61");
  Bench b{nm, header(6000, tol, term != TermCond::Blend), {}};
  line(b.gcode, 100, 0, 0);
  line(b.gcode, 100, 100, 0);
  b.gcode += "M2\n";
  return b;
}

// CAM-style: adaptive clearing of a 40 mm slot by trochoidal loops (tool
// radius 3, loop radius 2, 0.3 mm step): each loop a G3 arc on the cutting
// side and the way back as 8 short lines (as CAM systems linearise it),
// at Z-1, F3000, G64 P0.01.
Bench trochoidal(int loops) {
  Bench b{"CAM trochoidal slot", header(3000, 0.01), {}};
  line(b.gcode, 0, 2, 0);
  line(b.gcode, 0, 2, -1);
  char buf[160];
  const double r = 2, step = 0.3;
  for (int i = 0; i < loops; ++i) {
    const double cx = i * step;
    // From (cx, 2) through (cx + 2, 0) to (cx, -2): clockwise around (cx, 0).
    std::snprintf(buf, sizeof buf, "G2 X%.6f Y%.6f I%.6f J%.6f\n", cx, -r, 0.0, -r);
    b.gcode += buf;
    // Back over the left side, advancing by `step`: a half ellipse in 8 lines.
    for (int k = 1; k <= 8; ++k) {
      const double a = -std::numbers::pi / 2 - std::numbers::pi * k / 8;
      line(b.gcode, cx + step * k / 8 + 0.6 * r * std::cos(a), r * std::sin(a), -1);
    }
  }
  b.gcode += "G0 Z5\nM2\n";
  return b;
}

// CAM-style: 3-D surfacing raster (ball end finishing of z = 2 sin(x/8)
// cos(y/12)): zig-zag passes along X of 0.5 mm segments, 1 mm stepover,
// F4000, G64 P0.01.
Bench surfacing(int passes) {
  Bench b{"CAM 3-D surfacing raster", header(4000, 0.01), {}};
  const auto z = [](double x, double y) { return 2 * std::sin(x / 8) * std::cos(y / 12) - 3; };
  line(b.gcode, 0, 0, z(0, 0));
  for (int p = 0; p < passes; ++p) {
    const double y = p * 1.0;
    if (p > 0) line(b.gcode, p % 2 ? 60 : 0, y, z(p % 2 ? 60 : 0, y));
    for (int i = 1; i <= 120; ++i) {
      const double x = p % 2 ? 60 - 0.5 * i : 0.5 * i;
      line(b.gcode, x, y, z(x, y));
    }
  }
  b.gcode += "M2\n";
  return b;
}

// CAM-style: a dense polyline with small direction changes (a contour of
// r = 30 + 6 sin(5 t) sampled every ~0.1 mm, 0.3-3 degrees per vertex),
// F6000, G64 P0.01.
Bench dense_contour(int points) {
  Bench b{"CAM dense contour 0.1 mm", header(6000, 0.01), {}};
  for (int i = 0; i <= points; ++i) {
    const double t = 2 * std::numbers::pi * i / points;
    const double r = 30 + 6 * std::sin(5 * t);
    line(b.gcode, r * std::cos(t), r * std::sin(t), 0);
  }
  b.gcode += "M2\n";
  return b;
}

// --- lower bound of the traverse time ---
// Minimum time of a rest-to-rest straight move of length L under velocity
// v, acceleration a and jerk j (third-order profile).
double rest_to_rest(double L, double v, double a, double j) {
  if (!(L > 0)) return 0;
  // Time and distance to reach velocity w from rest (and back).
  const auto ramp = [&](double w, double& t, double& s) {
    t = w * j >= a * a ? w / a + a / j : 2 * std::sqrt(w / j);
    s = w * t / 2;
  };
  double t = 0, s = 0;
  ramp(v, t, s);
  if (2 * s <= L) return 2 * t + (L - 2 * s) / v;
  double lo = 0, hi = v;
  for (int k = 0; k < 100; ++k) {
    const double w = (lo + hi) / 2;
    ramp(w, t, s);
    (2 * s <= L ? lo : hi) = w;
  }
  ramp(lo, t, s);
  return 2 * t;
}

// The fastest motion over a straight length L from speed v0 to v1 under
// speed v, acceleration a and jerk j, the accelerations at both ends free
// (a corner may be passed accelerating): the trapezoid, and where it
// speeds up and brakes with no cruise between, the acceleration's swing
// from +a to -a at j (2a/j long, a^3/(3j^2) shorter than the instant
// switch), solved for the speed at which the swing starts.
double fastest_between(double L, double v0, double v1, double v, double a, double j) {
  const double peak = std::min(v, std::sqrt((v0 * v0 + v1 * v1) / 2 + a * L));
  const double d_up = (peak * peak - v0 * v0) / (2 * a);
  const double d_down = (peak * peak - v1 * v1) / (2 * a);
  const double trapezoid = (peak - v0) / a + (peak - v1) / a + std::max(0.0, L - d_up - d_down) / peak;
  const double vm = std::max(v0, v1);
  if (!(j < 1e299) || peak >= v || peak <= vm) return trapezoid;
  const double tau = 2 * a / j;  // the swing
  const auto dist = [&](double vs) {
    return (vs * vs - v0 * v0) / (2 * a) + vs * tau + (2.0 / 3.0) * a * a * a / (j * j) + (vs * vs - v1 * v1) / (2 * a);
  };
  if (dist(vm) > L || vm + a * a / (2 * j) > v) return trapezoid;  // no room for a full swing: the trapezoid still bounds
  double lo = vm, hi = peak;
  for (int k = 0; k < 80; ++k) {
    const double mid = (lo + hi) / 2;
    (dist(mid) <= L ? lo : hi) = mid;
  }
  if (lo + a * a / (2 * j) > v) return trapezoid;
  return std::max(trapezoid, (lo - v0) / a + tau + (lo - v1) / a);
}

// A lower bound for planners that follow the path in order within G64 P,
// counting its sharp corners (docs/tp.md, "The corner bound"). At a blended
// corner between two straight moves d1 -> d2 of angle theta, take the unit
// vector e perpendicular to d2 in their plane (e.d1 = sin theta): within P
// of the outgoing move and of the corner, e.(x - corner) lies in [-P, P],
// so from the last time it is -P the motion along e (acceleration at most
// A_e = sum |e_i| A_i) must stop within 2P: its speed there is at most
// sqrt(4 A_e P). That holds while the tool stays near the outgoing move
// for the time the stop takes (at most sqrt(4P / A_e), at most V times
// that in path length): shorter moves get no corner cap. Backward in time
// the same holds for f, perpendicular to d1 (the tool was within P of the
// incoming move), so at that moment |v.e| and |v.f| are both bounded and
// the speed is at most their larger bound over min(sin, cos)(theta / 2)
// (sqrt 2 times it at 90 degrees). Between the caps, moves accelerate and brake at most
// at their straight-line limit (min A_i / |d_i|; curved moves without a
// limit) under their speed cap, and where they speed up and brake their
// acceleration swings at most at the jerk limit (fastest_between); exact
// stops, exact-path direction changes and dwells are rests. Each move's
// length is shortened by what cutting its corners within P may save.
double corner_bound(const estimate::Moves& moves, const PlannerConfig& cfg) {
  struct Element {
    double len = 0, v = 0, a = 0, j = 1e300;
    bool line = false;
    std::array<double, 3> dir{};
    double tol = 0;        // G64 P of a blended end, 0 otherwise (G64 without P: no cap)
    bool exact_path = false;  // G61: a rest where the direction changes
    bool rest_after = false;
  };
  double total = 0;
  for (const Program& p : moves.sections) {
    std::vector<Element> el;
    Pose pos = p.start;
    for (std::size_t i = 0; i < p.moves.size(); ++i) {
      const ProgramMove& m = p.moves[i];
      if (m.kind == ProgramMove::Kind::Dwell) {
        if (!el.empty()) el.back().rest_after = true;
        total += m.seconds;
        continue;
      }
      Curve c;
      const bool ok = m.kind == ProgramMove::Kind::Line ? make_line(pos, m.end, 0, c)
                                                         : make_helix(pos, m.end, m.center, m.normal, m.turns, 0, c);
      pos = m.end;
      if (!ok || !(c.length > 0)) continue;
      Element e;
      e.len = c.length;
      e.line = !c.is_curved();
      e.v = m.params.feed > 0 ? m.params.feed : 1e300;
      if (m.params.max_velocity > 0) e.v = std::min(e.v, m.params.max_velocity);
      if (cfg.max_linear_velocity > 0) e.v = std::min(e.v, cfg.max_linear_velocity);
      e.a = 1e300;
      for (int ax = 0; ax < kNumAxes; ++ax) {
        if (!(cfg.axis_mask & (1U << ax)) || c.bound1[ax] < 1e-12) continue;
        const AxisLimits& l = cfg.axes[static_cast<std::size_t>(ax)];
        e.v = std::min(e.v, l.max_velocity / c.bound1[ax]);
        if (e.line) e.a = std::min(e.a, l.max_acceleration / c.bound1[ax]);
        if (e.line) e.j = std::min(e.j, l.max_jerk / c.bound1[ax]);
      }
      if (e.line) {
        for (int k = 0; k < 3; ++k) e.dir[static_cast<std::size_t>(k)] = c.rate[k];
      }
      e.tol = m.params.term == TermCond::Blend ? m.params.tolerance : 0;
      e.exact_path = m.params.term == TermCond::ExactPath;
      e.rest_after = m.params.term == TermCond::ExactStop;
      el.push_back(e);
    }
    if (el.empty()) continue;
    const std::size_t n = el.size();
    // cap[k]: the speed at the junction after element k (the last: rest).
    std::vector<double> cap(n, 0);
    for (std::size_t k = 0; k + 1 < n; ++k) {
      const Element& a = el[k];
      const Element& b = el[k + 1];
      double c = 1e300;
      if (a.rest_after) {
        c = 0;
      } else if (a.line && b.line) {
        const double cosine = a.dir[0] * b.dir[0] + a.dir[1] * b.dir[1] + a.dir[2] * b.dir[2];
        const bool turns = std::fabs(cosine - 1) > 1e-9;
        if (turns && a.exact_path) {
          c = 0;
        } else if (turns && a.tol > 0) {
          const double sine = std::sqrt(std::max(0.0, 1 - cosine * cosine));
          if (sine > 1e-6) {
            // e: perpendicular to b.dir toward a.dir; f: perpendicular to a.dir toward b.dir.
            std::array<double, 3> e{}, f{};
            double ne = 0, nf = 0;
            for (std::size_t i = 0; i < 3; ++i) {
              e[i] = a.dir[i] - cosine * b.dir[i];
              f[i] = b.dir[i] - cosine * a.dir[i];
              ne += e[i] * e[i];
              nf += f[i] * f[i];
            }
            ne = std::sqrt(ne);
            nf = std::sqrt(nf);
            double ae = 0, af = 0;
            for (std::size_t i = 0; i < 3; ++i) {
              const double lim = cfg.axes[i].max_acceleration;
              ae += std::fabs(e[i] / ne) * lim;
              af += std::fabs(f[i] / nf) * lim;
            }
            const double P = a.tol;
            const double vmax = std::max(a.v, b.v);
            const bool long_enough = b.len >= 2 * P + vmax * std::sqrt(4 * P / ae) &&
                                     a.len >= 2 * P + vmax * std::sqrt(4 * P / af);
            // |v.e| <= sqrt(4 A_e P) and |v.f| <= sqrt(4 A_f P) there; e and
            // f make the angle pi - theta, so |v| is at most the larger
            // over min(sin, cos) of theta/2 (the rhombus' far corner).
            const double half = 0.5 * std::acos(std::clamp(cosine, -1.0, 1.0));
            const double u = std::sqrt(4 * std::max(ae, af) * P);
            if (long_enough) c = u / std::max(1e-12, std::min(std::sin(half), std::cos(half)));
          }
        }
      }
      cap[k] = c;
    }
    cap[n - 1] = 0;
    // A path within P may cut a corner: from each move the length a chord
    // can save at its ends, 2P tan(theta/4) at a corner of angle theta
    // between lines, 2P where an arc meets it (its tangent is not
    // computed here); the program's own end points are exact.
    for (std::size_t k = 0; k + 1 < n; ++k) {
      Element& a = el[k];
      Element& b = el[k + 1];
      if (a.rest_after || a.exact_path || !(a.tol > 0)) continue;
      double cut = 2 * a.tol;
      if (a.line && b.line) {
        const double cosine = std::clamp(a.dir[0] * b.dir[0] + a.dir[1] * b.dir[1] + a.dir[2] * b.dir[2], -1.0, 1.0);
        cut = 2 * a.tol * std::tan(std::acos(cosine) / 4);
      }
      a.len = std::max(0.0, a.len - cut);
      b.len = std::max(0.0, b.len - cut);
    }
    // Forward and backward passes: the speed at each junction.
    std::vector<double> w(n + 1, 0);  // w[k]: speed at the start of element k; w[n]: end
    w[0] = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const Element& e = el[k];
      const double reach = e.a >= 1e299 ? 1e300 : std::sqrt(w[k] * w[k] + 2 * e.a * e.len);
      double next = std::min({cap[k], e.v, reach});
      if (k + 1 < n) next = std::min(next, el[k + 1].v);
      w[k + 1] = next;
    }
    w[n] = 0;
    for (std::size_t k = n; k-- > 0;) {
      const Element& e = el[k];
      const double reach = e.a >= 1e299 ? 1e300 : std::sqrt(w[k + 1] * w[k + 1] + 2 * e.a * e.len);
      w[k] = std::min(w[k], reach);
    }
    for (std::size_t k = 0; k < n; ++k) {
      const Element& e = el[k];
      const double v0 = w[k], v1 = w[k + 1];
      if (e.a >= 1e299) {
        total += e.len / e.v;
        continue;
      }
      total += fastest_between(e.len, v0, v1, e.v, e.a, e.j);
    }
  }
  return total;
}

// A lower bound no planner within the limits can beat: every move takes at
// least its length over the highest speed it allows (feed, cap, per-axis
// velocity in its direction); a run of collinear lines between two rests
// (section ends, exact stops, exact-path corners, dwells) at least the
// minimum time of one rest-to-rest move over it under the per-axis
// limits along its direction; dwells their time. Blended corners are
// taken at full speed, so the bound is low for programs of many corners.
double lower_bound(const estimate::Moves& moves, const PlannerConfig& cfg) {
  double total = 0;
  for (const Program& p : moves.sections) {
    Pose pos = p.start;
    double run_len = 0, run_time = 0, run_v = 0, run_a = 0, run_j = 0;
    std::array<double, 3> run_dir{};
    bool run_straight = true;
    const auto close_run = [&] {
      double t = run_time;
      if (run_straight && run_len > 0) t = std::max(t, rest_to_rest(run_len, run_v, run_a, run_j));
      total += t;
      run_len = run_time = run_v = 0;
      run_a = run_j = 0;
      run_straight = true;
      run_dir = {};
    };
    for (std::size_t i = 0; i < p.moves.size(); ++i) {
      const ProgramMove& m = p.moves[i];
      if (m.kind == ProgramMove::Kind::Dwell) {
        close_run();
        total += m.seconds;
        continue;
      }
      Curve c;
      const bool ok = m.kind == ProgramMove::Kind::Line ? make_line(pos, m.end, 0, c)
                                                         : make_helix(pos, m.end, m.center, m.normal, m.turns, 0, c);
      if (!ok) continue;
      double v = m.params.feed > 0 ? m.params.feed : 1e300;
      if (m.params.max_velocity > 0) v = std::min(v, m.params.max_velocity);
      double a = 1e300, j = 1e300;
      for (int ax = 0; ax < kNumAxes; ++ax) {
        if (!(cfg.axis_mask & (1U << ax)) || c.bound1[ax] < 1e-12) continue;
        const AxisLimits& l = cfg.axes[static_cast<std::size_t>(ax)];
        v = std::min(v, l.max_velocity / c.bound1[ax]);
        a = std::min(a, l.max_acceleration / c.bound1[ax]);
        j = std::min(j, l.max_jerk / c.bound1[ax]);
      }
      if (cfg.max_linear_velocity > 0) v = std::min(v, cfg.max_linear_velocity);
      std::array<double, 3> dir{};
      if (!c.is_curved()) {
        for (int k = 0; k < 3; ++k) dir[static_cast<std::size_t>(k)] = c.rate[k];
      }
      const bool collinear = !c.is_curved() && (run_len == 0 || std::fabs(dir[0] * run_dir[0] + dir[1] * run_dir[1] +
                                                                         dir[2] * run_dir[2] - 1) < 1e-9);
      if (!collinear && run_len > 0) {
        // A corner or a curve: the run goes on without a rest, no longer straight.
        run_straight = false;
      }
      if (run_len == 0) run_dir = dir;
      run_straight = run_straight && !c.is_curved();
      run_len += c.length;
      run_time += c.length / v;
      run_v = std::max(run_v, v);
      run_a = std::max(run_a, a);
      run_j = std::max(run_j, j);
      pos = m.end;
      // Rests: exact stop, and exact path at a change of direction.
      bool rest = m.params.term == TermCond::ExactStop;
      if (m.params.term == TermCond::ExactPath && i + 1 < p.moves.size()) {
        const ProgramMove& n = p.moves[i + 1];
        Curve cn;
        if (n.kind == ProgramMove::Kind::Line && !c.is_curved() && make_line(pos, n.end, 0, cn)) {
          const double d = cn.rate[0] * dir[0] + cn.rate[1] * dir[1] + cn.rate[2] * dir[2];
          rest = std::fabs(d - 1) > 1e-9;
        } else {
          rest = false;  // tangency unknown here: no rest assumed (still a bound)
        }
      }
      if (rest) close_run();
    }
    close_run();
  }
  return total;
}

// --- running ---
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
// --profile FILE: per servo cycle, time, path speed and program line of the
// --ngc programs (the columns of LinuxCNC's halsampler profile), to find
// where a program spends its time line by line.
std::string g_profile;

// The program's G-code in a file (generated programs are written to a
// temporary one) read through the task canon from `start`.
estimate::Moves read(const Bench& b, const estimate::Machine& m, const Pose& start) {
  std::filesystem::path f = b.file;
  if (f.empty()) {
    f = std::filesystem::temp_directory_path() / ("bench_tp_" + std::to_string(::getpid()) + ".ngc");
    std::ofstream(f) << b.gcode;
  }
  estimate::Moves mv = estimate::read_program(m, f, start);
  if (b.file.empty()) std::filesystem::remove(f);
  return mv;
}

void run_one(const Bench& b, const estimate::Machine& m, const std::string& prof) {
  const Pose start = g_start.value_or(m.home);
  const estimate::Moves mv = read(b, m, start);
  if (!mv.error.empty()) {
    std::printf("%-34s %-6s  %s\n", b.name.c_str(), prof.c_str(), mv.error.c_str());
    return;
  }
  estimate::Options opt;
  opt.measure_cpu = true;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 64;  // an interpreter that keeps up
  std::ofstream profile;
  uint64_t cycle = 0;
  if (!g_profile.empty() && !b.file.empty()) {
    profile.open(g_profile, std::ios::app);
    if (!profile) throw ConfigError(g_profile, 0, "cannot write the profile here");
    profile << "# " << b.file.string() << " (" << prof << ", " << std::lround(m.planner.cycle_time_s * 1e6)
            << " us): time_s path_velocity line\n";
    opt.after_cycle = [&](const CycleOutputs& out) {
      ++cycle;
      char row[96];
      std::snprintf(row, sizeof row, "%.6f %.4f %d\n", static_cast<double>(cycle) * m.planner.cycle_time_s,
                    out.path_velocity, out.line);
      profile << row;
    };
  }
  const estimate::Result r = estimate::run(m, mv, opt);
  const double T = m.planner.cycle_time_s;
  std::printf("%-34s %-6s %4.0f %-2s %9.3f %9.3f  %5.3f %5.3f %5.3f  %6.3f  %5.1f%%  %6.1f %6.1f %7.1f %7.1f  %6.2f %7.1f %6llu\n",
              b.name.c_str(), prof.c_str(), T * 1e6, r.completed ? "ok" : "no", r.stats.time_s,
              std::max(lower_bound(mv, m.planner), corner_bound(mv, m.planner)), r.stats.ratio_v, r.stats.ratio_a, r.stats.ratio_j, r.stats.deviation_ratio,
              100 * r.stats.at_feed_fraction, mean(r.cycle_ns) / 1e3, pct(r.cycle_ns, 0.99) / 1e3,
              pct(r.cycle_ns, 0.999) / 1e3, vmax(r.cycle_ns) / 1e3, mean(r.add_ns) / 1e3, pct(r.add_ns, 0.999) / 1e3,
              static_cast<unsigned long long>(r.servo_split));
  if (g_print_end) {
    std::printf("  end position X%.6f Y%.6f Z%.6f (machine), %zu moves, %zu stops%s%s\n", r.end[0], r.end[1], r.end[2],
                r.moves, r.stops, r.error.empty() ? "" : ": ", r.error.c_str());
  }
  std::fflush(stdout);
}

bool parse_triple(const char* s, double& a, double& b, double& c) { return std::sscanf(s, "%lf,%lf,%lf", &a, &b, &c) == 3; }

int usage() {
  std::fprintf(stderr,
               "usage: bench_tp [--quick] [--ini FILE] [--write-ngc DIR] [--ngc FILE ...] [--only-ngc]\n"
               "                [--limits [L:]V,A,J ...] [--linear V,A,J] [--lookahead N] [--period S] [--start X,Y,Z]\n"
               "                [--profile FILE]\n"
               "  --ini: limits, look-ahead, period, units, offsets and tools of a configuration (as cncd reads it)\n"
               "  --only-ngc: only the --ngc programs (with their end positions), no attainment table\n"
               "  --limits V,A,J: velocity, acceleration, jerk of X, Y, Z; X:V,A,J (Y:, Z:) of one axis\n"
               "  --linear: limits on the XYZ norm ([TRAJ]MAX_LINEAR_VELOCITY, _ACCELERATION, _JERK)\n"
               "  --profile FILE: per cycle of the --ngc programs, time, path speed and line (appended)\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string write_dir, ini_path;
  std::vector<std::string> ngc;
  bool only_ngc = false;
  bool custom = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has = i + 1 < argc;
    if (a == "--quick") quick = true;
    else if (a == "--ini" && has) ini_path = argv[++i];
    else if (a == "--write-ngc" && has) write_dir = argv[++i];
    else if (a == "--ngc" && has) ngc.push_back(argv[++i]);
    else if (a == "--only-ngc") only_ngc = true;
    else if (a == "--profile" && has) g_profile = argv[++i];
    else if (a == "--lookahead" && has) g_lookahead = std::atoi(argv[++i]);
    else if (a == "--period" && has) g_period = std::atof(argv[++i]);
    else if (a == "--limits" && has) {
      const std::string v = argv[++i];
      int axis = -1;
      std::string nums = v;
      if (v.size() > 2 && v[1] == ':') {
        const char* p = std::strchr("XYZ", std::toupper(static_cast<unsigned char>(v[0])));
        if (!p) return usage();
        axis = static_cast<int>(p - "XYZ");
        nums = v.substr(2);
      }
      AxisLimits l;
      if (!parse_triple(nums.c_str(), l.max_velocity, l.max_acceleration, l.max_jerk)) return usage();
      for (int k = 0; k < 3; ++k) {
        if (axis < 0 || axis == k) g_custom[k] = l;
      }
      custom = true;
    } else if (a == "--start" && has) {
      Pose p;
      if (!parse_triple(argv[++i], p[0], p[1], p[2])) return usage();
      g_start = p;
    } else if (a == "--linear" && has) {
      if (!parse_triple(argv[++i], g_linear[0], g_linear[1], g_linear[2])) return usage();
    } else {
      return usage();
    }
  }
  if ((g_lookahead && *g_lookahead < 1) || (g_period && !(*g_period > 0))) {
    std::fprintf(stderr, "bench_tp: --lookahead must be at least 1 and --period positive\n");
    return 2;
  }
  if (!ini_path.empty() && (custom || g_linear[0] > 0)) {
    std::fprintf(stderr, "bench_tp: --ini gives the limits; --limits and --linear are for runs without it\n");
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
    progs.push_back(trochoidal(quick ? 60 : 130));
    progs.push_back(surfacing(quick ? 20 : 60));
    progs.push_back(dense_contour(quick ? 2000 : 4000));
  }
  for (const std::string& f : ngc) progs.push_back(Bench{std::filesystem::path(f).filename().string(), "", f});
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

  try {
    std::vector<std::pair<std::string, estimate::Machine>> machines;
    if (!ini_path.empty()) {
      machines.emplace_back("ini", ini_machine(ini_path));
      const estimate::Machine& m = machines.back().second;
      std::printf("\n%s: %s; look-ahead %d moves, period %g us; per axis v/a/j:", ini_path.c_str(), m.kinematics.c_str(),
                  m.planner.lookahead_segments, m.planner.cycle_time_s * 1e6);
      for (int a = 0; a < 3; ++a) {
        const AxisLimits& l = m.planner.axes[static_cast<std::size_t>(a)];
        std::printf(" %c %g/%g/%g", "XYZ"[a], l.max_velocity, l.max_acceleration, l.max_jerk);
      }
      std::printf("; start X%g Y%g Z%g\n", g_start.value_or(m.home)[0], g_start.value_or(m.home)[1],
                  g_start.value_or(m.home)[2]);
    } else {
      std::vector<std::string> profs = quick ? std::vector<std::string>{"LC"} : std::vector<std::string>{"LC", "Mill-S", "Mill-F"};
      std::vector<double> periods = quick ? std::vector<double>{0.001} : std::vector<double>{0.001, 0.00025};
      if (custom) profs = {"custom"};
      if (g_period) periods = {*g_period};
      for (const std::string& pr : profs) {
        for (double T : periods) machines.emplace_back(pr, profile_machine(pr, T));
      }
    }

    std::printf("\n== traverse time, lower bound, limits, tolerance, CPU (inline planner; CPU in us)\n");
    std::printf("%-34s %-6s %4s %-2s %9s %9s  %5s %5s %5s  %6s  %6s  %6s %6s %7s %7s  %6s %7s %6s\n", "program", "limits",
                "T_us", "ok", "time_s", "bound_s", "v/V", "a/A", "j/J", "dev/P", "@feed", "cyc_mn", "p99", "p99.9", "max",
                "seg_mn", "seg999", "split");
    for (const Bench& b : progs) {
      for (const auto& [name, m] : machines) run_one(b, m, name);
    }

    if (only_ngc) return 0;
    std::printf("\n== short-segment feed attainment: collinear segments over 100 mm (20 mm for 1 um; F6000 = 100 mm/s, LC limits)\n");
    std::printf("%-10s %5s %10s %10s %9s %12s\n", "segment", "T_us", "mean/F", "peak/F", "@feed", "LinuxCNC cap");
    for (double seg : {0.001, 0.01, 0.1, 1.0}) {
      for (double T : {0.001, 0.00025}) {
        const double len = seg < 0.005 ? 20.0 : 100.0;
        estimate::Machine m = profile_machine("LC", T);
        // Look-ahead over 12 mm: more than the 6 mm a stop from 100 mm/s needs.
        m.planner.lookahead_segments = std::max(2000, static_cast<int>(12.0 / seg));
        const estimate::Moves mv = read(short_lines(seg, len, 6000), m, Pose{});
        estimate::Options opt;
        opt.flush_at_end = true;
        opt.moves_per_cycle = 1 << 20;
        const estimate::Result r = estimate::run(m, mv, opt);
        // LinuxCNC 2.9: every segment lasts at least 1.02 servo periods.
        const double cap = std::min(1.0, seg / (1.02 * T) / 100.0);
        std::printf("%-10g %5.0f %9.1f%% %9.1f%% %8.1f%% %11.1f%%\n", seg, T * 1e6, 100 * r.stats.mean_feed_ratio,
                    100 * r.stats.max_v[0] / 100.0, 100 * r.stats.at_feed_fraction, 100 * cap);
      }
    }
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "bench_tp: %s\n", e.what());
    return 2;
  }
  return 0;
}
