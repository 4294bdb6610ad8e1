// Step 8 of commissioning without a controller: the cycle inside the soft
// limits, readings from a laser's file, entered values and measurement
// files checked with file and line, the fit lowering ISO 230-2 A, the
// table in the written configuration, and the state keeping it all.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "commission/compensation.hpp"
#include "comp/comp_table.hpp"
#include "commission/config_writer.hpp"
#include "commission/state.hpp"
#include "core/util/error.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

State one_axis() {
  State s;
  s.interface = "virtual:comp";
  ScannedNode n;
  n.node_id = 1;
  n.cia402 = true;
  n.encoder_increments = 10000;
  s.nodes.push_back(n);
  Axis a;
  a.letter = 'X';
  a.joint = 0;
  a.node = 1;
  a.scaling.encoder_counts = 10000;
  a.scaling.screw_lead = 5;
  a.min_limit = -10;
  a.max_limit = 250;
  a.limits_source = "entered";
  a.max_velocity = 30;
  s.axes.push_back(a);
  return s;
}

// A screw 40 um/m long, a wave of 6 um and 5 um of backlash: what a laser
// would read at each stop (mm, zero anywhere).
double truth_um(double x, int direction) { return 0.04 * x + 6 * std::sin(x / 40) + direction * 2.5; }
std::vector<double> laser_readings(const std::vector<CycleStop>& stops) {
  std::vector<double> r;
  for (const CycleStop& st : stops) r.push_back(17.5 + st.target + truth_um(st.target, st.direction) / 1000);
  return r;
}

void write(const std::filesystem::path& p, const std::string& s) {
  std::ofstream out(p);
  out << s;
}

TEST(CommissionCompensation, TheDefaultCycleStaysInsideTheSoftLimitsWithItsOvershoot) {
  State s = one_axis();
  const Axis& a = s.axes[0];
  const AxisCompensation c = default_compensation(a);
  EXPECT_NO_THROW(check_cycle(a, c));
  EXPECT_GE(c.x_min - c.overshoot_mm, a.min_limit);
  EXPECT_LE(c.x_max + c.overshoot_mm, a.max_limit);
  EXPECT_LE(c.feed_mm_min, a.max_velocity * 60);
  const auto stops = cycle_stops(a, c);
  const auto targets = comp::iso_targets(cycle_options(a, c));
  ASSERT_EQ(stops.size(), targets.size() * 2 * static_cast<std::size_t>(c.runs));
  EXPECT_EQ(stops.front().direction, 1);
  EXPECT_DOUBLE_EQ(stops.front().target, targets.front());
  EXPECT_EQ(stops[targets.size()].direction, -1);
  EXPECT_DOUBLE_EQ(stops[targets.size()].target, targets.back());
  // The program is comp/'s cycle, G53 moves of this axis.
  EXPECT_NE(comp::iso_cycle_gcode(cycle_options(a, c)).find("G53 G1 X"), std::string::npos);
}

TEST(CommissionCompensation, ACycleBeyondTheSoftLimitsOrWithOneRunIsRefusedNamingTheAxis) {
  State s = one_axis();
  AxisCompensation c = default_compensation(s.axes[0]);
  c.x_max = 249;  // + 2 mm overshoot > 250
  try {
    check_cycle(s.axes[0], c);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis X"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("soft limits"), std::string::npos) << e.what();
  }
  c = default_compensation(s.axes[0]);
  c.runs = 1;
  EXPECT_THROW(check_cycle(s.axes[0], c), std::invalid_argument);
  c = default_compensation(s.axes[0]);
  c.feed_mm_min = 5000;  // above MAX_VELOCITY 30 mm/s
  EXPECT_THROW(check_cycle(s.axes[0], c), std::invalid_argument);
}

TEST(CommissionCompensation, LaserReadingsBecomeDeviationsRelativeToTheFirstStop) {
  State s = one_axis();
  const AxisCompensation c = default_compensation(s.axes[0]);
  const auto stops = cycle_stops(s.axes[0], c);
  const auto points = points_from_readings(stops, laser_readings(stops));
  ASSERT_EQ(points.size(), stops.size());
  const double zero = truth_um(stops[0].target, 1);
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_NEAR(points[i].deviation_um, truth_um(stops[i].target, stops[i].direction) - zero, 1e-6) << i;
  EXPECT_EQ(points.back().run, c.runs);
  // An axis whose scaling is 1 % off reads millimetres off at the far end: refused naming the stop.
  std::vector<double> off = laser_readings(stops);
  for (std::size_t i = 0; i < off.size(); ++i) off[i] *= 1.01;
  try {
    points_from_readings(stops, off);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("more than 1 mm"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("stop ", 0), 0u) << e.what();
  }
}

