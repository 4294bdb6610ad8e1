// Step 7, tuning: the analysis of move tests on synthetic records (the
// CSV format, saturation, the recommendation rule), the state and the
// configuration writer's use of the recommendation. The tests on a
// controller are in tuning_e2e_test.cpp (label slow).
#include <gtest/gtest.h>

#include <cmath>

#include "commission/config_writer.hpp"
#include "commission/steps.hpp"
#include "commission/tuning.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

// A back-and-forth-like record: the command accelerates at `acc` to `v`,
// cruises, brakes; the feedback lags `lag` seconds (ferror = lag x
// velocity); the torque is `torque_per_acc` x acceleration plus friction.
std::vector<TuningSample> synthetic(double v, double acc, double lag, double torque_per_acc, double period = 1e-3) {
  std::vector<TuningSample> out;
  double x = 0, vel = 0;
  const double t_acc = v / acc, t_cruise = 0.1;
  const double total = 2 * t_acc + t_cruise + 0.05;
  for (double t = 0; t < total; t += period) {
    double a = 0;
    if (t < t_acc) a = acc;
    else if (t < t_acc + t_cruise) a = 0;
    else if (t < 2 * t_acc + t_cruise) a = -acc;
    vel = std::max(0.0, vel + a * period);
    x += vel * period;
    TuningSample s;
    s.time_s = t;
    s.command_mm = x;
    s.vel_cmd_mm_s = vel;
    s.ferror_mm = lag * vel + 0.0005;
    s.feedback_mm = x - s.ferror_mm;
    s.velocity_mm_s = vel;
    s.torque_pct = torque_per_acc * a + (vel > 0 ? 5 : 0);
    out.push_back(s);
  }
  return out;
}

TuningTest analysed(const std::string& series, double v, double acc, const std::vector<TuningSample>& r,
                    double reference = 0) {
  TuningTest t;
  t.series = series;
  t.velocity = v;
  t.acceleration = acc;
  t.jerk = acc * 250;
  analyse_test(t, r, SaturationRule{}, reference);
  return t;
}

TEST(TuningCsv, HasTheWizardsColumnsOneRowPerCycleAndReadsBack) {
  const auto r = synthetic(100, 2000, 0.002, 0.01);
  const std::string text = tuning_csv(r);
  EXPECT_EQ(text.substr(0, text.find('\n')), "time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct");
  const auto back = parse_tuning_csv(text, "x.csv");
  ASSERT_EQ(back.size(), r.size());
  for (std::size_t i = 0; i < r.size(); i += 17) {
    EXPECT_NEAR(back[i].time_s, r[i].time_s, 1e-6);
    EXPECT_NEAR(back[i].command_mm, r[i].command_mm, 1e-6);
    EXPECT_NEAR(back[i].feedback_mm, r[i].feedback_mm, 1e-6);
    EXPECT_NEAR(back[i].ferror_mm, r[i].ferror_mm, 1e-6);
    EXPECT_NEAR(back[i].velocity_mm_s, r[i].velocity_mm_s, 1e-4);
    EXPECT_NEAR(back[i].torque_pct, r[i].torque_pct, 0.01);
  }
}

