// Tables sampled from the model: signs (a trim undoes the deviation),
// spacing chosen for a stated interpolation error, reference offset.
#include <gtest/gtest.h>

#include <cmath>

#include "comp/tables.hpp"

using namespace cnc::comp;

namespace {
ErrorModel model() {
  ErrorModel m;
  m.x_min = 0;
  m.x_max = 300;
  m.spline = {0, 1, 3, 2, 5, 6, 4, 7};  // um
  m.backlash0_um = 6;
  m.backlash1_um = 2;
  m.lead_mm = 5;
  m.sin_um = {1.2};
  m.cos_um = {-0.4};
  return m;
}
}  // namespace

TEST(CompTables, TrimsUndoTheDeviation) {
  const ErrorModel m = model();
  TableOptions o;
  o.points = 301;
  const CompTable t = make_comp_table(m, o);
  ASSERT_EQ(t.size(), 301u);
  EXPECT_DOUBLE_EQ(t.nominal.front(), 0);
  EXPECT_DOUBLE_EQ(t.nominal.back(), 300);
  for (std::size_t i = 0; i < t.size(); i += 37) {
    EXPECT_NEAR(t.forward[i] * 1000, -m.deviation_um(t.nominal[i], 1), 1e-9);
    EXPECT_NEAR(t.reverse[i] * 1000, -m.deviation_um(t.nominal[i], -1), 1e-9);
  }
}

TEST(CompTables, AutomaticSpacingMeetsTheTolerance) {
  const ErrorModel m = model();
  for (const double tol : {0.5, 0.1, 0.02}) {
    TableOptions o;
    o.tolerance_um = tol;
    const CompTable t = make_comp_table(m, o);
    const double err = interpolation_error_um(t, m);
    EXPECT_LE(err, tol) << t.size() << " points";
    // Not wasteful: a table a quarter smaller misses the tolerance.
    TableOptions fewer;
    fewer.points = static_cast<int>(t.size() * 3 / 4);
    EXPECT_GT(interpolation_error_um(make_comp_table(m, fewer), m), tol * 0.9) << tol;
  }
  TableOptions o;
  o.spacing_mm = 0.7;
  const CompTable t = make_comp_table(m, o);
  EXPECT_LE(t.nominal[1] - t.nominal[0], 0.7 + 1e-12);
  EXPECT_DOUBLE_EQ(t.nominal.back(), 300);
}

TEST(CompTables, AReferencePositionGetsAZeroMeanCorrection) {
  const ErrorModel m = model();
  TableOptions o;
  o.points = 601;
  o.reference_mm = 100;
  const CompTable t = make_comp_table(m, o);
  EXPECT_NEAR(t.at(100, 1) + t.at(100, -1), 0, 1e-12);
  EXPECT_NEAR((t.at(100, 1) - t.at(100, -1)) * 1000, -m.backlash_um(100), 1e-6);
  EXPECT_LE(interpolation_error_um(t, m, reference_offset_um(m, o)), 0.15);
}
