// What the planner's own side (the builder's thread, or inline after add_*)
// hands the servo thread ready-made, so that run_cycle only copies it
// (issue 20: the servo thread's work per cycle). Counted, never timed.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <thread>
#include <vector>

#include "tests/core/tp/tp_test_util.hpp"

namespace cnc::tp {
namespace {

using test::expect_clean;
using test::feed_params;
using test::line_to;
using test::pose;
using test::profile;

Program spiral(int n) { return test::spiral_polyline(n); }

struct Totals {
  uint64_t ingested = 0, limits = 0;
  int most_ingested = 0;
};

RunOptions counting(Totals& t, bool yield) {
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 1 << 20;
  opt.before_cycle = [&t, yield](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
    // A real servo thread sleeps between cycles: let the builder run.
    if (yield) std::this_thread::yield();
    const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
    t.ingested += static_cast<uint64_t>(w.ingested);
    t.limits += static_cast<uint64_t>(w.limits);
    t.most_ingested = std::max(t.most_ingested, w.ingested);
  };
  return opt;
}

// The whole look-ahead of a dense program arrives at once at its start:
// the servo thread used to compute every piece's limit table (16 grid
// velocities per piece, a logarithm and an exponential for the ceiling)
// while taking the pieces in, 128 of them in one cycle, a third of the
// start's burst. The builder's side computes them now; the servo thread
// computes none, in both threading modes.
TEST(TpHandover, PieceLimitTablesAreNotComputedInTheServoCycle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  const Program prog = spiral(1500);
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(th == PlannerThreading::Inline ? "inline" : "own thread");
    Totals t;
    auto planner = make_planner(cfg, th);
    const RunResult r = run_program(*planner, cfg, prog, counting(t, th == PlannerThreading::OwnThread));
    expect_clean(r);
    EXPECT_GT(t.ingested, 1500u);
    EXPECT_EQ(t.limits, 0u);
    EXPECT_LE(t.most_ingested, Executor::kIngestPerCycle);
  }
}

// The pieces' splitting into spans (the ceilings that spread onto each
// piece from its neighbours, cuts at doubling distances from its ends, at
// most 24 spans) ran in the servo thread, up to 64 pieces a cycle while a
// dense program's look-ahead arrived. The planner's side splits them now
// and the servo thread copies the spans (and joins short ones, which
// depends on where the input is): none split in the servo cycle, in both
// threading modes, and the motion is that of the servo-side splitting
// (the same spans: TpHandover.SpansForOtherLimitsAreSplitInTheServoCycle).
TEST(TpHandover, PiecesAreNotSplitIntoSpansInTheServoCycle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  const Program prog = spiral(1500);
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(th == PlannerThreading::Inline ? "inline" : "own thread");
    uint64_t split = 0, taken = 0;
    int most_taken = 0;
    auto planner = make_planner(cfg, th);
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = 1 << 20;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& p, CycleInputs&) {
      if (th == PlannerThreading::OwnThread) std::this_thread::yield();
      const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(p).executor().cycle_work();
      split += static_cast<uint64_t>(w.split);
      taken += static_cast<uint64_t>(w.taken);
      most_taken = std::max(most_taken, w.taken);
    };
    const RunResult r = run_program(*planner, cfg, prog, opt);
    expect_clean(r);
    EXPECT_EQ(split, 0u);
    EXPECT_GT(taken, 1500u);
    EXPECT_LE(most_taken, Executor::kSplitPerCycle);
  }
}

// Limits changed while the machine moves: the spans the planner's side
// split for them do not match the servo side's limits (the spread of the
// ceilings depends on the averaging window), so the servo thread splits
// those pieces itself, and the motion holds every limit. With the same
// limits given again, the servo thread's spans are the planner side's:
// inline, the path position is the same in every cycle as without the
// change.
TEST(TpHandover, SpansForOtherLimitsAreSplitInTheServoCycle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 200;
  const Program prog = spiral(1500);
  std::vector<double> plain_s;
  {
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = 1 << 20;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& p, CycleInputs&) {
      plain_s.push_back(dynamic_cast<LookaheadPlanner&>(p).executor().path_position());
    };
    expect_clean(test::run_inline(cfg, prog, opt));
  }
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(th == PlannerThreading::Inline ? "inline" : "own thread");
    uint64_t split = 0;
    bool changed = false;
    std::vector<double> s;
    auto planner = make_planner(cfg, th);
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = 1 << 20;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& p, CycleInputs&) {
      if (th == PlannerThreading::OwnThread) std::this_thread::yield();
      const Executor& e = dynamic_cast<LookaheadPlanner&>(p).executor();
      s.push_back(e.path_position());
      split += static_cast<uint64_t>(e.cycle_work().split);
      if (!changed && e.is_moving()) {
        p.set_config(cfg);
        changed = true;
      }
    };
    const RunResult r = run_program(*planner, cfg, prog, opt);
    expect_clean(r);
    EXPECT_TRUE(changed);
    EXPECT_GT(split, 100u);
    if (th == PlannerThreading::Inline) {
      ASSERT_EQ(s.size(), plain_s.size());
      std::size_t differ = 0;
      for (std::size_t i = 0; i < s.size(); ++i) differ += s[i] != plain_s[i];
      EXPECT_EQ(differ, 0u);
    }
  }
}

