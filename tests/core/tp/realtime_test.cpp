// The servo thread's share of tp::LookaheadPlanner: bounded work per cycle
// whatever the program (counted, never timed), no allocation. What it
// costs in time on this machine: build/bin/bench_tp (docs/tp.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <thread>

#include "tests/core/tp/tp_test_util.hpp"
#include "tests/support/testing.hpp"

namespace cnc::tp {
namespace {

using test::expect_clean;
using test::feed_params;
using test::line_to;
using test::pose;
using test::profile;

RunResult run(const PlannerConfig& cfg, const Program& prog, RunOptions opt = {}) {
  return test::run_inline(cfg, prog, opt);
}

Program spiral(int n) { return test::spiral_polyline(n); }

// The servo thread's share of planning is bounded per cycle whatever the
// program: a deep queue of short curved moves arriving at once (a spiral
// polyline, G64 P0.01, 600 moves of 0.2 mm, all queued in the first
// cycles) once made one cycle take in, split and envelope the whole queue
// (the envelope's backward walk over every span). Counted, not timed.
TEST(TpRealtime, ServoCycleWorkIsBoundedWhateverTheQueue) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  const Program prog = spiral(600);
  Executor::CycleWork most;
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 1 << 20;
  opt.before_cycle = [&](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
    const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
    most.ingested = std::max(most.ingested, w.ingested);
    most.split = std::max(most.split, w.split);
    most.enveloped = std::max(most.enveloped, w.enveloped);
  };
  const RunResult r = run(cfg, prog, opt);
  expect_clean(r);
  EXPECT_LE(most.ingested, Executor::kIngestPerCycle);
  EXPECT_LE(most.split, Executor::kSplitPerCycle);
  EXPECT_LE(most.enveloped, Executor::kEnvelopePerCycle);
  EXPECT_GT(most.enveloped, 0);
}

TEST(TpRealtime, ServoThreadCallsNeverAllocate) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counter off in sanitizer builds";
  const PlannerConfig cfg = profile("mill-s", 0.00025);
  const Program prog = test::random_program(77, 80);
  for (PlannerThreading th : {PlannerThreading::Inline, PlannerThreading::OwnThread}) {
    auto planner = make_planner(cfg, th);  // construction allocates
    planner->set_position(prog.start);
    CycleInputs in;
    CycleOutputs out;
    std::size_t next = 0;
    uint64_t allocations = 0;
    {
      testing::ScopedAllocationCheck check;  // this (the servo) thread only
      // A real servo thread sleeps between cycles; this loop yields so the
      // builder thread gets the CPU on a loaded machine. When it is late
      // anyway the executor stops and waits (more cycles, no allocation):
      // the cycle bound is generous for that.
      for (int c = 0; c < 4'000'000 && !(next == prog.moves.size() && planner->is_done()); ++c) {
        if (th == PlannerThreading::OwnThread) std::this_thread::yield();
        while (next < prog.moves.size() && queue_move(*planner, prog, next) != Result::QueueFull) ++next;
        if (c == 3000) planner->pause();
        if (c == 3500) planner->resume();
        in.feed_scale = c > 5000 && c < 9000 ? 0.3 : 1.0;
        planner->run_cycle(in, out);
      }
      allocations = check.allocations();
    }
    EXPECT_TRUE(planner->is_done());
    EXPECT_EQ(allocations, 0u) << (th == PlannerThreading::Inline ? "inline" : "own thread");
  }
}

// The envelope's walk is bounded in range minima (its unit of cost), not
// only in spans: a span on curved pieces takes up to kSpanQueriesMax of
// them, a straight one a handful, so 24 curved spans in one cycle (the
// walk near the input) once cost up to 10 000 queries on this spiral.
// Now the walk stops after kQueriesUrgent queries, past the span it is
// on. Whole spiral queued at once, then fed at one move a
// cycle: both ways the walk runs near the input.
TEST(TpRealtime, EnvelopeWalkIsBoundedInRangeQueriesPerCycle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  for (int per_cycle : {1 << 20, 1}) {
    SCOPED_TRACE(per_cycle);
    int most = 0, most_total = 0;
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = per_cycle;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
      const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
      most = std::max(most, w.envelope_queries);
      most_total = std::max(most_total, w.queries);
    };
    const RunResult r = run(cfg, spiral(1500), opt);
    expect_clean(r);
    EXPECT_GT(most, 0);
    EXPECT_LE(most, Executor::kQueriesUrgent + Executor::kSpanQueriesMax);
    // The split (one query a piece) and the input's limits (two) besides.
    EXPECT_LE(most_total, Executor::kQueriesUrgent + Executor::kSpanQueriesMax + Executor::kSplitPerCycle + 2);
  }
}

