// Motion time on small arcs (issue 20): the executor's tangential
// acceleration inside a curved piece that no corner window touches comes
// from the helix's exact shape (the tangential and normal parts of each
// axis's acceleration and jerk add in quadrature), not from the sum of the
// per-axis bounds of the curve's derivatives. Times are in servo cycles
// (deterministic), and every stream is checked sample by sample.
#include <gtest/gtest.h>

#include <array>

#include "tests/core/tp/tp_test_util.hpp"

namespace cnc::tp {
namespace {

using test::expect_clean;
using test::feed_params;
using test::line_to;
using test::pose;
using test::profile;

ProgramMove arc_to(const Pose& end, std::array<double, 3> center, std::array<double, 3> normal,
                   const SegmentParams& p) {
  ProgramMove m;
  m.kind = ProgramMove::Kind::Circle;
  m.end = end;
  m.center = center;
  m.normal = normal;
  m.params = p;
  m.params.type = MotionType::Arc;
  return m;
}

// gen_gcode.py --mode mixed in small: 1 mm lines along X and G2/G3 half
// circles of radius 0.5 mm, alternating, F6000, G64 P0.01. `dz` climbs
// each arc (a helix), `dr` ends each arc off its circle (a spiral).
Program serpentine(int pairs, double dz = 0, double dr = 0) {
  Program prog;
  const SegmentParams p = feed_params(100, 0.01);
  double x = 0, z = 0;
  for (int i = 0; i < pairs; ++i) {
    x += 1;
    prog.moves.push_back(line_to(x, 0, z, p));
    z += dz;
    const double ez = (i % 2 == 0 ? -1 : 1);  // G2, G3
    prog.moves.push_back(arc_to(pose(x + 1 + dr, 0, z), {x + 0.5, 0, z - dz}, {0, 0, ez}, p));
    x += 1 + dr;
  }
  return prog;
}

// 20 lines and 20 half circles under the LC limits. With the sums of the
// per-axis bounds the arcs allowed about 56 mm/s^2 of tangential
// acceleration near their velocity ceiling and the run took 6383 cycles;
// with the helix's shape 5431.
TEST(TpCurveTime, SmallArcsOfASerpentineSpeedUpAndBrakeWithinTheLimits) {
  const PlannerConfig cfg = profile("lc");
  const RunResult r = test::run_inline(cfg, serpentine(20));
  expect_clean(r);
  EXPECT_LT(r.cycles, 5800u);
}

// The same bound on helices and spirals, and on a faster machine: every
// output sample within the limits.
TEST(TpCurveTime, HelicesAndSpiralsOfSmallRadiusKeepTheLimits) {
  for (const char* prof : {"lc", "mill-s", "mill-f"}) {
    const PlannerConfig cfg = profile(prof);
    SCOPED_TRACE(prof);
    expect_clean(test::run_inline(cfg, serpentine(10, 0.3, 0)));
    expect_clean(test::run_inline(cfg, serpentine(10, 0, 0.2)));
    expect_clean(test::run_inline(cfg, serpentine(10, 0.2, -0.15)));
  }
}

}  // namespace
}  // namespace cnc::tp
