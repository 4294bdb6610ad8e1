// Property tests over seeded random programs: every sample within the
// per-axis v/a/j limits, every sample within the tolerance of the
// programmed path, the path ends exactly at the programmed end point,
// progress is monotone and the machine can always stop within the planned
// distance.
#include <gtest/gtest.h>

#include <cstdlib>
#include <random>

#include "tests/core/tp/tp_test_util.hpp"

namespace cnc::tp {
namespace {

struct Case {
  const char* profile;
  double cycle_s;
};

void check_seed(uint32_t seed, int moves, const Case& c, PlannerThreading threading = PlannerThreading::Inline) {
  const PlannerConfig cfg = test::profile(c.profile, c.cycle_s);
  const Program prog = test::random_program(seed, moves);
  auto planner = make_planner(cfg, threading);
  RunOptions opt;
  opt.moves_per_cycle = 1 + static_cast<int>(seed % 7);
  const RunResult r = run_program(*planner, cfg, prog, opt);
  SCOPED_TRACE(testing::Message() << "seed " << seed << " profile " << c.profile << " T " << c.cycle_s);
  ASSERT_TRUE(r.completed) << "cycles " << r.cycles;
  EXPECT_LE(r.stats.ratio_v, 1 + 1e-9);
  EXPECT_LE(r.stats.ratio_a, 1 + 1e-9);
  EXPECT_LE(r.stats.ratio_j, 1 + 1e-9);
  EXPECT_LE(r.stats.deviation_ratio, 1 + 1e-6) << "max deviation " << r.stats.max_deviation;
  EXPECT_LT(r.stats.end_error, 1e-9);
  EXPECT_TRUE(r.monotone);
  // The model margin covers samples whose stop stays clear of barriers
  // (tight corners, braked in two stages); StarvedPlannerStopsWithinPlannedPath
  // checks every case by actually stopping.
  EXPECT_GE(r.stop_margin, -1e-7);
  EXPECT_EQ(r.overruns, 0u);
}

// The interpreter stops feeding at a random moment and the planner is not
// allowed to flush: the machine must come to rest inside what it had
// planned (never past its end, no limit broken), then go on when the moves
// come again.
void check_starved(uint32_t seed, int moves, const Case& c) {
  PlannerConfig cfg = test::profile(c.profile, c.cycle_s);
  cfg.flush_idle_cycles = 1 << 30;
  const Program prog = test::random_program(seed, moves);
  uint64_t total = 0;
  {
    auto planner = make_planner(cfg, PlannerThreading::Inline);
    RunOptions opt;
    opt.flush_at_end = true;
    total = run_program(*planner, cfg, prog, opt).cycles;
  }
  std::mt19937 rng(seed);
  for (int k = 0; k < 2; ++k) {
    auto planner = make_planner(cfg, PlannerThreading::Inline);
    RunOptions opt;
    opt.flush_at_end = true;
    opt.moves_per_cycle = 1 + static_cast<int>(rng() % 5);
    opt.starve_from_cycle = 2 + rng() % std::max<uint64_t>(1, total / 2);
    const RunResult r = run_program(*planner, cfg, prog, opt);
    SCOPED_TRACE(testing::Message() << "seed " << seed << " profile " << c.profile << " T " << c.cycle_s
                                    << " starved at " << opt.starve_from_cycle);
    ASSERT_TRUE(r.completed) << "cycles " << r.cycles;
    EXPECT_TRUE(r.starve_stopped);
    EXPECT_GE(r.starve_stop_gap, 0.0);
    EXPECT_EQ(r.overruns, 0u);
    EXPECT_LE(r.stats.ratio_v, 1 + 1e-9);
    EXPECT_LE(r.stats.ratio_a, 1 + 1e-9);
    EXPECT_LE(r.stats.ratio_j, 1 + 1e-9);
    EXPECT_LE(r.stats.deviation_ratio, 1 + 1e-6) << "max deviation " << r.stats.max_deviation;
    EXPECT_LT(r.stats.end_error, 1e-9);
    EXPECT_TRUE(r.monotone);
  }
}

int seeds_from_env(int fallback) {
  const char* e = std::getenv("CNC_TP_SEEDS");
  return e ? std::atoi(e) : fallback;
}

TEST(TpProperty, RandomProgramsHoldLimitsAndTolerance) {
  const Case cases[] = {{"lc", 0.001}, {"mill-s", 0.00025}, {"mill-f", 0.001}};
  const int n = seeds_from_env(12);
  for (int s = 0; s < n; ++s) check_seed(1000 + static_cast<uint32_t>(s), 60, cases[s % 3]);
}

TEST(TpProperty, StarvedPlannerStopsWithinPlannedPath) {
  const Case cases[] = {{"lc", 0.001}, {"mill-s", 0.00025}, {"mill-f", 0.001}};
  const int n = seeds_from_env(12) / 2;
  for (int s = 0; s < n; ++s) check_starved(2000 + static_cast<uint32_t>(s), 40, cases[s % 3]);
}

TEST(TpProperty, OwnThreadPlannerHoldsLimits) {
  // The same checks with the builder on its own thread (timing-dependent
  // interleaving; the properties must hold for every one).
  for (uint32_t s = 0; s < 2; ++s) check_seed(3000 + s, 40, {"mill-f", 0.001}, PlannerThreading::OwnThread);
}

}  // namespace
}  // namespace cnc::tp