TEST(TuningCsv, ABadValueNamesTheFileLineAndColumn) {
  try {
    parse_tuning_csv("time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct\n0,1,1,0,0,0\n0.001,1,x,0,0,0\n",
                     "x-01.csv");
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("x-01.csv:3: column feedback_mm"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_tuning_csv("time_s,command_mm\n", "y.csv"), std::runtime_error);
}

TEST(TuningScopeCsv, TakesThePinsInOrderAndBitElevenOfTheStatuswordAsTheLimit) {
  const auto pins = tuning_scope_pins(2, 2);
  ASSERT_EQ(pins.size(), 7u);
  EXPECT_EQ(pins[0], "joint.2.motor-pos-cmd");
  EXPECT_EQ(pins[4], "cia402.0.drive.02.torque");
  EXPECT_EQ(pins[6], "cia402.0.drive.02.statusword");
  std::string text = "time_s";
  for (const auto& p : pins) text += "," + p;
  text += "\n0.000000,1,0.9,0.1,50,20,51,4663\n0.001000,1.05,0.95,0.1,50,20,51,6711\n";  // 0x1237, 0x1A37
  const auto r = parse_scope_csv(text);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_FALSE(r[0].limit);
  EXPECT_TRUE(r[1].limit);
  EXPECT_DOUBLE_EQ(r[1].vel_cmd_mm_s, 51);
  EXPECT_DOUBLE_EQ(r[1].torque_pct, 20);
}

TEST(TuningScopeCsv, AGantryCaptureHoldsBothSidesPinsOneAfterTheOther) {
  std::string text = "time_s";
  for (int j : {1, 2})
    for (const auto& p : tuning_scope_pins(j, j)) text += "," + p;
  text += "\n0.000000,1,0.9,0.1,50,20,51,4663,1,0.8,0.2,49,35,51,6711\n";
  const auto r = parse_scope_csv_sides(text, 2);
  ASSERT_EQ(r.size(), 2u);
  ASSERT_EQ(r[1].size(), 1u);
  EXPECT_DOUBLE_EQ(r[0][0].ferror_mm, 0.1);
  EXPECT_DOUBLE_EQ(r[1][0].ferror_mm, 0.2);
  EXPECT_DOUBLE_EQ(r[1][0].torque_pct, 35);
  EXPECT_FALSE(r[0][0].limit);
  EXPECT_TRUE(r[1][0].limit);
  // One side's capture read as two, or two as one: the header says so.
  EXPECT_THROW(parse_scope_csv(text), std::runtime_error);
}

TEST(TuningAnalysis, AGantryTestIsTheWorseOfItsTwoSides) {
  TuningTest a, b;
  a.series = b.series = "velocity";
  a.velocity = b.velocity = 100;
  a.max_ferror = 0.05, b.max_ferror = 0.08;
  a.max_torque = 120, b.max_torque = 90;
  a.ferror_per_velocity = 0.001, b.ferror_per_velocity = 0.0012;
  a.reached_velocity = 100, b.reached_velocity = 99.5;
  a.csv = "y-01.csv", b.csv = "y-01-second-drive.csv";
  TuningTest w = worse_side(a, b);
  EXPECT_FALSE(w.saturated);
  EXPECT_DOUBLE_EQ(w.max_ferror, 0.08);
  EXPECT_DOUBLE_EQ(w.max_torque, 120);
  EXPECT_DOUBLE_EQ(w.ferror_per_velocity, 0.0012);
  EXPECT_DOUBLE_EQ(w.reached_velocity, 99.5);
  EXPECT_EQ(w.csv, "y-01.csv");
  b.saturated = true;
  b.finding = "torque 280 % reached 90 % of the drive's limit";
  w = worse_side(a, b);
  EXPECT_TRUE(w.saturated);
  EXPECT_EQ(w.finding, "the gantry's second drive: torque 280 % reached 90 % of the drive's limit");
  EXPECT_EQ(w.csv, "y-01-second-drive.csv");
  // The recommendation of a pair comes from its merged tests: the first
  // side clean alone would allow 100 mm/s, the pair does not.
  EXPECT_THROW(recommend_tuning({w}, 20, 1000), std::invalid_argument);
}

TEST(TuningAnalysis, AProportionalLagWithTorqueInReachIsClean) {
  const TuningTest slow = analysed("velocity", 50, 1000, synthetic(50, 1000, 0.002, 0.02));
  EXPECT_FALSE(slow.saturated) << slow.finding;
  EXPECT_NEAR(slow.reached_velocity, 50, 1);
  EXPECT_NEAR(slow.reached_acceleration, 1000, 1);
  EXPECT_NEAR(slow.ferror_per_velocity, 0.002, 0.0002);
  const TuningTest fast = analysed("velocity", 200, 1000, synthetic(200, 1000, 0.002, 0.02), slow.ferror_per_velocity);
  EXPECT_FALSE(fast.saturated) << fast.finding;
  EXPECT_NEAR(fast.max_ferror, 0.4005, 0.002);
}

TEST(TuningAnalysis, TorqueNearTheDrivesLimitIsSaturation) {
  // 0.1 %/(mm/s2) at 2800 mm/s2: 280 % + friction, above 90 % of 300 %.
  const TuningTest t = analysed("acceleration", 100, 2800, synthetic(100, 2800, 0.002, 0.1));
  EXPECT_TRUE(t.saturated);
  EXPECT_NE(t.finding.find("torque"), std::string::npos) << t.finding;
  const TuningTest ok = analysed("acceleration", 100, 2000, synthetic(100, 2000, 0.002, 0.1));
  EXPECT_FALSE(ok.saturated) << ok.finding;
}

TEST(TuningAnalysis, TheDrivesLimitBitInTenCyclesIsSaturationInNineItIsNot) {
  auto r = synthetic(100, 1000, 0.002, 0.02);
  for (int i = 0; i < 9; ++i) r[static_cast<std::size_t>(10 + 3 * i)].limit = true;
  EXPECT_FALSE(analysed("velocity", 100, 1000, r).saturated);
  r[60].limit = true;
  const TuningTest t = analysed("velocity", 100, 1000, r);
  EXPECT_TRUE(t.saturated);
  EXPECT_EQ(t.limit_cycles, 10);
  EXPECT_NE(t.finding.find("bit 11"), std::string::npos) << t.finding;
}

TEST(TuningAnalysis, AFollowingErrorGrowingOutOfProportionWithVelocityIsSaturation) {
  // The first test lags 2 ms; one lagging 5 ms (a drive cut to its speed
  // limit falls behind) is saturated, one lagging 3 ms is not.
  EXPECT_TRUE(analysed("velocity", 300, 1000, synthetic(300, 1000, 0.005, 0.02), 0.002).saturated);
  EXPECT_FALSE(analysed("velocity", 300, 1000, synthetic(300, 1000, 0.003, 0.02), 0.002).saturated);
  // Tiny errors of slow tests (quantisation) do not count.
  EXPECT_FALSE(analysed("velocity", 2, 1000, synthetic(2, 1000, 0.005, 0.02), 0.002).saturated);
}

TEST(TuningRecommendation, IsTheHighestCleanTestLessTheMargin) {
  std::vector<TuningTest> tests;
  double ref = 0;
  for (double v : {50.0, 100.0, 200.0}) {
    tests.push_back(analysed("velocity", v, 1000, synthetic(v, 1000, 0.002, 0.02), ref));
    ref = tests.front().ferror_per_velocity;
  }
  tests.push_back(analysed("velocity", 400, 1000, synthetic(400, 1000, 0.006, 0.02), ref));  // saturated
  ASSERT_TRUE(tests.back().saturated);
  for (double a : {2000.0, 2500.0})
    tests.push_back(analysed("acceleration", 200, a, synthetic(200, a, 0.002, 0.1), ref));
  tests.push_back(analysed("acceleration", 200, 3000, synthetic(200, 3000, 0.002, 0.1), ref));  // torque
  ASSERT_TRUE(tests.back().saturated);
  const AxisTuning r = recommend_tuning(tests, 20, 1000);
  EXPECT_NEAR(r.max_velocity, 0.8 * 200, 1.0);
  EXPECT_NEAR(r.max_acceleration, 0.8 * 2500, 1.0);
  EXPECT_NEAR(r.max_jerk, 0.8 * 2500 * 250, 1.0);
  EXPECT_EQ(r.margin_pct, 20);
  EXPECT_NE(r.velocity_limit.find("saturation at 400 mm/s"), std::string::npos) << r.velocity_limit;
  EXPECT_NE(r.acceleration_limit.find("torque"), std::string::npos) << r.acceleration_limit;
  // FERROR: twice the lag (2 ms) at the joint's MAX_VELOCITY (1.05 x 160);
  // MIN_FERROR: twice the low-speed error and what braking at the joint's
  // MAX_ACCELERATION (1.1 x 2000) adds within one lag.
  EXPECT_NEAR(r.ferror, 2 * 0.002 * 1.05 * r.max_velocity, 0.02);
  EXPECT_GE(r.min_ferror, 0.05);
  EXPECT_GE(r.min_ferror, 2 * 0.002 * 0.002 * 1.1 * r.max_acceleration);
  EXPECT_LE(r.min_ferror, r.ferror);
  EXPECT_EQ(r.tests.size(), tests.size());
}

TEST(TuningRecommendation, NeverBelowTenEncoderCountsAndRefusedWithoutACleanTest) {
  std::vector<TuningTest> tests{analysed("velocity", 10, 100, synthetic(10, 100, 0.0, 0.02))};
  EXPECT_NEAR(recommend_tuning(tests, 20, 100).min_ferror, 10.0 / 100, 1e-9);  // 100 counts/mm: 0.1 mm
  EXPECT_NEAR(recommend_tuning(tests, 20, 1e6).min_ferror, 0.05, 1e-9);
  tests[0].saturated = true;
  tests[0].finding = "torque 290 % reached 90 % of the drive's limit";
  try {
    recommend_tuning(tests, 20, 1000);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("torque 290 %"), std::string::npos) << e.what();
  }
  EXPECT_THROW(recommend_tuning({}, 20, 1000), std::invalid_argument);
}

