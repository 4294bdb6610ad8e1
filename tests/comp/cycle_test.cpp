// The measurement programs: ISO 230-2 targets (count, ends, uneven and
// seeded spacing), the standard cycle (runs, overshoot, dwell, measurement
// on/off with motion), and the dense periodic runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "comp/cycle.hpp"

using namespace cnc::comp;

namespace {
// G-code comments do not nest: at most one '(' and one ')' per line.
void expect_plain_comments(const std::string& g) {
  std::size_t start = 0;
  for (std::size_t end = g.find('\n'); end != std::string::npos; start = end + 1, end = g.find('\n', start)) {
    const std::string line = g.substr(start, end - start);
    EXPECT_LE(std::count(line.begin(), line.end(), '('), 1) << line;
    EXPECT_EQ(std::count(line.begin(), line.end(), '('), std::count(line.begin(), line.end(), ')')) << line;
  }
}

int count(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}
}  // namespace

TEST(MeasurementCycle, IsoTargetsFollowTheStandard) {
  CycleOptions o;
  o.x_min = 5;
  o.x_max = 285;
  const auto t = iso_targets(o);
  EXPECT_GE(t.size(), 5u);
  EXPECT_DOUBLE_EQ(t.front(), 5);
  EXPECT_DOUBLE_EQ(t.back(), 285);
  EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
  const double p = 280.0 / (t.size() - 1);
  std::set<long> gaps;
  for (std::size_t i = 1; i < t.size(); ++i) {
    gaps.insert(std::lround((t[i] - t[i - 1]) * 1000));
    EXPECT_LE(std::fabs(t[i] - (5 + i * p)), p / 5 + 1e-3) << "within a fifth of the nominal spacing";
  }
  EXPECT_GT(gaps.size(), t.size() / 2) << "spacing uneven on purpose";
  EXPECT_EQ(iso_targets(o), t) << "the same seed gives the same targets";
  o.seed = 2;
  EXPECT_NE(iso_targets(o), t);
  o.x_max = 1805;
  EXPECT_GE(iso_targets(o).size(), 10u) << "at least 5 per metre";
  o.targets = 7;
  EXPECT_EQ(iso_targets(o).size(), 7u);
}

TEST(MeasurementCycle, StandardCycleProgram) {
  CycleOptions o;
  o.x_min = 10;
  o.x_max = 110;
  o.targets = 6;
  o.runs = 5;
  o.dwell_s = 0.75;
  o.overshoot_mm = 3;
  o.digital_out = 2;
  o.axis = 'Y';
  const std::string g = iso_cycle_gcode(o);
  EXPECT_EQ(count(g, "G4 P0.750\n"), 6 * 5 * 2) << "one dwell per target, run and direction";
  EXPECT_EQ(count(g, "G53 G1 Y113.0000 (overshoot)"), 5);
  EXPECT_EQ(count(g, "G53 G1 Y7.0000 (overshoot)"), 5);
  EXPECT_NE(g.find("G61"), std::string::npos) << "exact stop";
  const std::size_t on = g.find("M62 P2"), off = g.find("M62 P3"), first = g.find("G53 G1 Y10.0000\nG4 P0.750");
  EXPECT_EQ(g.find("M65 P2\nM65 P3\n"), g.find("M65")) << "both marks cleared before anything moves";
  EXPECT_LT(g.find("M65"), g.find("G53"));
  ASSERT_NE(on, std::string::npos);
  ASSERT_NE(off, std::string::npos);
  EXPECT_LT(on, first) << "measurement on with the move to the first target";
  EXPECT_GT(off, g.rfind("G4 P0.750")) << "off after the last dwell";
  EXPECT_EQ(g.substr(g.size() - 3), "M2\n");
  expect_plain_comments(g);
}

TEST(MeasurementCycle, PeriodicRunsCoverLeadsAtSeveralPlaces) {
  CycleOptions o;
  o.x_min = 0;
  o.x_max = 300;
  o.lead_mm = 5;
  o.periodic_places = 3;
  o.periodic_leads = 2;
  o.periodic_steps_per_lead = 8;
  for (int place = 0; place < 3; ++place) {
    const auto t = periodic_targets(o, place);
    ASSERT_EQ(t.size(), 17u);
    EXPECT_NEAR(t.back() - t.front(), 10, 1e-9);
    EXPECT_NEAR(t[1] - t[0], 0.625, 1e-3);
    EXPECT_GE(t.front(), 0);
    EXPECT_LE(t.back(), 300);
  }
  EXPECT_DOUBLE_EQ(periodic_targets(o, 0).front(), 0);
  EXPECT_DOUBLE_EQ(periodic_targets(o, 2).back(), 300);
  const std::string g = periodic_cycle_gcode(o);
  EXPECT_EQ(count(g, "G4 P0.800\n"), 3 * 17 * o.periodic_runs * 2);
  EXPECT_EQ(count(g, "M62 P0"), 1);
  EXPECT_EQ(count(g, "M62 P1"), 1);
  EXPECT_EQ(count(g, "M63"), 0) << "an M63 read ahead would replace the M62 waiting for its move";
  expect_plain_comments(g);
  o.lead_mm = 0;
  EXPECT_THROW(periodic_cycle_gcode(o), std::invalid_argument);
}