// The envelope's range minima mostly take the answer of one asked before
// (issue 20: the walk's cycles were the slowest 0.1 %, at about 25 ns a
// range minimum). Its nested bisections (over the velocity, and within
// each over the braking acceleration) move a range's ends by less than a
// piece from one query to the next; a query that resolves to the same
// pieces as one of the last two of its grid channel is answered without a
// search or a tree query (Executor::RangeMemo). The walk's budget stays in
// queries, so its pace and the motion are unchanged. Counted, not timed:
// on the spiral of 0.2 mm moves, queued at once and at a move a cycle, the
// walk searches for a small part of its queries, overall and in every
// cycle that walks a full slice (every query was a search before).
TEST(TpRealtime, EnvelopeRangeMinimaReuseTheAnswersOfTheirChannel) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  for (int per_cycle : {1 << 20, 1}) {
    SCOPED_TRACE(per_cycle);
    uint64_t queries = 0, searches = 0, full_slices = 0;
    double worst = 0;  // largest share searched in a cycle walking a full slice
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = per_cycle;
    opt.before_cycle = [&](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
      const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
      EXPECT_LE(w.envelope_searches, w.envelope_queries);
      EXPECT_LE(w.searches, w.queries);
      queries += static_cast<uint64_t>(w.envelope_queries);
      searches += static_cast<uint64_t>(w.envelope_searches);
      if (w.envelope_queries >= Executor::kQueriesPerCycle) {
        ++full_slices;
        worst = std::max(worst, static_cast<double>(w.envelope_searches) / w.envelope_queries);
      }
    };
    const RunResult r = run(cfg, spiral(1500), opt);
    expect_clean(r);
    ASSERT_GT(queries, 100'000u);
    ASSERT_GT(full_slices, 50u);
    std::printf("walk: %llu range minima, %llu searched (%.1f %%); %llu cycles at a full slice, at most %.1f %% searched\n",
                static_cast<unsigned long long>(queries), static_cast<unsigned long long>(searches),
                100.0 * static_cast<double>(searches) / static_cast<double>(queries),
                static_cast<unsigned long long>(full_slices), 100 * worst);
    EXPECT_LE(searches * 10, queries);  // 4.7 % and 3.5 % measured
    EXPECT_LE(worst, 0.25);
  }
}

// The envelope's walk over a deep queue of short curved moves (issue 20:
// the planner's servo-thread work per cycle): a walk from the tail
// re-walks the stretch within a stop of the old tail, whatever was added,
// so walking after every new piece (one a cycle or two on a dense program)
// kept the walk at its per-cycle slice nearly all the time. New spans far
// ahead of the input are walked in batches now. Counted, not timed: on a
// spiral of 4000 moves of 0.2 mm with 1000 of look-ahead, the walk's range minima per
// cycle stay within the slice (the urgent slice only while the whole
// look-ahead arrives at the start), and their mean over the program is a
// small part of it.
TEST(TpRealtime, EnvelopeWorkOnADenseProgramStaysWithinTheSlicesAndIsMostlyIdle) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  const Program prog = spiral(4000);
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 1 << 20;
  uint64_t cycles = 0, total = 0, above_slice = 0;
  int most = 0, most_split = 0, most_ingested = 0;
  opt.before_cycle = [&](uint64_t, TrajectoryPlanner& planner, CycleInputs&) {
    const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
    ++cycles;
    total += static_cast<uint64_t>(w.envelope_queries);
    most = std::max(most, w.envelope_queries);
    most_split = std::max(most_split, w.split);
    most_ingested = std::max(most_ingested, w.ingested);
    if (w.envelope_queries > Executor::kQueriesPerCycle + Executor::kSpanQueriesMax) ++above_slice;
  };
  const RunResult r = run(cfg, prog, opt);
  expect_clean(r);
  ASSERT_GT(cycles, 5000u);
  EXPECT_LE(most, Executor::kQueriesUrgent + Executor::kSpanQueriesMax);
  EXPECT_LE(most_split, Executor::kSplitPerCycle);
  EXPECT_LE(most_ingested, Executor::kIngestPerCycle);
  // Above the slice (the urgent walk) in at most 1 % of the cycles: the
  // start, while the look-ahead arrives (28 of 10 707 cycles).
  EXPECT_LE(above_slice * 100, cycles);
  // 200 range minima a cycle on average (488 when every new piece started
  // a walk): the walk keeps up with a margin.
  EXPECT_LE(total, cycles * 300);
}