State machine() {
  State s;
  s.interface = "virtual:t";
  ScannedNode n;
  n.node_id = 1;
  n.cia402 = true;
  n.encoder_increments = 10000;
  s.nodes.push_back(n);
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5);
  return s;
}

AxisTuning some_tuning() {
  AxisTuning t;
  t.tests.push_back(analysed("velocity", 50, 1000, synthetic(50, 1000, 0.002, 0.02)));
  t.tests.back().csv = "tuning-x/x-01-velocity-v50-a1000.csv";
  t.margin_pct = 25;
  t.max_velocity = 123.5;
  t.max_acceleration = 4321;
  t.max_jerk = 987654;
  t.ferror = 0.75;
  t.min_ferror = 0.05;
  t.velocity_limit = "saturation at 200 mm/s";
  t.acceleration_limit = "no saturation up to the highest test (5000 mm/s2)";
  return t;
}

TEST(TuningState, IsKeptInTheStateFile) {
  State s = machine();
  s.axis('X')->tuning = some_tuning();
  const State back = from_json_text(to_json_text(s), "state.json");
  ASSERT_TRUE(back.axis('X')->tuning.has_value());
  const AxisTuning& t = *back.axis('X')->tuning;
  EXPECT_EQ(t.max_velocity, 123.5);
  EXPECT_EQ(t.max_jerk, 987654);
  EXPECT_EQ(t.min_ferror, 0.05);
  EXPECT_EQ(t.velocity_limit, "saturation at 200 mm/s");
  ASSERT_EQ(t.tests.size(), 1u);
  EXPECT_EQ(t.tests[0].csv, "tuning-x/x-01-velocity-v50-a1000.csv");
  EXPECT_EQ(t.tests[0].series, "velocity");
  EXPECT_DOUBLE_EQ(t.tests[0].ferror_per_velocity, s.axis('X')->tuning->tests[0].ferror_per_velocity);
}

