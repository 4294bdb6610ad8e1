// Behaviour of tp::LookaheadPlanner through the TrajectoryPlanner interface:
// limits on lines, arcs, helices and blends; G64 P, G61 and G61.1; tangent
// joints at full speed; short segments at the programmed feed; look-ahead
// depth; overrides, pause/resume, step, abort, probe, dwell (the servo
// thread's realtime discipline: realtime_test.cpp). Every stream is
// checked sample by sample
// (StreamChecker: finite differences, distance to the programmed path).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <thread>
#include <vector>

#include "tests/core/tp/tp_test_util.hpp"
#include "tests/support/testing.hpp"

namespace cnc::tp {
namespace {

using test::expect_clean;
using test::feed_params;
using test::line_to;
using test::pose;
using test::profile;

ProgramMove arc_to(const Pose& end, std::array<double, 3> center, std::array<double, 3> normal,
                   const SegmentParams& p, int turns = 0) {
  ProgramMove m;
  m.kind = ProgramMove::Kind::Circle;
  m.end = end;
  m.center = center;
  m.normal = normal;
  m.turns = turns;
  m.params = p;
  m.params.type = MotionType::Arc;
  return m;
}

RunResult run(const PlannerConfig& cfg, const Program& prog, RunOptions opt = {}) {
  return test::run_inline(cfg, prog, opt);
}

// --- limits on every kind of move ------------------------------------------

TEST(TpLimits, ArcsAndHelicesInEveryPlaneHoldPerAxisLimits) {
  for (const char* prof : {"lc", "mill-s", "mill-f"}) {
    for (double T : {0.001, 0.00025}) {
      const PlannerConfig cfg = profile(prof, T);
      Program prog;
      const SegmentParams p = feed_params(400, 0.01);
      // XY (G17) full circle, XZ (G18) half circle, YZ (G19) arc, then a
      // helix with two extra turns, all at a feed above what the axes allow.
      prog.moves.push_back(line_to(10, 0, 0, p));
      prog.moves.push_back(arc_to(pose(10, 0, 0), {5, 0, 0}, {0, 0, 1}, p));
      prog.moves.push_back(arc_to(pose(20, 0, 0), {15, 0, 0}, {0, 1, 0}, p));
      prog.moves.push_back(arc_to(pose(20, 6, 0), {20, 3, 0}, {1, 0, 0}, p));
      prog.moves.push_back(arc_to(pose(20, 6, -6), {20, 3, 0}, {0, 0, -1}, p, 2));
      prog.moves.push_back(line_to(0, 0, 0, p));
      SCOPED_TRACE(::testing::Message() << prof << " T " << T);
      const RunResult r = run(cfg, prog);
      expect_clean(r);
      // The axes, not the program, limit these moves: some axis reaches at
      // least half its acceleration limit (the test is not trivially slow).
      EXPECT_GT(r.stats.ratio_a, 0.5);
    }
  }
}

// bench_tp's "circles and helices" once reported 33 x P: on a helix whose
// turns lie closer together (1/3 mm pitch) than the checker's samples (0.05
// rad at radius 17 = 0.85 mm), the checker measured from the wrong turn.
TEST(TpCheck, DistanceToAFinePitchHelixIsMeasuredFromTheNearestTurn) {
  Program prog;
  prog.start = pose(20, 0, -5);
  // Clockwise (G2) about (3, 0), three turns down to Z-6.
  prog.moves.push_back(arc_to(pose(20, 0, -6), {3, 0, -5}, {0, 0, -1}, feed_params(50, 0.01), 2));
  const StreamChecker check(profile("lc"), prog);
  Curve helix;
  ASSERT_TRUE(make_helix(prog.start, prog.moves[0].end, {3, 0, -5}, {0, 0, -1}, 2, 0, helix));
  // Points on the helix (all turns, with the start of the second turn
  // where the failure was seen), and the same points 0.005 mm off it
  // radially.
  for (double s : {0.0, 50.0, 106.0, 106.8, 106.9, 150.0, 213.6, 300.0, helix.length}) {
    AxisVec on;
    helix.eval(s, on);
    Pose p;
    p.v = on;
    SCOPED_TRACE(::testing::Message() << "s " << s);
    EXPECT_LT(check.distance_to_move(p, 0), 1e-6);
    const double a = std::atan2(on[1], on[0] - 3);
    p[0] += 0.005 * std::cos(a);
    p[1] += 0.005 * std::sin(a);
    EXPECT_NEAR(check.distance_to_move(p, 0), 0.005, 1e-6);
  }
}

TEST(TpLimits, FinePitchHelixAfterAFullCircleHoldsTheTolerance) {
  // The bench's program in small: a line, two full turns, a three-turn
  // helix with 1/3 mm pitch, a line outwards.
  const PlannerConfig cfg = profile("lc");
  const SegmentParams p = feed_params(50, 0.01);
  Program prog;
  prog.moves.push_back(line_to(20, 0, -5, p));
  prog.moves.push_back(arc_to(pose(20, 0, -5), {3, 0, -5}, {0, 0, 1}, p, 1));
  prog.moves.push_back(arc_to(pose(20, 0, -6), {3, 0, -5}, {0, 0, -1}, p, 2));
  prog.moves.push_back(line_to(25, 0, -6, p));
  const RunResult r = run(cfg, prog);
  expect_clean(r);
  EXPECT_LE(r.stats.max_deviation, 0.01 * (1 + 1e-6));
}

TEST(TpLimits, AxisSpecificLimitsHoldOnDiagonals) {
  // Z much weaker than X/Y: a diagonal move must respect Z's own limits.
  PlannerConfig cfg = profile("mill-f", 0.001);
  cfg.axes[2] = {50, 500, 10000};
  Program prog;
  const SegmentParams p = feed_params(500, 0.02);
  prog.moves.push_back(line_to(100, 50, 40, p));
  prog.moves.push_back(line_to(150, 0, 0, p));
  prog.moves.push_back(arc_to(pose(150, 20, 10), {150, 10, 5}, {1, 0, 0}, p));
  prog.moves.push_back(line_to(0, 0, 0, p));
  const RunResult r = run(cfg, prog);
  expect_clean(r);
  EXPECT_LE(r.stats.max_v[2], 50 * (1 + 1e-9));
  EXPECT_LE(r.stats.max_a[2], 500 * (1 + 1e-9));
  EXPECT_LE(r.stats.max_j[2], 10000 * (1 + 1e-9));
  EXPECT_GT(r.stats.max_v[2], 0.9 * 50);  // Z is the binding axis
}

// --- corners ----------------------------------------------------------------

Program corner(TermCond term, double tol, double feed = 100) {
  Program prog;
  const SegmentParams p = feed_params(feed, tol, term);
  prog.moves.push_back(line_to(50, 0, 0, p));
  prog.moves.push_back(line_to(50, 50, 0, p));
  prog.moves.push_back(line_to(0, 50, 0, p));
  return prog;
}

// Smallest speed along the path near (50, 0), the first corner.
double corner_speed(const PlannerConfig& cfg, const Program& prog) {
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  double vmin = 1e300;
  Pose last = prog.start;
  planner->set_position(prog.start);
  for (std::size_t i = 0; i < prog.moves.size(); ++i) EXPECT_EQ(queue_move(*planner, prog, i), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  for (int c = 0; c < 100000 && !(planner->is_done() && c > 0); ++c) {
    planner->run_cycle(in, out);
    const double d = std::hypot(out.position[0] - 50, out.position[1]);
    const double v = std::hypot(out.position[0] - last[0], out.position[1] - last[1]) / cfg.cycle_time_s;
    if (d < 0.5) vmin = std::min(vmin, v);
    last = out.position;
  }
  return vmin;
}

TEST(TpCorners, BlendStaysWithinTheToleranceAndUsesIt) {
  const PlannerConfig cfg = profile("lc");
  for (double tol : {0.001, 0.01, 0.1, 0.5}) {
    SCOPED_TRACE(::testing::Message() << "P " << tol);
    const RunResult r = run(cfg, corner(TermCond::Blend, tol));
    expect_clean(r);
    EXPECT_LE(r.stats.max_deviation, tol * (1 + 1e-6));
    // Rounded where the tolerance leaves a window faster than a stop; at
    // P0.001 and P0.01 a square corner under these limits is stopped at
    // (TpCorners.ASquareCornerWithTooLittleToleranceIsStoppedAtWhichIsFaster).
    if (tol >= 0.1) {
      EXPECT_GT(r.stats.max_deviation, 0.3 * tol);
    }
  }
  // A larger tolerance lets the corner go faster.
  EXPECT_GT(corner_speed(cfg, corner(TermCond::Blend, 0.5)), corner_speed(cfg, corner(TermCond::Blend, 0.1)));
  EXPECT_GT(corner_speed(cfg, corner(TermCond::Blend, 0.1)), 5.0);
}

// 1 mm zig-zag with square corners: the window G64 P0.01 allows is so
// tight (about 2.4 mm/s under LC limits) that crawling through it took 42 %
// longer than stopping at every corner (25.3 s against 17.8 s for 200
// moves before the planner chose the stop). A blended corner must never be
// slower than the exact stop; a tolerance that allows a real window (P0.1)
// is faster than both.
TEST(TpCorners, ASquareCornerWithTooLittleToleranceIsStoppedAtWhichIsFaster) {
  const PlannerConfig cfg = profile("lc");
  auto zigzag = [](TermCond term, double tol) {
    Program prog;
    const SegmentParams p = feed_params(100, tol, term);
    double x = 0, y = 0;
    for (int i = 0; i < 40; ++i) {
      if (i % 2 == 0) x += 1;
      else y += (i / 2) % 2 == 0 ? 1 : -1;
      prog.moves.push_back(line_to(x, y, 0, p));
    }
    return prog;
  };
  const RunResult stop = run(cfg, zigzag(TermCond::ExactStop, 0));
  const RunResult tight = run(cfg, zigzag(TermCond::Blend, 0.01));
  const RunResult loose = run(cfg, zigzag(TermCond::Blend, 0.1));
  expect_clean(stop);
  expect_clean(tight);
  expect_clean(loose);
  EXPECT_LE(tight.cycles, stop.cycles + 2) << "P0.01 is slower than stopping at every corner";
  EXPECT_LT(loose.cycles, 0.8 * stop.cycles) << "P0.1's windows are not faster than stopping";
  EXPECT_GT(loose.stats.max_deviation, 0.3 * 0.1);
}

TEST(TpCorners, ExactPathFollowsTheCornerExactly) {
  const PlannerConfig cfg = profile("mill-s");
  const RunResult r = run(cfg, corner(TermCond::ExactPath, 0));
  expect_clean(r);
  EXPECT_LT(r.stats.max_deviation, 1e-6);
  // A square corner needs a stop (speed from position differences: at rest
  // up to the resolution of one sample).
  EXPECT_LT(corner_speed(cfg, corner(TermCond::ExactPath, 0)), 1e-3);
}

TEST(TpCorners, ExactStopStopsEvenBetweenCollinearMoves) {
  const PlannerConfig cfg = profile("lc");
  Program prog;
  prog.moves.push_back(line_to(25, 0, 0, feed_params(100, 0.1, TermCond::ExactStop)));
  prog.moves.push_back(line_to(50, 0, 0, feed_params(100, 0.1, TermCond::ExactStop)));
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(prog.start);
  ASSERT_EQ(queue_move(*planner, prog, 0), Result::Ok);
  ASSERT_EQ(queue_move(*planner, prog, 1), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  bool stopped_at_25 = false;
  for (int c = 0; c < 10000 && !planner->is_done(); ++c) {
    planner->run_cycle(in, out);
    if (std::fabs(out.position[0] - 25) < 1e-9 && out.path_velocity == 0) stopped_at_25 = true;
  }
  EXPECT_TRUE(stopped_at_25);
  EXPECT_NEAR(out.position[0], 50, 1e-12);
}

TEST(TpCorners, TangentJoinsAreNotSlowed) {
  // Joins without a change of direction or curvature: collinear lines, and
  // an arc continued by an arc of the same circle. (A line meeting an arc
  // tangentially still changes curvature at once; the jerk limit then sets
  // the speed there, as it must.)
  const PlannerConfig cfg = profile("mill-s");
  Program prog;
  const double F = 50;  // v^2/r = 2500/20 = 125 mm/s^2, far below the limits
  const SegmentParams p = feed_params(F, 0.001);
  prog.moves.push_back(line_to(20, 0, 0, p));
  prog.moves.push_back(line_to(40, 0, 0, p));
  prog.moves.push_back(arc_to(pose(60, 20, 0), {40, 20, 0}, {0, 0, 1}, p));
  prog.moves.push_back(arc_to(pose(40, 40, 0), {40, 20, 0}, {0, 0, 1}, p));
  prog.moves.push_back(arc_to(pose(20, 20, 0), {40, 20, 0}, {0, 0, 1}, p));
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(prog.start);
  for (std::size_t i = 0; i < prog.moves.size(); ++i) ASSERT_EQ(queue_move(*planner, prog, i), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  double vmin_lines = 1e300, vmin_arcs = 1e300;
  for (int c = 0; c < 20000 && !planner->is_done(); ++c) {
    planner->run_cycle(in, out);
    if (out.position[1] == 0 && out.position[0] > 10 && out.position[0] < 30) vmin_lines = std::min(vmin_lines, out.path_velocity);
    if (out.position[1] > 10 && out.position[0] > 30) vmin_arcs = std::min(vmin_arcs, out.path_velocity);
  }
  EXPECT_GT(vmin_lines, F * 0.999 * (1 - 1e-9));  // joint at X20
  // An arc continued by the same circle is a smooth join (no window); it
  // ran at F / sqrt(2) until bare helix pieces got an exact speed bound.
  EXPECT_GT(vmin_arcs, 0.99 * F);
}

// A bare circle or helix (no corner window on it) runs at the programmed
// feed when the axes allow it: its speed along s is exactly 1 and no axis
// component of the tangent exceeds 1. It used to run at F / sqrt 2 (the
// norm of the per-axis bounds of dP/ds was taken as the path speed).
TEST(TpLimits, BareCircleAndHelixRunAtTheProgrammedFeed) {
  const PlannerConfig cfg = profile("mill-s");
  const double F = 50;  // v^2/r = 2500/20 = 125 mm/s^2, far below the limits
  const SegmentParams p = feed_params(F, 0.01, TermCond::ExactStop);
  for (int helix = 0; helix < 2; ++helix) {
    SCOPED_TRACE(helix ? "helix" : "circle");
    Program prog;
    prog.start = pose(20, 0, 0);
    prog.moves.push_back(arc_to(pose(20, 0, helix ? -10 : 0), {0, 0, 0}, {0, 0, 1}, p, helix ? 1 : 0));
    auto planner = make_planner(cfg, PlannerThreading::Inline);
    planner->set_position(prog.start);
    ASSERT_EQ(queue_move(*planner, prog, 0), Result::Ok);
    planner->flush();
    CycleInputs in;
    CycleOutputs out;
    std::vector<double> v;
    for (int c = 0; c < 100000 && !planner->is_done(); ++c) {
      planner->run_cycle(in, out);
      v.push_back(out.path_velocity);
    }
    ASSERT_TRUE(planner->is_done());
    ASSERT_GT(v.size(), 100u);
    // The middle half of the motion (the ramps take well under a quarter).
    double vmin = 1e300;
    for (std::size_t i = v.size() / 4; i < 3 * v.size() / 4; ++i) vmin = std::min(vmin, v[i]);
    EXPECT_GE(vmin, 0.99 * F);
    EXPECT_LE(vmin, F * (1 + 1e-9));
    const RunResult r = run(cfg, prog);
    expect_clean(r);
  }
}

// --- short segments and look-ahead -------------------------------------------

TEST(TpShortSegments, TenMicronSegmentsAtOneKilohertzRunAtTheProgrammedFeed) {
  // 0.01 mm segments at F6000 (100 mm/s) and 1 kHz: one segment lasts 0.1
  // servo period. LinuxCNC 2.9 caps this at 588 mm/min (one cycle per
  // segment).
  const PlannerConfig cfg = profile("lc", 0.001);
  Program prog;
  const SegmentParams p = feed_params(100, 0.001);
  for (int i = 1; i <= 8000; ++i) prog.moves.push_back(line_to(0.01 * i, 0, 0, p));
  RunOptions opt;
  opt.flush_at_end = true;
  const RunResult r = run(cfg, prog, opt);
  expect_clean(r);
  EXPECT_GT(r.stats.max_v[0], 0.998 * 100);
  // 80 mm at 100 mm/s is 0.8 s; ramps at 1000 mm/s^2 and 50000 mm/s^3 add
  // about 0.12 s.
  EXPECT_LT(r.stats.time_s, 0.95);
  // The ramps up and down take about 0.12 s each of the 0.92 s.
  EXPECT_GT(r.stats.at_feed_fraction, 0.7);
}

// A zig-zag of 0.02 mm segments whose 0.002 mm wiggle lies well inside P
// is followed as the straight band it is, not slowed corner by corner:
// it takes at most 10 % longer than the straight line through the same
// band under the same limits (once 2.4 mm/s, 31 % of the feed with
// G64 Q = P; a mean of 73 % of F, 0.82 s against the line's 0.79 s, since
// the vertex smoothing). The line itself averages 76 % of F over these
// 60 mm (the ramps), which is why the bar is relative to it.
TEST(TpShortSegments, NearlyCollinearZigZagWithinToleranceRunsAsFastAsTheStraightBand) {
  const PlannerConfig cfg = profile("mill-s", 0.001);
  const SegmentParams p = feed_params(100, 0.01);
  Program zigzag, line;
  for (int i = 1; i <= 3000; ++i) {
    zigzag.moves.push_back(line_to(0.02 * i, (i % 2) * 0.002, 0, p));
    line.moves.push_back(line_to(0.02 * i, 0, 0, p));
  }
  RunOptions opt;
  opt.flush_at_end = true;
  const RunResult rz = run(cfg, zigzag, opt);
  const RunResult rl = run(cfg, line, opt);
  expect_clean(rz);
  expect_clean(rl);
  EXPECT_LT(rz.stats.time_s, 1.10 * rl.stats.time_s) << "zig-zag " << rz.stats.time_s << " s, line " << rl.stats.time_s << " s";
  EXPECT_GT(rz.stats.max_v[0], 0.95 * 100);
}

// A look-ahead shorter in path length than the executor's reach (2 mm of
// 0.01 mm moves), with and without G64 Q merging: it once stood still with
// room in the queue (segments behind a stop never freed) or with the queue
// full of held chords. Slow, stop and go, but it must finish.
TEST(TpLookahead, ShortLookaheadNeverStalls) {
  for (double q : {0.0, 0.001}) {
    for (int depth : {50, 200, 1000}) {
      PlannerConfig cfg = profile("lc", 0.001);
      cfg.lookahead_segments = depth;
      Program prog;
      SegmentParams p = feed_params(100, 0.001);
      p.naive_cam_tolerance = q;
      for (int i = 1; i <= 3000; ++i) prog.moves.push_back(line_to(0.01 * i, 0, 0, p));
      RunOptions opt;
      opt.flush_at_end = true;
      opt.max_cycles = 20000;
      const RunResult r = run(cfg, prog, opt);
      SCOPED_TRACE(::testing::Message() << "depth " << depth << " Q " << q);
      expect_clean(r);
      // 30 mm at 100 mm/s is 0.3 s and the ramps.
      if (depth == 1000) {
        EXPECT_LT(r.stats.time_s, 0.6);
      }
    }
  }
}

TEST(TpLookahead, QueueTakesAtLeastTheConfiguredDepth) {
  for (int depth : {1000, 3000}) {
    PlannerConfig cfg = profile("lc");
    cfg.lookahead_segments = depth;
    auto planner = make_planner(cfg, PlannerThreading::Inline);
    planner->set_position(Pose{});
    int accepted = 0;
    const SegmentParams p = feed_params(100, 0.01);
    for (int i = 1; i <= depth + 500; ++i) {
      Pose e;
      e[0] = 0.01 * i;
      if (planner->add_line(e, p) != Result::Ok) break;
      ++accepted;
    }
    EXPECT_EQ(accepted, depth);
    EXPECT_TRUE(planner->is_queue_full());
    EXPECT_EQ(planner->queue_depth(), depth);
  }
}

TEST(TpLookahead, DeepQueueLetsShortSegmentsReachFullSpeed) {
  // Reaching 500 mm/s (Mill-F) and stopping again needs about 60 mm: with
  // 0.05 mm segments that is 1200 segments of look-ahead.
  PlannerConfig cfg = profile("mill-f", 0.001);
  cfg.lookahead_segments = 2000;
  Program prog;
  const SegmentParams p = feed_params(500, 0.001);
  for (int i = 1; i <= 4000; ++i) prog.moves.push_back(line_to(0.05 * i, 0, 0, p));
  RunOptions opt;
  opt.flush_at_end = true;
  const RunResult r = run(cfg, prog, opt);
  expect_clean(r);
  EXPECT_GT(r.stats.max_v[0], 0.99 * 500);
}

// --- operator controls ------------------------------------------------------

Program long_line(double feed = 100) {
  Program prog;
  prog.moves.push_back(line_to(100, 20, 0, feed_params(feed, 0.01)));
  prog.moves.push_back(line_to(150, 20, 10, feed_params(feed, 0.01)));
  return prog;
}

TEST(TpControls, FeedOverrideChangesSpeedSmoothlyWithinLimits) {
  const PlannerConfig cfg = profile("lc");
  RunOptions opt;
  opt.flush_at_end = true;
  double v_half = 0, v_full = 0;
  opt.before_cycle = [&](uint64_t c, TrajectoryPlanner& tp, CycleInputs& in) {
    const auto& e = dynamic_cast<LookaheadPlanner&>(tp).executor();
    if (c == 300) in.feed_scale = 0.5;
    if (c == 600) v_half = e.path_velocity();
    if (c == 700) in.feed_scale = 1.2;  // above 1: capped by the axes
    if (c == 1000) v_full = e.path_velocity();
  };
  const RunResult r = run(cfg, long_line(50), opt);
  expect_clean(r);
  EXPECT_NEAR(v_half, 25, 1e-6);
  EXPECT_NEAR(v_full, 60, 1e-6);
}

TEST(TpControls, ZeroFeedOverrideStopsOnThePathAndOneResumes) {
  const PlannerConfig cfg = profile("mill-s");
  RunOptions opt;
  opt.flush_at_end = true;
  double held_at = -1, after = -2;
  opt.before_cycle = [&](uint64_t c, TrajectoryPlanner& tp, CycleInputs& in) {
    const auto& e = dynamic_cast<LookaheadPlanner&>(tp).executor();
    if (c == 200) in.feed_scale = 0;
    if (c == 700) held_at = e.path_position();
    if (c == 900) after = e.path_position();
    if (c == 900) in.feed_scale = 1;
  };
  const RunResult r = run(cfg, long_line(), opt);
  expect_clean(r);
  EXPECT_GT(held_at, 0);
  EXPECT_EQ(held_at, after);  // at rest while the override is 0
}

TEST(TpControls, PauseDeceleratesAlongThePathAndResumeContinues) {
  const PlannerConfig cfg = profile("lc");
  RunOptions opt;
  opt.flush_at_end = true;
  bool paused_seen = false;
  double s_hold = -1;
  opt.before_cycle = [&](uint64_t c, TrajectoryPlanner& tp, CycleInputs&) {
    const auto& e = dynamic_cast<LookaheadPlanner&>(tp).executor();
    if (c == 400) tp.pause();
    if (c == 800) {
      paused_seen = tp.is_paused() && !e.is_moving();
      s_hold = e.path_position();
    }
    if (c == 900) {
      EXPECT_EQ(e.path_position(), s_hold);
      tp.resume();
    }
  };
  const RunResult r = run(cfg, long_line(), opt);
  expect_clean(r);
  EXPECT_TRUE(paused_seen);
  EXPECT_GT(s_hold, 10);
}

TEST(TpControls, StepRunsToTheEndOfTheCurrentMoveThenHolds) {
  const PlannerConfig cfg = profile("lc");
  Program prog;
  for (int i = 1; i <= 4; ++i) prog.moves.push_back(line_to(10.0 * i, (i % 2) * 5.0, 0, feed_params(100, 0.01)));
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(prog.start);
  for (std::size_t i = 0; i < prog.moves.size(); ++i) ASSERT_EQ(queue_move(*planner, prog, i), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  for (int c = 0; c < 20; ++c) planner->run_cycle(in, out);
  planner->pause();
  for (int c = 0; c < 1000; ++c) planner->run_cycle(in, out);
  ASSERT_TRUE(planner->is_paused());
  const uint32_t id = out.id;
  planner->step();
  for (int c = 0; c < 3000; ++c) planner->run_cycle(in, out);
  EXPECT_TRUE(planner->is_paused());
  EXPECT_FALSE(planner->is_done());
  // Held at the start of the next move (the end point of move `id`).
  const Pose& end = prog.moves[id].end;
  EXPECT_NEAR(out.position[0], end[0], 0.011) << "id " << id;
  EXPECT_NEAR(out.position[1], end[1], 0.011);
  planner->resume();
  for (int c = 0; c < 10000 && !planner->is_done(); ++c) planner->run_cycle(in, out);
  EXPECT_TRUE(planner->is_done());
  EXPECT_NEAR(out.position[0], 40, 1e-12);
}

TEST(TpControls, AbortStopsWithinLimitsAndEmptiesTheQueue) {
  const PlannerConfig cfg = profile("mill-f");
  Program prog;
  for (int i = 1; i <= 50; ++i) prog.moves.push_back(line_to(5.0 * i, (i % 2) * 1.0, 0, feed_params(400, 0.05)));
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(prog.start);
  for (std::size_t i = 0; i < prog.moves.size(); ++i) ASSERT_EQ(queue_move(*planner, prog, i), Result::Ok);
  StreamChecker check(cfg, prog, cfg.blend_span_segments + 4);
  CycleInputs in;
  CycleOutputs out;
  for (int c = 0; c < 300; ++c) {
    planner->run_cycle(in, out);
    check.add(out);
  }
  EXPECT_GT(out.path_velocity, 30);
  planner->abort();
  int c = 0;
  for (; c < 5000 && !planner->is_done(); ++c) {
    planner->run_cycle(in, out);
    check.add(out);
  }
  EXPECT_TRUE(planner->is_done());
  EXPECT_EQ(planner->queue_depth(), 0);
  EXPECT_LT(c, 400);  // a stop, not the rest of the program
  const StreamStats st = check.finish();
  EXPECT_LE(st.ratio_v, 1 + 1e-9);
  EXPECT_LE(st.ratio_a, 1 + 1e-9);
  EXPECT_LE(st.ratio_j, 1 + 1e-9);
  EXPECT_LE(st.deviation_ratio, 1 + 1e-6);
  // Ready for new moves from where it stopped.
  planner->set_position(out.position);
  Pose back;
  ASSERT_EQ(planner->add_line(back, feed_params(100, 0.01)), Result::Ok);
  planner->flush();
  for (c = 0; c < 20000 && !planner->is_done(); ++c) planner->run_cycle(in, out);
  EXPECT_TRUE(planner->is_done());
  EXPECT_NEAR(out.position[0], 0, 1e-12);
}

// After an abort the next move starts where the machine stopped, without
// the caller telling the planner (motion never did): the command never
// jumps to the end of the moves the abort dropped. (It jumped: a program
// run after an abort mid-move faulted on a 120 mm following error.)
TEST(TpControls, AfterAnAbortTheNextMoveStartsWhereTheMachineStopped) {
  for (const PlannerThreading threading : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(threading == PlannerThreading::Inline ? "inline" : "threaded");
    const PlannerConfig cfg = profile("mill-f");
    auto planner = make_planner(cfg, threading);
    planner->set_position(pose(0, 120, 0));
    ASSERT_EQ(planner->add_line(pose(0, 20, 0), feed_params(20, 0.01)), Result::Ok);
    planner->flush();
    CycleInputs in;
    CycleOutputs out;
    for (int c = 0; c < 200000 && out.position[1] > 100; ++c) {
      planner->run_cycle(in, out);
      if (threading == PlannerThreading::OwnThread) std::this_thread::yield();  // the builder's thread plans
    }
    ASSERT_LE(out.position[1], 100);
    planner->abort();
    for (int c = 0; c < 5000 && !planner->is_done(); ++c) planner->run_cycle(in, out);
    ASSERT_TRUE(planner->is_done());
    const Pose stopped = out.position;
    ASSERT_GT(stopped[1], 20.5);
    // The task asks for X only: Y and Z stay where they stopped.
    Pose target = stopped;
    target[0] = 50;
    for (int c = 0; c < 100 && planner->add_line(target, feed_params(100, 0.01)) == Result::QueueFull; ++c) {
      planner->run_cycle(in, out);  // a threaded builder takes the reset first
    }
    planner->flush();
    double worst_step = 0;  // per-axis step as a share of its velocity limit
    Pose prev = out.position;
    for (int c = 0; c < 20000 && !(planner->is_done() && out.position[0] == 50); ++c) {
      planner->run_cycle(in, out);
      for (std::size_t a = 0; a < 3; ++a) {
        const double share = std::fabs(out.position[a] - prev[a]) / (cfg.axes[a].max_velocity * cfg.cycle_time_s);
        worst_step = std::max(worst_step, share);
      }
      prev = out.position;
      if (threading == PlannerThreading::OwnThread) std::this_thread::yield();
    }
    EXPECT_NEAR(out.position[0], 50, 1e-9);
    EXPECT_NEAR(out.position[1], stopped[1], 1e-9) << "Y must stay where the abort stopped it";
    EXPECT_NEAR(out.position[2], stopped[2], 1e-9);
    EXPECT_LE(worst_step, 1 + 1e-9) << "the command jumped";
  }
}

TEST(TpControls, ProbeStopsOnTheInputAndRecordsWhereItTripped) {
  const PlannerConfig cfg = profile("lc");
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(Pose{});
  SegmentParams p = feed_params(20, 0, TermCond::ExactStop);
  p.type = MotionType::Probe;
  ASSERT_EQ(planner->add_line(pose(0, 0, -30), p), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  int c = 0;
  for (; c < 20000 && !planner->is_done(); ++c) {
    in.probe_input = out.position[2] <= -10;
    planner->run_cycle(in, out);
  }
  EXPECT_TRUE(planner->is_done());
  ASSERT_TRUE(out.probe_tripped);
  EXPECT_NEAR(out.probed_position[2], -10, 20 * cfg.cycle_time_s + 1e-9);
  EXPECT_LT(out.position[2], out.probed_position[2]);  // stopped past it, within the limits
  EXPECT_GT(out.position[2], -11);
}

TEST(TpControls, DwellHoldsInPlaceForItsTime) {
  const PlannerConfig cfg = profile("lc");
  Program prog;
  prog.moves.push_back(line_to(10, 0, 0, feed_params(100, 0.01)));
  ProgramMove d;
  d.kind = ProgramMove::Kind::Dwell;
  d.seconds = 0.25;
  d.params = feed_params(100, 0.01);
  prog.moves.push_back(d);
  prog.moves.push_back(line_to(20, 0, 0, feed_params(100, 0.01)));
  auto planner = make_planner(cfg, PlannerThreading::Inline);
  planner->set_position(prog.start);
  for (std::size_t i = 0; i < prog.moves.size(); ++i) ASSERT_EQ(queue_move(*planner, prog, i), Result::Ok);
  planner->flush();
  CycleInputs in;
  CycleOutputs out;
  int at_10 = 0;
  for (int c = 0; c < 10000 && !planner->is_done(); ++c) {
    planner->run_cycle(in, out);
    if (out.position[0] == 10) ++at_10;
  }
  EXPECT_NEAR(at_10, 250, 2);
  EXPECT_EQ(out.position[0], 20);
}

}  // namespace
}  // namespace cnc::tp
