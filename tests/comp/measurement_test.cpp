// The measurement file (docs/compensation.md): columns by name, optional
// temperature and time, errors with file and line, run numbering.
#include <gtest/gtest.h>

#include <cmath>

#include "comp/measurement.hpp"
#include "core/util/error.hpp"

using namespace cnc;
using namespace cnc::comp;

namespace {
std::string error_of(const std::string& text) {
  try {
    parse_measurement(text, "m.csv");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

TEST(MeasurementFile, ReadsColumnsByNameInAnyOrder) {
  const Measurement m = parse_measurement(
      "# axis: Y\n# a note\nrun,direction,target,deviation_um,time_s\n1,+,10.5,1.25,3\n1,down,10.5,-0.75,4.5\n",
      "m.csv");
  EXPECT_EQ(m.axis, "Y");
  ASSERT_EQ(m.points.size(), 2u);
  EXPECT_DOUBLE_EQ(m.points[0].target, 10.5);
  EXPECT_EQ(m.points[0].direction, 1);
  EXPECT_EQ(m.points[1].direction, -1);
  EXPECT_DOUBLE_EQ(m.points[1].deviation_um, -0.75);
  EXPECT_DOUBLE_EQ(m.points[1].time_s, 4.5);
  EXPECT_TRUE(std::isnan(m.points[0].temperature_c));
  EXPECT_FALSE(m.has_temperature());
  EXPECT_TRUE(m.has_time());
  EXPECT_EQ(m.notes, std::vector<std::string>{"a note"});
}

TEST(MeasurementFile, WritesWhatItReads) {
  Measurement m;
  m.axis = "X";
  m.notes = {"laser XL-80 stand-in"};
  for (int i = 0; i < 6; ++i) {
    MeasurementPoint p;
    p.target = 12.5 * i;
    p.run = 1 + i / 2;
    p.direction = i % 2 ? -1 : 1;
    p.deviation_um = 0.1234 * i - 0.3;
    p.temperature_c = 20.5 + 0.01 * i;
    p.time_s = 3.0 * i;
    m.points.push_back(p);
  }
  const Measurement back = parse_measurement(format_measurement(m), "rt");
  ASSERT_EQ(back.points.size(), m.points.size());
  EXPECT_EQ(back.axis, "X");
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    EXPECT_DOUBLE_EQ(back.points[i].target, m.points[i].target);
    EXPECT_EQ(back.points[i].run, m.points[i].run);
    EXPECT_EQ(back.points[i].direction, m.points[i].direction);
    EXPECT_NEAR(back.points[i].deviation_um, m.points[i].deviation_um, 1e-4);
    EXPECT_NEAR(back.points[i].temperature_c, m.points[i].temperature_c, 1e-3);
  }
}

TEST(MeasurementFile, ErrorsNameFileAndLine) {
  EXPECT_EQ(error_of("target,run,direction,deviation\n"),
            "m.csv:1: unknown column 'deviation' (expected target, run, direction, deviation_um and optionally "
            "temperature_c, time_s)");
  EXPECT_EQ(error_of("target,run,direction\n"),
            "m.csv:1: the header has no 'deviation_um' column (the first line that is not a comment names the columns: "
            "target,run,direction,deviation_um[,temperature_c][,time_s])");
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n1,1,+,0.5\n2,1,x,0.5\n"),
            "m.csv:3: direction: expected + or - (or up/down), found 'x'");
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n1,0,+,0.5\n"),
            "m.csv:2: run: expected a whole number from 1, found '0'");
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n1,1,+\n"), "m.csv:2: expected 4 values, found 3");
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n1,1,+,abc\n"), "m.csv:2: deviation_um: 'abc' is not a number");
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n"), "m.csv: no measured points");
  EXPECT_EQ(error_of("target,target,run,direction,deviation_um\n"), "m.csv:1: column 'target' appears twice");
}

TEST(MeasurementFile, RunsAreNumberedPerTargetAndDirection) {
  Measurement m;
  for (const auto& [x, d] : std::vector<std::pair<double, int>>{
           {0, 1}, {10, 1}, {10, -1}, {0, -1}, {0, 1}, {10.0000001, 1}, {10, -1}, {0, -1}, {0, 1}}) {
    MeasurementPoint p;
    p.target = x;
    p.direction = d;
    m.points.push_back(p);
  }
  number_runs(m);
  const std::vector<int> runs = {1, 1, 1, 1, 2, 2, 2, 2, 3};
  for (std::size_t i = 0; i < runs.size(); ++i) EXPECT_EQ(m.points[i].run, runs[i]) << "point " << i;
}

// Deviations written in nanometres (or a complog scale off by 1000) read as
// micrometres gave millimetre trims in the fitted tables and exports.
TEST(MeasurementFile, DeviationsLargerThanAMillimetreAreRefusedAsAUnitMistake) {
  const std::string head = "target,run,direction,deviation_um\n0,1,+,0.5\n";
  EXPECT_EQ(error_of(head + "25,1,+,6234.5\n"),
            "m.csv:3: deviation_um: 6234.5 um (6.2345 mm) is larger than 1000 um: deviations are in micrometres "
            "(position reached minus target); are these nanometres? A compensation from them would move the axis by "
            "millimetres. If the axis really is this far off, raise the limit (cnc-comp --max-deviation UM)");
  EXPECT_NE(error_of(head + "25,1,-,-1e300\n").find("m.csv:3: deviation_um: -1e+300 um"), std::string::npos);
  EXPECT_EQ(error_of(head + "25,1,+,-999.9\n"), "no error");
  MeasurementLimits wide;
  wide.max_abs_deviation_um = 10000;
  EXPECT_EQ(parse_measurement(head + "25,1,+,6234.5\n", "m.csv", wide).points.size(), 2u) << "raised knowingly";
}

TEST(MeasurementFile, TargetsTemperaturesAndTimesOutsideAnyMeasurementAreRefused) {
  EXPECT_EQ(error_of("target,run,direction,deviation_um\n1e300,1,+,0.5\n"),
            "m.csv:2: target: 1e+300 is not a position on a machine axis (more than 1000000 machine units from 0)");
  EXPECT_EQ(error_of("target,run,direction,deviation_um,temperature_c\n0,1,+,0.5,293.4\n"),
            "m.csv:2: temperature_c: 293.4 is outside -50..150 degrees Celsius (kelvin or Fahrenheit?)");
  EXPECT_NE(error_of("target,run,direction,deviation_um,time_s\n0,1,+,0.5,1e300\n").find("m.csv:2: time_s:"),
            std::string::npos);
}

// A copied block used to count as extra runs: n (and s, R, A) were wrong.
TEST(MeasurementFile, ARepeatedRunOfATargetAndDirectionIsRefused) {
  const std::string text =
      "target,run,direction,deviation_um\n"
      "0,1,+,0.5\n10,1,+,0.7\n10,1,-,0.1\n0,1,-,0.2\n"
      "0,2,+,0.6\n10,2,+,0.8\n10,2,-,0.2\n0,2,-,0.1\n"
      "10.0000001,1,+,0.7\n";  // line 2-5 again, in part
  EXPECT_EQ(error_of(text),
            "m.csv:10: run 1 of target 10 moving + appears again (first at line 3): each run of a target and "
            "direction is one line; a repeated line would count as an extra run");
  EXPECT_EQ(error_of(text.substr(0, text.rfind("10.0000001"))), "no error");
}
