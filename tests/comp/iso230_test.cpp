// ISO 230-2 figures on hand-computed data sets, and the invariants the
// standard's definitions imply on many random ones (E >= max(E up, E down),
// A >= E, M <= E, R >= max(R up, R down), A >= max(A up, A down),
// B >= |mean B|), guarding against the mistakes published tools make.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "comp/iso230.hpp"

using namespace cnc::comp;

namespace {

Measurement from(const std::vector<std::tuple<double, int, std::vector<double>>>& groups) {
  Measurement m;
  for (const auto& [x, d, values] : groups) {
    int run = 1;
    for (double v : values) {
      MeasurementPoint p;
      p.target = x;
      p.direction = d;
      p.run = run++;
      p.deviation_um = v;
      m.points.push_back(p);
    }
  }
  return m;
}

const double kSqrt3 = std::sqrt(3.0);

}  // namespace

TEST(Iso230, HandComputedTwoTargetsThreeRuns) {
  // Target 0:   up 1 2 3 (mean 2, s 1)      down -1 -1 -4 (mean -2, s sqrt 3)
  // Target 100: up 5 5 8 (mean 6, s sqrt 3) down  4  6  5 (mean 5, s 1)
  const Iso230Result r = evaluate_iso230(from({{100, 1, {5, 5, 8}},
                                               {0, 1, {1, 2, 3}},
                                               {0, -1, {-1, -1, -4}},
                                               {100, -1, {4, 6, 5}}}));
  ASSERT_EQ(r.targets.size(), 2u);
  const Iso230Target& a = r.targets[0];
  const Iso230Target& b = r.targets[1];
  EXPECT_DOUBLE_EQ(a.position, 0);
  EXPECT_DOUBLE_EQ(a.mean_up, 2);
  EXPECT_DOUBLE_EQ(a.mean_down, -2);
  EXPECT_DOUBLE_EQ(a.mean, 0);
  EXPECT_DOUBLE_EQ(a.reversal, 4);
  EXPECT_DOUBLE_EQ(a.s_up, 1) << "n - 1 in the denominator (n would give 0.816)";
  EXPECT_NEAR(a.s_down, kSqrt3, 1e-12);
  EXPECT_DOUBLE_EQ(a.r_up, 4);
  EXPECT_NEAR(a.r_down, 4 * kSqrt3, 1e-12);
  EXPECT_NEAR(a.r, 2 + 2 * kSqrt3 + 4, 1e-12) << "R_i includes the reversal term";
  EXPECT_DOUBLE_EQ(b.mean, 5.5);
  EXPECT_DOUBLE_EQ(b.reversal, 1);
  EXPECT_NEAR(b.r, 4 * kSqrt3, 1e-12) << "here R_i up is the largest of the three";

  EXPECT_EQ(r.min_runs, 3);
  EXPECT_DOUBLE_EQ(r.B, 4);
  EXPECT_DOUBLE_EQ(r.B_mean, 2.5);
  EXPECT_NEAR(r.R_up, 4 * kSqrt3, 1e-12);
  EXPECT_NEAR(r.R_down, 4 * kSqrt3, 1e-12);
  EXPECT_NEAR(r.R, 6 + 2 * kSqrt3, 1e-12) << "R is not max(R up, R down)";
  EXPECT_DOUBLE_EQ(r.E_up, 4);
  EXPECT_DOUBLE_EQ(r.E_down, 7);
  EXPECT_DOUBLE_EQ(r.E, 8);
  EXPECT_DOUBLE_EQ(r.M, 5.5);
  EXPECT_NEAR(r.A_up, 6 + 2 * kSqrt3 - 0, 1e-12);
  EXPECT_NEAR(r.A_down, 7 - (-2 - 2 * kSqrt3), 1e-12);
  EXPECT_NEAR(r.A, (6 + 2 * kSqrt3) - (-2 - 2 * kSqrt3), 1e-12);
  ASSERT_EQ(r.warnings.size(), 2u) << "3 runs and 2 targets fall short of the standard test";
}

