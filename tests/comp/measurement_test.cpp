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