// Where the slowest cycles of a dense program came from (issue 20,
// run_cycle p99.9): the envelope's walk at its urgent slice
// (kQueriesUrgent range minima) in the same cycle as the input's search
// for its step (up to 18 brake simulations, CycleWork::brakes), both
// where a circle of 0.05 mm lines turns through a quadrant (the input
// brakes against the envelope there, in runs of cycles). And with a
// look-ahead shorter than the walk's urgency distance (the circle's 1000
// moves are 50 mm, about that distance at LC) every walk from the tail
// ran at the urgent slice, though it changed nothing within the input's
// reach. Now the urgent slice waits while the input searched in the last
// kSearchQuiet cycles, and is taken only on spans the input may need
// soon (within about twice a stop from twice its speed, or never walked:
// a start). Counted, not timed: the circle fed as bench_tp feeds it (64
// moves a cycle).
TEST(TpRealtime, TheWalksUrgentSliceWaitsForTheInputsSearchAndForSpansItMayNeed) {
  PlannerConfig cfg = profile("lc", 0.001);
  cfg.lookahead_segments = 1000;
  Program prog;
  prog.start = pose(0, 0, 0);
  SegmentParams p = feed_params(100, 0.01);
  p.naive_cam_tolerance = 0.01;
  const int n = static_cast<int>(2 * std::numbers::pi * 10 / 0.05);
  prog.moves.push_back(line_to(10, 0, 0, p));
  for (int turn = 0; turn < 2; ++turn) {
    for (int i = 1; i <= n; ++i) {
      const double a = 2 * std::numbers::pi * i / n;
      prog.moves.push_back(line_to(10 * std::cos(a), 10 * std::sin(a), 0, p));
    }
  }
  RunOptions opt;
  opt.flush_at_end = true;
  opt.moves_per_cycle = 64;
  std::vector<int> brakes, queries;
  opt.before_cycle = [&](uint64_t cycle, TrajectoryPlanner& planner, CycleInputs&) {
    if (cycle == 0) return;  // cycle_work() is the last cycle's
    const Executor::CycleWork& w = dynamic_cast<LookaheadPlanner&>(planner).executor().cycle_work();
    brakes.push_back(w.brakes);
    queries.push_back(w.envelope_queries);
  };
  const RunResult r = run(cfg, prog, opt);
  expect_clean(r);
  ASSERT_GT(queries.size(), 1500u);
  const int slice = Executor::kQueriesPerCycle + Executor::kSpanQueriesMax;
  int urgent = 0, searched = 0, together = 0;
  for (std::size_t c = 0; c < queries.size(); ++c) {
    searched += brakes[c] > 1;
    if (queries[c] <= slice) continue;
    ++urgent;
    // A search in the kSearchQuiet cycles before: the urgent slice waits.
    for (std::size_t b = c >= Executor::kSearchQuiet ? c - Executor::kSearchQuiet : 0; b < c; ++b) {
      if (brakes[b] > 1) {
        ++together;
        break;
      }
    }
  }
  std::printf("%zu cycles: %d searched, %d above the ordinary slice, %d of them after a search\n", queries.size(),
              searched, urgent, together);
  EXPECT_GT(searched, 50);
  EXPECT_EQ(together, 0);
  // The start (the look-ahead arriving, the walks coming down to the
  // input) and walks through new spans at the tail: 119 of 1788 cycles
  // above the ordinary slice, 737 before (253 of them within
  // kSearchQuiet cycles after a search).
  EXPECT_LE(urgent, 200);
}

}  // namespace
}  // namespace cnc::tp