TEST(Iso230, NegativeReversalsAndUpDownLabels) {
  // The down runs read higher than the up runs: B_i < 0. B is the largest
  // magnitude; mean B keeps the sign. Swapping up and down labels must
  // swap E up / E down and A up / A down, not E or A.
  const auto groups = std::vector<std::tuple<double, int, std::vector<double>>>{
      {0, 1, {0, 0.2}}, {0, -1, {3, 3.2}}, {50, 1, {1, 1.4}}, {50, -1, {2, 2.2}}, {90, 1, {-1, -1}}, {90, -1, {-3, -3}}};
  const Iso230Result r = evaluate_iso230(from(groups));
  EXPECT_NEAR(r.targets[0].reversal, -3, 1e-12);
  EXPECT_NEAR(r.targets[1].reversal, -0.9, 1e-12);
  EXPECT_NEAR(r.targets[2].reversal, 2, 1e-12);
  EXPECT_NEAR(r.B, 3, 1e-12);
  EXPECT_NEAR(r.B_mean, (-3 - 0.9 + 2) / 3, 1e-12);
  auto swapped = groups;
  for (auto& g : swapped) std::get<1>(g) = -std::get<1>(g);
  const Iso230Result s = evaluate_iso230(from(swapped));
  EXPECT_NEAR(s.E_up, r.E_down, 1e-12);
  EXPECT_NEAR(s.E_down, r.E_up, 1e-12);
  EXPECT_NEAR(s.A_up, r.A_down, 1e-12);
  EXPECT_NEAR(s.E, r.E, 1e-12);
  EXPECT_NEAR(s.A, r.A, 1e-12);
  EXPECT_NEAR(s.B_mean, -r.B_mean, 1e-12);
}

TEST(Iso230, TargetsWithoutRunsBothWaysAreRefusedByName) {
  try {
    evaluate_iso230(from({{0, 1, {1, 2}}, {0, -1, {1, 2}}, {25.5, 1, {1, 2, 3}}, {25.5, -1, {1}}}));
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(),
                 "target 25.5: ISO 230-2 needs at least two runs in each direction (found 3 moving + and 1 moving -)");
  }
}

TEST(Iso230, InvariantsHoldOnRandomMeasurements) {
  for (uint64_t seed = 1; seed <= 500; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> targets(2, 15), runs(2, 7);
    std::normal_distribution<double> level(0, 10), spread(0, 1), reversal(0, 5);
    std::uniform_real_distribution<double> noise_scale(0.01, 3);
    Measurement m;
    const int nt = targets(rng), nr = runs(rng);
    for (int i = 0; i < nt; ++i) {
      const double base = level(rng), rev = reversal(rng), sc = noise_scale(rng);
      for (int d : {1, -1}) {
        for (int j = 1; j <= nr; ++j) {
          MeasurementPoint p;
          p.target = i * 17.5;
          p.direction = d;
          p.run = j;
          p.deviation_um = base + d * rev / 2 + sc * spread(rng);
          m.points.push_back(p);
        }
      }
    }
    const Iso230Result r = evaluate_iso230(m);
    ASSERT_EQ(static_cast<int>(r.targets.size()), nt);
    EXPECT_GE(r.E, std::max(r.E_up, r.E_down) - 1e-12);
    EXPECT_GE(r.A, r.E - 1e-12);
    EXPECT_LE(r.M, r.E + 1e-12);
    EXPECT_GE(r.R, std::max(r.R_up, r.R_down) - 1e-12);
    EXPECT_GE(r.A, std::max(r.A_up, r.A_down) - 1e-12);
    EXPECT_GE(r.B, std::fabs(r.B_mean) - 1e-12);
    EXPECT_GE(r.A_up, r.E_up - 1e-12);
    EXPECT_GE(r.A_down, r.E_down - 1e-12);
    for (const Iso230Target& t : r.targets) {
      EXPECT_GE(t.r, std::fabs(t.reversal) - 1e-12);
      EXPECT_LE(t.r, r.R + 1e-12);
    }
  }
}

// +-1e300 gave A = inf and a report with rc 0 (the file reader now refuses
// such values; the evaluation refuses them too when built in code).
TEST(Iso230, FiguresThatOverflowAreRefusedNotReportedAsInfinite) {
  EXPECT_THROW(evaluate_iso230(from({{0, 1, {1e300, -1e300}}, {0, -1, {0, 1}}})), std::invalid_argument);
  EXPECT_THROW(evaluate_iso230(from({{0, 1, {std::nan(""), 1}}, {0, -1, {0, 1}}})), std::invalid_argument);
}

TEST(Iso230, DeviationsThatLookLikeMillimetresAreFlagged) {
  const Iso230Result r = evaluate_iso230(from({{0, 1, {0.002, 0.003}}, {0, -1, {-0.001, 0.004}}}));
  bool said = false;
  for (const auto& w : r.warnings) said = said || w.find("are they in millimetres?") != std::string::npos;
  EXPECT_TRUE(said);
}