// Limits handed over while the machine moves apply from the next idle
// moment on the servo side (the averaging window cannot change under a
// moving machine), while the builder's side has taken them at once: the
// tables it made for them do not match what the servo side runs with, so
// the servo thread computes those itself, as before, and the motion holds
// every limit.
TEST(TpHandover, TablesForOtherLimitsAreRecomputedInTheServoCycle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 200;
  const Program prog = spiral(1500);
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(th == PlannerThreading::Inline ? "inline" : "own thread");
    Totals t;
    auto planner = make_planner(cfg, th);
    RunOptions opt = counting(t, th == PlannerThreading::OwnThread);
    auto count = opt.before_cycle;
    bool changed = false;
    opt.before_cycle = [&](uint64_t cycle, TrajectoryPlanner& p, CycleInputs& in) {
      count(cycle, p, in);
      // The same limits, a new configuration, once the machine moves (the
      // builder's thread may be late on a loaded machine).
      if (!changed && dynamic_cast<LookaheadPlanner&>(p).executor().is_moving()) {
        p.set_config(cfg);
        changed = true;
      }
    };
    const RunResult r = run_program(*planner, cfg, prog, opt);
    expect_clean(r);
    EXPECT_TRUE(changed);
    EXPECT_GT(t.limits, 100u);
  }
}

// At a start the whole look-ahead arrives at once, and the envelope's
// first walk from the tail came down to the input only after many cycles
// at the urgent slice, the machine standing meanwhile (15 cycles on this
// spiral: a burst of servo-thread work that bought nothing). The first
// walk now begins a few spans ahead of the input and the machine moves
// from the fourth cycle; the walk from the tail follows at its pace.
TEST(TpHandover, AStartMovesWithinAFewCyclesWhenTheWholeLookaheadArrivesAtOnce) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 1 << 20;
  uint64_t first_moving = 0;
  int urgent_cycles = 0;
  opt.before_cycle = [&](uint64_t cycle, TrajectoryPlanner& planner, CycleInputs&) {
    const Executor& e = dynamic_cast<LookaheadPlanner&>(planner).executor();
    if (first_moving == 0 && e.is_moving()) first_moving = cycle;
    if (cycle < 20 && e.cycle_work().envelope_queries > Executor::kQueriesPerCycle + Executor::kSpanQueriesMax) {
      ++urgent_cycles;
    }
  };
  const RunResult r = test::run_inline(cfg, spiral(1500), opt);
  expect_clean(r);
  EXPECT_GT(first_moving, 0u);
  EXPECT_LE(first_moving, 6u);
  // Cycles above the walk's ordinary slice while the look-ahead arrives
  // (the first 20): 10 before, 4 now.
  EXPECT_LE(urgent_cycles, 6);
}

// The machine waits a few cycles for the envelope at a start, with the
// queue full (the whole look-ahead arrives at once). The rule that
// flushes a full queue when the machine stands (a look-ahead shorter than
// the executor's reach would wait forever otherwise) took that wait for a
// stall: after 4 cycles it flushed the builder, inside the servo cycle
// when inline, and the flush baked a stop into the end of the look-ahead,
// where the machine then stopped in the middle of the spiral. The rule now
// needs the machine to stand at the end of what is published.
TEST(TpHandover, AFullQueueAtTheStartIsNotFlushedWhileTheMachineWaitsForTheEnvelope) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 500;
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 1 << 20;
  std::vector<double> v;
  opt.before_cycle = [&](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
    v.push_back(dynamic_cast<LookaheadPlanner&>(planner).executor().path_velocity());
  };
  const RunResult r = test::run_inline(cfg, spiral(2000), opt);
  expect_clean(r);
  ASSERT_GT(v.size(), 1000u);
  // Moving all the way from its start to its final braking.
  std::size_t first = 0;
  while (first < v.size() && !(v[first] > 0)) ++first;
  double slowest = 1e300;
  for (std::size_t i = first + 200; i + 400 < v.size(); ++i) slowest = std::min(slowest, v[i]);
  EXPECT_GT(slowest, 10.0);
}