TEST(TuningWriter, JointAndAxisLimitsAreTheRecommendationAndTheScopeAndTorqueAreRecorded) {
  testing::TempDir dir;
  State s = machine();
  s.axis('X')->tuning = some_tuning();
  const std::string ini = generate_config(s, dir.path(), "m").at(0).content;
  const std::string hal = generate_config(s, dir.path(), "m").at(1).content;
  EXPECT_NE(ini.find("[AXIS_X]\nMIN_LIMIT = -10\nMAX_LIMIT = 10\nMAX_VELOCITY = 123.5\nMAX_ACCELERATION = 4321\nMAX_JERK = 987654\n"),
            std::string::npos) << ini;
  EXPECT_NE(ini.find("MAX_VELOCITY = 129.675\nMAX_ACCELERATION = 4753.1\nMAX_JERK = 1086419.4\nFERROR = 0.75\nMIN_FERROR = 0.05\n"),
            std::string::npos) << ini;
  EXPECT_NE(ini.find("MAX_LINEAR_VELOCITY = 123.5\nMAX_LINEAR_ACCELERATION = 4321\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("TPDO1 = 0x6041:0:u16 0x6064:0:s32 0x6077:0:s16\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("QUICK_STOP_DECEL = 5761.333333\n"), std::string::npos) << ini;  // 4321 / (1 - 25 %)
  EXPECT_NE(hal.find("loadrt scope samples=60000\naddf scope.sample servo-thread\n"), std::string::npos) << hal;
}

TEST(TuningWriter, TheTuningConfigurationHasTheCeilingsAndAWideFollowingErrorLimit) {
  State s = machine();
  s.axis('X')->max_velocity = 10;
  TuneOptions o;
  o.max_velocity = 400;
  o.max_acceleration = 8000;
  const State t = tuning_configuration(s, 'X', o);
  ASSERT_TRUE(t.axis('X')->tuning.has_value());
  EXPECT_EQ(t.axis('X')->tuning->max_velocity, 400);
  EXPECT_EQ(t.axis('X')->tuning->max_acceleration, 8000);
  EXPECT_GE(t.axis('X')->tuning->ferror, 400 * 4 * 1e-3);
  EXPECT_FALSE(s.axis('X')->tuning.has_value());  // the state itself is unchanged
  EXPECT_THROW(tuning_configuration(s, 'Y', o), std::invalid_argument);
}

}  // namespace
}  // namespace cnc::commission