TEST(CommissionCompensation, LaserCsvErrorsNameFileAndLine) {
  State s = one_axis();
  const auto stops = cycle_stops(s.axes[0], default_compensation(s.axes[0]));
  const auto r = laser_readings(stops);
  auto text_of = [&](std::size_t n, const std::string& header) {
    std::string t = "# laser export\n" + header;
    char b[64];
    for (std::size_t i = 0; i < n; ++i) {
      if (header.empty()) std::snprintf(b, sizeof b, "%.6f\n", r[i]);
      else std::snprintf(b, sizeof b, "%.3f,%c,%.6f\n", stops[i].target, stops[i].direction > 0 ? '+' : '-', r[i]);
      t += b;
    }
    return t;
  };
  // One reading per line, and the header form: both read.
  EXPECT_EQ(parse_laser_csv(text_of(stops.size(), ""), "laser.csv", stops).size(), stops.size());
  EXPECT_EQ(parse_laser_csv(text_of(stops.size(), "target,direction,reading_mm\n"), "laser.csv", stops).size(),
            stops.size());
  auto error_of = [&](const std::string& text) -> std::string {
    try {
      parse_laser_csv(text, "laser.csv", stops);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "accepted";
  };
  std::string bad = text_of(stops.size(), "");
  bad.replace(bad.find('\n', bad.find('\n', bad.find('\n') + 1) + 1) + 1, 0, "12.x4\n");  // line 4
  EXPECT_NE(error_of(bad).find("laser.csv:4:"), std::string::npos) << error_of(bad);
  EXPECT_NE(error_of(bad).find("12.x4"), std::string::npos);
  const std::string few = error_of(text_of(stops.size() - 1, ""));
  EXPECT_NE(few.find("laser.csv:"), std::string::npos) << few;
  EXPECT_NE(few.find(std::to_string(stops.size() - 1) + " reading(s)"), std::string::npos) << few;
  // A target that is not the cycle's (the readings in another order).
  std::string swapped = text_of(stops.size(), "target,direction,reading_mm\n");
  const std::size_t l3 = swapped.find('\n', swapped.find('\n') + 1) + 1;  // line 3: the first reading
  swapped.replace(l3, swapped.find(',', l3) - l3, "99.999");
  EXPECT_NE(error_of(swapped).find("laser.csv:3: target '99.999'"), std::string::npos) << error_of(swapped);
  EXPECT_NE(error_of("# nothing\nfoo,bar\n1,2\n").find("laser.csv:2:"), std::string::npos);
}

TEST(CommissionCompensation, EnteredValuesAndMeasurementFilesAreCheckedNamingTheValueOrLine) {
  State s = one_axis();
  const auto stops = cycle_stops(s.axes[0], default_compensation(s.axes[0]));
  std::string values;
  for (std::size_t i = 0; i < stops.size(); ++i) values += (i ? "," : "") + std::string(i == 1 ? "abc" : "1.5");
  try {
    points_from_values(stops, values);
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("value 2 'abc'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(points_from_values(stops, "1,2,3"), std::invalid_argument);
  EXPECT_EQ(points_from_values(stops, std::string(values).replace(values.find("abc"), 3, "2")).size(), stops.size());

  testing::TempDir dir;
  write(dir / "meas.csv", "# axis: X\ntarget,run,direction,deviation_um\n10,1,+,1.0\n10,1,sideways,2.0\n");
  try {
    points_from_measurement_file(s.axes[0], dir / "meas.csv");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.line(), 4) << e.what();
    EXPECT_NE(std::string(e.what()).find("meas.csv"), std::string::npos) << e.what();
  }
  write(dir / "far.csv", "target,run,direction,deviation_um\n300,1,+,1.0\n300,1,-,2.0\n");
  EXPECT_THROW(points_from_measurement_file(s.axes[0], dir / "far.csv"), ConfigError);  // beyond MAX_LIMIT 250
}

TEST(CommissionCompensation, TheFitOnAScrewWithPitchErrorAndBacklashLowersAAndTheTableIsWrittenWhenInstalled) {
  State s = one_axis();
  s.axes[0].compensation = default_compensation(s.axes[0]);
  const auto stops = cycle_stops(s.axes[0], *s.axes[0].compensation);
  const CompFigures& m = set_measurement(s, 'X', points_from_readings(stops, laser_readings(stops)), "test laser");
  EXPECT_GT(m.A, 10.0);
  EXPECT_NEAR(m.B, 5.0, 0.01);
  testing::TempDir dir;
  const std::string report = fit_compensation(s, 'X', dir / "fit", false);
  const AxisCompensation& c = *s.axes[0].compensation;
  std::printf("ISO 230-2 A measured %.3f um, predicted %.3f um; B %.3f -> %.3f um\n", c.before.A, c.predicted.A,
              c.before.B, c.predicted.B);
  EXPECT_TRUE(c.fitted);
  EXPECT_LT(c.predicted.A, c.before.A / 5);
  EXPECT_LT(c.predicted.B, 0.5);
  EXPECT_FALSE(c.nominal.empty());
  EXPECT_NE(report.find("predicted"), std::string::npos);
  for (const char* f : {"measurement.csv", "X.comp", "report.txt"}) EXPECT_TRUE(std::filesystem::exists(dir / "fit" / f)) << f;

  // Not installed: the configuration has no table.
  auto files = generate_config(s, dir.path(), "machine");
  EXPECT_EQ(files[0].content.find("COMP_FILE"), std::string::npos);
  EXPECT_EQ(files[1].content.find("screwcomp"), std::string::npos);
  // Installed: the table, its keys in [JOINT_0] and screwcomp in the HAL file.
  fit_compensation(s, 'X', dir / "fit", true);
  files = generate_config(s, dir.path(), "machine");
  const std::string& ini = files[0].content;
  const std::size_t joint = ini.find("[JOINT_0]");
  const std::size_t key = ini.find("COMP_FILE = machine-x.comp\nCOMP_FILE_TYPE = 1\n");
  ASSERT_NE(key, std::string::npos) << ini;
  EXPECT_GT(key, joint);
  EXPECT_LT(key, ini.find("[EMCIO]"));
  EXPECT_NE(files[1].content.find("loadrt screwcomp\n"), std::string::npos);
  bool table = false;
  for (const auto& f : files)
    if (f.path == dir / "machine-x.comp") {
      table = true;
      EXPECT_EQ(comp::parse_comp_table(f.content, comp::CompFileType::Trims, "machine-x.comp").size(), c.nominal.size());
    }
  EXPECT_TRUE(table);
  // A new scaling (another direction test) leaves the table behind: write refuses it, naming the axis.
  s.axes[0].scaling.correction = 1.001;
  try {
    generate_config(s, dir.path(), "machine");
    FAIL() << "a table of the old scaling was written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis X: the compensation was measured at 2000 counts/mm"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(fit_compensation(s, 'X', dir / "fit", true), std::invalid_argument);
  s.axes[0].scaling.correction = 1;
  // A new measurement drops the fit that belonged to the old one.
  set_measurement(s, 'X', points_from_readings(stops, laser_readings(stops)), "again");
  EXPECT_FALSE(s.axes[0].compensation->fitted);
  EXPECT_EQ(generate_config(s, dir.path(), "machine")[0].content.find("COMP_FILE"), std::string::npos);
}

TEST(CommissionCompensation, TheStateKeepsTheCycleMeasurementFitAndBackup) {
  State s = one_axis();
  s.axes[0].compensation = default_compensation(s.axes[0]);
  const auto stops = cycle_stops(s.axes[0], *s.axes[0].compensation);
  set_measurement(s, 'X', points_from_readings(stops, laser_readings(stops)), "test laser");
  testing::TempDir dir;
  fit_compensation(s, 'X', dir / "fit", true);
  set_measurement(s, 'X', points_from_readings(stops, laser_readings(stops)), "check", true);
  s.backup = DriveBackup{"/tmp/b", "2026-11-27T07:00:00Z", {"node-01-x.dcf"}};
  save_state(s, dir / "state.json");
  const State t = load_state(dir / "state.json");
  ASSERT_TRUE(t.axes[0].compensation);
  const AxisCompensation &a = *s.axes[0].compensation, &b = *t.axes[0].compensation;
  EXPECT_EQ(b.points.size(), a.points.size());
  EXPECT_EQ(b.check_points.size(), a.check_points.size());
  EXPECT_DOUBLE_EQ(b.points[7].deviation_um, a.points[7].deviation_um);
  EXPECT_EQ(b.points[7].direction, a.points[7].direction);
  EXPECT_TRUE(b.fitted);
  EXPECT_TRUE(b.install);
  EXPECT_DOUBLE_EQ(b.predicted.A, a.predicted.A);
  EXPECT_EQ(b.forward, a.forward);
  EXPECT_EQ(b.source, "test laser");
  ASSERT_TRUE(b.checked);
  ASSERT_TRUE(t.backup);
  EXPECT_EQ(t.backup->files, std::vector<std::string>{"node-01-x.dcf"});
  // A broken table is named with file and key.
  std::string text = to_json_text(s);
  text.replace(text.find("\"forward\": ["), 12, "\"forward\": [1, ");
  try {
    from_json_text(text, "state.json");
    FAIL() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("state.json: axes[].compensation.table"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cnc::commission