// Lower limits given while the machine moves (a program paused with moves
// queued, the operator's new INI values): the moves already planned keep
// theirs, and the servo side takes the new ones at the next idle moment,
// so that the next program holds them at the output. It used to keep the
// old ones until another configuration arrived while idle.
TEST(TpHandover, LimitsGivenWhileMovingHoldForTheNextProgram) {
  const PlannerConfig high = profile("lc", 0.001);
  PlannerConfig low = high;
  for (int i = 0; i < 3; ++i) low.axes[static_cast<std::size_t>(i)] = AxisLimits{50, 250, 10000};
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    SCOPED_TRACE(th == PlannerThreading::Inline ? "inline" : "own thread");
    auto planner = make_planner(high, th);
    RunOptions opt;
    opt.flush_at_end = true;
    bool changed = false;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& p, CycleInputs&) {
      if (th == PlannerThreading::OwnThread) std::this_thread::yield();
      if (!changed && dynamic_cast<LookaheadPlanner&>(p).executor().is_moving()) {
        p.set_config(low);
        changed = true;
      }
    };
    Program first;
    first.start = pose(0, 0, 0);
    first.moves.push_back(line_to(40, 0, 0, feed_params(100, 0.01, TermCond::ExactStop)));
    expect_clean(run_program(*planner, high, first, opt));
    ASSERT_TRUE(changed);
    // The next program, checked against the lower limits.
    Program second;
    second.start = pose(40, 0, 0);
    second.moves.push_back(line_to(0, 30, 0, feed_params(100, 0.01, TermCond::ExactStop)));
    second.moves.push_back(line_to(10, 0, 0, feed_params(100, 0.01, TermCond::ExactStop)));
    RunOptions plain;
    plain.flush_at_end = true;
    if (th == PlannerThreading::OwnThread) plain.before_cycle = [](uint64_t, TrajectoryPlanner&, CycleInputs&) { std::this_thread::yield(); };
    expect_clean(run_program(*planner, low, second, plain));
  }
}

// The ring that hands the split spans over holds two spans per piece slot,
// and a piece may have up to 24: when it is full the planner's side stops
// splitting, and run_cycle splits the pieces it needs itself (one range
// minimum and the split, as before the hand-over). A ring of 64 spans
// (the construction parameter; the production ring never fills on these
// programs) forces that on a dense spiral and on a random program of
// lines, arcs, helices, dwells, rapids and stops: the servo thread splits
// (CycleWork::split), every limit and the tolerance hold, and inline the
// motion is the same in every cycle as with the ring that never fills
// (the same spans from either side).
TEST(TpHandover, AFullRingOfSplitSpansIsSplitInTheServoCycleWithTheSameMotion) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  constexpr std::size_t kSmallRing = 64;
  for (const Program& prog : {spiral(1500), test::random_program(11, 300)}) {
    SCOPED_TRACE(prog.moves.size());
    struct Run {
      uint64_t split = 0, taken = 0;
      int most_split = 0;
      std::vector<double> s;
      std::vector<Pose> pos;
    };
    auto run = [&](PlannerThreading th, std::size_t ring, Run& out) {
      LookaheadPlanner planner(cfg, th, ring);
      RunOptions opt;
      opt.flush_at_end = true;
      opt.moves_per_cycle = 1 << 20;
      opt.before_cycle = [&](uint64_t, TrajectoryPlanner& p, CycleInputs&) {
        if (th == PlannerThreading::OwnThread) std::this_thread::yield();
        const Executor& e = dynamic_cast<LookaheadPlanner&>(p).executor();
        out.split += static_cast<uint64_t>(e.cycle_work().split);
        out.taken += static_cast<uint64_t>(e.cycle_work().taken);
        out.most_split = std::max(out.most_split, e.cycle_work().split);
        out.s.push_back(e.path_position());
      };
      opt.after_cycle = [&](uint64_t, const CycleOutputs& o) { out.pos.push_back(o.position); };
      return run_program(planner, cfg, prog, opt);
    };
    Run full_size, small;
    expect_clean(run(PlannerThreading::Inline, 0, full_size));
    EXPECT_EQ(full_size.split, 0u);
    expect_clean(run(PlannerThreading::Inline, kSmallRing, small));
    EXPECT_GT(small.split, 100u);
    EXPECT_LE(small.most_split, Executor::kSplitPerCycle);
    ASSERT_EQ(small.s.size(), full_size.s.size());
    ASSERT_EQ(small.pos.size(), full_size.pos.size());
    double worst = 0;
    for (std::size_t i = 0; i < small.s.size(); ++i) {
      worst = std::max(worst, std::fabs(small.s[i] - full_size.s[i]));
      for (int a = 0; a < kNumAxes; ++a) worst = std::max(worst, std::fabs(small.pos[i][a] - full_size.pos[i][a]));
    }
    EXPECT_LE(worst, 1e-12);
    // The planner's thread splits while the ring has room; the servo
    // thread, running its cycles back to back, outruns it.
    Run threaded;
    expect_clean(run(PlannerThreading::OwnThread, kSmallRing, threaded));
    EXPECT_GT(threaded.split, 0u);
    EXPECT_LE(threaded.most_split, Executor::kSplitPerCycle);
  }
}

}  // namespace
}  // namespace cnc::tp
