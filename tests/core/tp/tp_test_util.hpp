// Helpers shared by the trajectory planner tests: limit profiles and seeded
// program generators.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>

#include "core/tp/lookahead_planner.hpp"
#include "core/tp/trajectory_check.hpp"

namespace cnc::tp::test {

inline Pose pose(double x, double y, double z) {
  Pose p;
  p[0] = x;
  p[1] = y;
  p[2] = z;
  return p;
}

// What every run must keep: completed, per-axis |v|, |a|, |j| within the
// limits on every sample, deviation within P, the end point, a monotone
// path parameter and no overrun.
inline void expect_clean(const RunResult& r, double end_tol = 1e-9) {
  ASSERT_TRUE(r.completed) << "cycles " << r.cycles;
  EXPECT_LE(r.stats.ratio_v, 1 + 1e-9);
  EXPECT_LE(r.stats.ratio_a, 1 + 1e-9);
  EXPECT_LE(r.stats.ratio_j, 1 + 1e-9);
  EXPECT_LE(r.stats.deviation_ratio, 1 + 1e-6) << "max deviation " << r.stats.max_deviation;
  EXPECT_LT(r.stats.end_error, end_tol);
  EXPECT_TRUE(r.monotone);
  EXPECT_EQ(r.overruns, 0u);
}

// `prog` on an inline planner.
inline RunResult run_inline(const PlannerConfig& cfg, const Program& prog, RunOptions opt = {}) {
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  return run_program(*planner, cfg, prog, opt);
}

// Per-axis v (units/s), a (units/s^2), j (units/s^3) on X Y Z; the issue's
// profiles.
inline PlannerConfig profile(const std::string& name, double cycle_s = 0.001) {
  PlannerConfig c;
  c.cycle_time_s = cycle_s;
  AxisLimits l{100, 1000, 50000};  // LC
  if (name == "mill-s") l = {166.7, 2000, 50000};
  if (name == "mill-f") l = {500, 5000, 200000};
  for (int i = 0; i < 3; ++i) c.axes[static_cast<std::size_t>(i)] = l;
  c.axis_mask = 0x7;
  return c;
}

inline SegmentParams feed_params(double feed, double tol, TermCond term = TermCond::Blend) {
  SegmentParams p;
  p.type = MotionType::Feed;
  p.feed = feed;
  p.term = term;
  p.tolerance = tol;
  return p;
}

inline ProgramMove line_to(double x, double y, double z, const SegmentParams& p) {
  ProgramMove m;
  m.kind = ProgramMove::Kind::Line;
  m.end[0] = x;
  m.end[1] = y;
  m.end[2] = z;
  m.params = p;
  return m;
}

// A spiral polyline of `n` moves of 0.2 mm (G64 P0.01) from (5, 0, 0),
// its radius growing 0.5 mm a turn: curved pieces, whose envelope spans
// cost the servo thread the most.
inline Program spiral_polyline(int n) {
  Program prog;
  const SegmentParams p = feed_params(100, 0.01);
  double theta = 0;
  for (int i = 0; i < n; ++i) {
    const double r = 5 + 0.5 / (2 * std::numbers::pi) * theta;
    theta += 0.2 / r;
    prog.moves.push_back(line_to(r * std::cos(theta), r * std::sin(theta), 0, p));
  }
  prog.start = pose(5, 0, 0);
  return prog;
}

// A random program: lines of log-uniform length (some collinear, some
// nearly, some reversing), arcs and helices in the three planes, several
// tolerances and termination modes, feeds and rapids, a few dwells.
inline Program random_program(uint32_t seed, int moves, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  auto lu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u01(rng)); };
  Program prog;
  Pose pos;
  double dir[3] = {1, 0, 0};
  const double tols[] = {0.001, 0.01, 0.05, 0.2, 0};
  for (int i = 0; i < moves; ++i) {
    SegmentParams p = feed_params(lu(5, 400), tols[rng() % 5]);
    const double r = u01(rng);
    if (r < 0.06) p.term = TermCond::ExactPath;
    else if (r < 0.1) p.term = TermCond::ExactStop;
    if (u01(rng) < 0.08) {
      p.type = MotionType::Traverse;
      p.feed = 0;
    }
    const double kind = u01(rng);
    if (kind < 0.03) {
      ProgramMove m;
      m.kind = ProgramMove::Kind::Dwell;
      m.seconds = u01(rng) * 0.01;
      m.params = p;
      prog.moves.push_back(m);
      continue;
    }
    if (kind < 0.25 && p.type != MotionType::Traverse) {
      // Arc or helix in a random principal plane, tangent or not.
      const int plane = static_cast<int>(rng() % 3);
      const int a0 = plane == 0 ? 0 : (plane == 1 ? 2 : 1);
      const int a1 = plane == 0 ? 1 : (plane == 1 ? 0 : 2);
      const int ax = 3 - a0 - a1;
      const double rad = lu(0.2, 20) * scale;
      const double ang = u01(rng) * 2 * std::numbers::pi;
      ProgramMove m;
      m.kind = ProgramMove::Kind::Circle;
      m.params = p;
      m.params.type = MotionType::Arc;
      std::array<double, 3> c{pos[0], pos[1], pos[2]};
      c[static_cast<std::size_t>(a0)] += rad * std::cos(ang);
      c[static_cast<std::size_t>(a1)] += rad * std::sin(ang);
      m.center = c;
      m.normal = {0, 0, 0};
      m.normal[static_cast<std::size_t>(ax)] = u01(rng) < 0.5 ? 1 : -1;
      const double sweep = u01(rng) * 2 * std::numbers::pi * (u01(rng) < 0.1 ? 2.0 : 1.0);
      m.turns = sweep > 2 * std::numbers::pi ? 1 : 0;
      // End point on the circle (sense given by the normal).
      const double sgn = m.normal[static_cast<std::size_t>(ax)] *
                         ((a0 == 0 && a1 == 1) || (a0 == 2 && a1 == 0) || (a0 == 1 && a1 == 2) ? 1 : -1);
      const double end_ang = ang + std::numbers::pi + sgn * std::fmod(sweep, 2 * std::numbers::pi);
      Pose e = pos;
      e[a0] = c[static_cast<std::size_t>(a0)] + rad * std::cos(end_ang);
      e[a1] = c[static_cast<std::size_t>(a1)] + rad * std::sin(end_ang);
      if (u01(rng) < 0.3) e[ax] += (u01(rng) - 0.5) * 4 * scale;  // helix
      m.end = e;
      prog.moves.push_back(m);
      Curve cv;
      if (make_helix(pos, e, m.center, m.normal, m.turns, 1, cv)) {
        AxisVec pp, d1;
        cv.eval(cv.length, pp, &d1);
        const double n = std::sqrt(d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]);
        for (int k = 0; k < 3; ++k) dir[k] = d1[static_cast<std::size_t>(k)] / n;
        pos = e;
      } else {
        prog.moves.pop_back();
      }
      continue;
    }
    // Line: keep direction, turn slightly, turn sharply or reverse.
    const double t = u01(rng);
    double nd[3];
    if (t < 0.3) {
      for (int k = 0; k < 3; ++k) nd[k] = dir[k];
    } else if (t < 0.6) {
      for (int k = 0; k < 3; ++k) nd[k] = dir[k] + (u01(rng) - 0.5) * 0.1;
    } else if (t < 0.95) {
      for (int k = 0; k < 3; ++k) nd[k] = u01(rng) - 0.5;
    } else {
      for (int k = 0; k < 3; ++k) nd[k] = -dir[k];
    }
    double n = std::sqrt(nd[0] * nd[0] + nd[1] * nd[1] + nd[2] * nd[2]);
    if (n < 1e-6) continue;
    const double len = lu(0.005, 30) * scale;
    Pose e = pos;
    for (int k = 0; k < 3; ++k) {
      dir[k] = nd[k] / n;
      e[k] += dir[k] * len;
    }
    ProgramMove m;
    m.kind = ProgramMove::Kind::Line;
    m.end = e;
    m.params = p;
    prog.moves.push_back(m);
    pos = e;
  }
  return prog;
}

}  // namespace cnc::tp::test
