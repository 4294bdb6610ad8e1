// The path builder's own work (core/tp/path_builder.hpp), counted rather
// than timed: what it does per queued move on a dense CAM polyline.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/tp/path_builder.hpp"
#include "tests/core/tp/tp_test_util.hpp"

namespace cnc::tp {
namespace {

using test::feed_params;
using test::profile;

// A spiral of 0.2 mm chords as CAM writes it (gen_gcode --mode poly), built
// with no servo side: the rings are large enough for everything.
struct SpiralBuild {
  PathStore store{1 << 14, 1 << 14, 1 << 17};
  PathBuilder builder;
  int moves = 0;

  explicit SpiralBuild(int n) : builder(profile("lc"), store) {
    const SegmentParams p = feed_params(100, 0.01);
    double angle = 0;
    for (int i = 0; i < n; ++i) {
      const double r = 5 + 0.002 * i;
      angle += 0.2 / r;
      Pose end;
      end[0] = r * std::cos(angle);
      end[1] = r * std::sin(angle);
      if (i == 0) {
        Pose start = end;
        start[0] -= 0.2;
        builder.set_position(start);
      }
      EXPECT_EQ(builder.add_line(end, p), Result::Ok) << i;
      ++moves;
    }
    builder.flush();
  }
};

// The final check of a corner's window samples its stretch and sums, at
// each sample, the corrections of the windows that may reach it. Only the
// windows that overlap the stretch are summed, and at each sample only
// those not yet passed and not starting after it. Summing over every
// corner within two spans of it (up to 33, as before) made 3.7 times the
// terms (measured: 574 per move then, 229 when passed windows were
// skipped, 153 now that those ahead of the sample are skipped too).
TEST(TpBuilderWork, FinalCheckSumsOnlyTheWindowsThatReachTheSample) {
  SpiralBuild b(1500);
  ASSERT_FALSE(b.builder.has_held());
  EXPECT_GE(b.builder.segments_built(), 1400u);
  const double per_move = static_cast<double>(b.builder.check_terms()) / b.moves;
  EXPECT_GT(per_move, 50);  // the checks ran
  EXPECT_LT(per_move, 190);
}

// The tentative width of a corner is bisected (14 steps) on the deviation
// its neighbours would add at the same width. The sum of a step stops as
// soon as it exceeds the budget (its terms are never negative, so the
// answer is the full sum's): measured 137.8 terms per move
// before, 105.6 now.
TEST(TpBuilderWork, WidthBisectionStopsSummingOnceOverTheBudget) {
  SpiralBuild b(1500);
  ASSERT_FALSE(b.builder.has_held());
  const double per_move = static_cast<double>(b.builder.size_terms()) / b.moves;
  EXPECT_GT(per_move, 20);  // the bisections ran
  EXPECT_LT(per_move, 125);
}

}  // namespace
}  // namespace cnc::tp
