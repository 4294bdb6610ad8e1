// Step 9's check program (commission/check.hpp), the state's check block,
// and the travel the motion steps may use (known_travel: tune and the
// compensation cycle stay inside the soft limits and the switches found).
#include <gtest/gtest.h>

#include <sstream>

#include "commission/check.hpp"
#include "commission/compensation.hpp"
#include "commission/config_writer.hpp"
#include "commission/steps.hpp"
#include "commission/tuning.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

State two_axes() {
  State s;
  s.interface = "virtual:check";
  for (int id : {1, 2}) {
    ScannedNode n;
    n.node_id = id;
    n.cia402 = true;
    n.encoder_increments = 10000;
    s.nodes.push_back(n);
  }
  assign_axis(s, 'X', 0, 1);
  assign_axis(s, 'Z', 1, 2);
  set_scaling(s, 'X', 5);
  set_scaling(s, 'Z', 5);
  Axis& x = *s.axis('X');
  x.min_limit = -20;
  x.max_limit = 200;
  x.max_velocity = 30;
  Axis& z = *s.axis('Z');
  z.min_limit = -60;
  z.max_limit = 25;
  z.max_velocity = 100;
  AxisHoming h;
  h.method = "controller";
  h.home = 20;
  z.homing = h;
  return s;
}

std::vector<std::string> motion_lines(const std::string& program) {
  std::vector<std::string> out;
  std::istringstream in(program);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("G53 ", 0) == 0) out.push_back(line);
  return out;
}

TEST(CommissionCheck, TheProgramMovesEachAxisALittleInsideItsSoftLimitsAndBackToItsHomeAtReducedFeed) {
  const std::string p = check_program(two_axes());
  // X: 5 % of 220 mm is 11 mm, at most 5 mm inside; a quarter of 30 mm/s.
  // Z: 4.25 mm inside; a quarter of 100 mm/s is above the 20 mm/s cap;
  // back to the HOME homing leaves it at.
  const std::vector<std::string> want = {"G53 G1 X-15 F450", "G53 G1 X195", "G53 G1 X0",
                                         "G53 G1 Z-55.75 F1200", "G53 G1 Z20.75", "G53 G1 Z20"};
  EXPECT_EQ(motion_lines(p), want) << p;
  EXPECT_NE(p.find("\nM2\n"), std::string::npos) << p;
  const auto end = declared_end(p, "check.ngc");
  ASSERT_EQ(end.size(), 2u) << p;
  EXPECT_EQ(end[0], std::make_pair('X', 0.0));
  EXPECT_EQ(end[1], std::make_pair('Z', 20.0));
}

TEST(CommissionCheck, TheProgramStaysShortOfALimitSwitchFoundInsideTheSoftLimits) {
  State s = two_axes();
  AxisSwitches w;
  w.neg_limit.seen = true;
  w.neg_limit.position = -12;  // inside the soft limit -20
  s.axis('X')->switches = w;
  EXPECT_EQ(motion_lines(check_program(s)).at(0), "G53 G1 X-5 F450");  // -12 + 2 clearance + 5 inset
}

TEST(CommissionCheck, TheFeedFollowsTheTunedVelocity) {
  State s = two_axes();
  AxisTuning t;
  t.max_velocity = 40;
  t.max_acceleration = 500;
  s.axis('X')->tuning = t;
  EXPECT_DOUBLE_EQ(check_feed(*s.axis('X')), 10.0);
  EXPECT_EQ(motion_lines(check_program(s)).at(0), "G53 G1 X-15 F600");
}

// The program's length at its feeds, which bounds the check's time limit:
// a tuning that lowers an axis' velocity lengthens it.
TEST(CommissionCheck, TheProgramsLengthIsItsMovesAtTheirFeeds) {
  State s = two_axes();
  // X: 0 -> -15 -> 195 -> 0, 420 mm at 7.5 mm/s; Z: 20 -> -55.75 -> 20.75
  // -> 20, 153 mm at 20 mm/s.
  EXPECT_NEAR(check_program_seconds(s), 420 / 7.5 + 153 / 20.0, 1e-9);
  AxisTuning t;
  t.max_velocity = 8;  // a tuning that stopped low: 2 mm/s
  t.max_acceleration = 500;
  s.axis('X')->tuning = t;
  EXPECT_NEAR(check_program_seconds(s), 420 / 2.0 + 153 / 20.0, 1e-9);
  EXPECT_DOUBLE_EQ(check_default_timeout_s(check_program_seconds(s)), 600);  // at least 600 s
  s.axis('X')->tuning->max_velocity = 2;  // 0.5 mm/s: 840 s of X
  EXPECT_NEAR(check_default_timeout_s(check_program_seconds(s)), 2 * (840 + 7.65) + 60, 1e-6);
}

TEST(CommissionCheck, AnAxisWithoutTravelIsRefusedNamingIt) {
  State s = two_axes();
  s.axis('Z')->min_limit = 0;
  s.axis('Z')->max_limit = 0.8;
  try {
    (void)check_program(s);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis Z"), std::string::npos) << e.what();
  }
}

TEST(CommissionCheck, TheDeclaredEndIsReadFromItsCommentAndAMalformedOneNamesFileAndLine) {
  EXPECT_TRUE(declared_end("G0 X1\nM2\n", "p.ngc").empty());
  const auto e = declared_end("(my program)\n(cnc-commission end X10 y-2.5)\nG0 X10\n", "p.ngc");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(e[1], std::make_pair('Y', -2.5));
  for (const char* bad : {"(cnc-commission end X1 Q2)\n", "(cnc-commission end Xabc)\n", "(cnc-commission end X1\n",
                          "(cnc-commission end)\n"}) {
    try {
      (void)declared_end(std::string("G0 X0\n") + bad, "p.ngc");
      ADD_FAILURE() << bad << ": no error";
    } catch (const std::invalid_argument& ex) {
      EXPECT_NE(std::string(ex.what()).find("p.ngc:2:"), std::string::npos) << ex.what();
    }
  }
}

TEST(CommissionCheck, TheWriterWritesTheCheckProgramBesideTheIni) {
  testing::TempDir dir;
  const State s = two_axes();
  const auto files = generate_config(s, dir.path(), "m");
  bool found = false;
  for (const auto& f : files)
    if (f.path == dir / "check.ngc") {
      found = true;
      EXPECT_EQ(f.content, check_program(s));
    }
  EXPECT_TRUE(found);
}

TEST(CommissionCheck, TheCheckBlockTheWrittenIniAndTheLimitsSourceSurviveASaveAndLoad) {
  testing::TempDir dir;
  State s = two_axes();
  s.axis('X')->limits_source = "switches";
  s.config_ini = "/m/mill.ini";
  CheckRun r;
  r.program = "/m/check.ngc";
  r.ini = "/m/mill.ini";
  r.passed = true;
  r.message = "the program ran to its end";
  r.duration_s = 42.5;
  r.time = "2026-11-27T10:00:00Z";
  s.check = r;
  save_state(s, dir / "s.json");
  const State l = load_state(dir / "s.json");
  EXPECT_EQ(l.config_ini, "/m/mill.ini");
  ASSERT_TRUE(l.check.has_value());
  EXPECT_EQ(l.check->program, "/m/check.ngc");
  EXPECT_EQ(l.check->ini, "/m/mill.ini");
  EXPECT_TRUE(l.check->passed);
  EXPECT_EQ(l.check->message, r.message);
  EXPECT_DOUBLE_EQ(l.check->duration_s, 42.5);
  EXPECT_EQ(l.check->time, r.time);
  EXPECT_EQ(l.axis('X')->limits_source, "switches");
  EXPECT_EQ(l.axis('Z')->limits_source, "");
}

TEST(CommissionCheck, AnUnknownLimitsSourceIsRefusedAndAnOldFileWithLimitsGivenCountsAsEntered) {
  EXPECT_THROW((void)from_json_text(R"({"version": 1, "axes": [{"letter": "X", "limits_source": "guess"}]})", "s.json"),
               std::runtime_error);
  const State s = from_json_text(R"({"version": 1, "axes": [{"letter": "X", "min_limit": -5, "max_limit": 100},
                                                            {"letter": "Y"}]})", "s.json");
  EXPECT_EQ(s.axis('X')->limits_source, "entered");
  EXPECT_EQ(s.axis('Y')->limits_source, "");
}

// --- the travel of the motion steps ---

Axis with_switches(double neg, double pos) {
  Axis a;
  a.letter = 'Y';
  AxisSwitches w;
  w.neg_limit.seen = true;
  w.neg_limit.position = neg;
  w.pos_limit.seen = true;
  w.pos_limit.position = pos;
  a.switches = w;
  return a;
}

TEST(CommissionTravel, NeitherLimitsNorSwitchesKnownIsRefusedSayingWhatToDo) {
  Axis a;
  a.letter = 'Y';
  try {
    (void)known_travel(a);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("axis Y: the travel is not known"), std::string::npos) << m;
    EXPECT_NE(m.find("axis Y switches"), std::string::npos) << m;
    EXPECT_NE(m.find("axis Y limits --min MM --max MM"), std::string::npos) << m;
  }
}

TEST(CommissionTravel, EnteredLimitsAreUsedAsGivenWhileNoSwitchIsKnown) {
  Axis a;
  a.min_limit = -10;
  a.max_limit = 250;
  a.limits_source = "entered";
  const Travel t = known_travel(a);
  EXPECT_EQ(t.min, -10);
  EXPECT_EQ(t.max, 250);
}

TEST(CommissionTravel, LimitsReachingPastTheSwitchesFoundStopShortOfThem) {
  Axis a = with_switches(-29.5, 133.0);
  a.min_limit = -10;
  a.max_limit = 150;  // past the positive switch
  a.limits_source = "entered";
  const Travel t = known_travel(a);
  EXPECT_EQ(t.min, -10);
  EXPECT_DOUBLE_EQ(t.max, 133.0 - kSwitchClearance);
  EXPECT_NE(t.source.find("below the positive limit switch at 133.000 mm"), std::string::npos) << t.source;
}

TEST(CommissionTravel, TheSwitchesAloneGiveTheTravelWhenNoLimitsWereGiven) {
  const Travel t = known_travel(with_switches(-29.5, 133.0));
  EXPECT_DOUBLE_EQ(t.min, -29.5 + kSwitchClearance);
  EXPECT_DOUBLE_EQ(t.max, 133.0 - kSwitchClearance);
}

TEST(CommissionTravel, TuningRefusesToMoveWhenTheTravelIsNotKnown) {
  Axis a;
  a.letter = 'Y';
  a.scaling.encoder_counts = 10000;
  a.scaling.screw_lead = 5;
  TuneOptions o;
  // The controller is never reached: the refusal comes first.
  try {
    (void)run_tuning(Controller("/nonexistent"), a, o);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("the travel is not known"), std::string::npos) << e.what();
  }
}

TEST(CommissionTravel, TheCompensationCycleStaysShortOfTheSwitchesFound) {
  Axis a = with_switches(-29.5, 133.0);
  a.min_limit = -10;
  a.max_limit = 250;
  a.limits_source = "entered";
  a.max_velocity = 30;
  const AxisCompensation c = default_compensation(a);
  EXPECT_LE(c.x_max + c.overshoot_mm, 133.0 - kSwitchClearance);
  EXPECT_NO_THROW(check_cycle(a, c));
  AxisCompensation wide = c;
  wide.x_max = 200;
  EXPECT_THROW(check_cycle(a, wide), std::invalid_argument);
  Axis unknown;
  unknown.max_velocity = 30;
  EXPECT_THROW(check_cycle(unknown, default_compensation(unknown)), std::invalid_argument);
}

}  // namespace
}  // namespace cnc::commission

namespace cnc::commission {
namespace {

// The direction test's first jog is short until a dial reading checked the scaling.
TEST(CommissionDirectionTravel, TheFirstTestIsShortUntilADialReadingCheckedTheScalingAndANewScalingStartsOver) {
  State s = two_axes();
  const Axis& x = *s.axis('X');
  EXPECT_EQ(direction_test_travel_limit(x), kFirstTestTravel);
  apply_direction_test(s, 'X', 2, 2, 2.0, false);  // no dial: nothing checked
  EXPECT_EQ(direction_test_travel_limit(x), kFirstTestTravel);
  apply_direction_test(s, 'X', 2, 2, 12.0, true);  // the table moved 6x the command
  EXPECT_TRUE(x.scaling.dial_checked);
  EXPECT_EQ(direction_test_travel_limit(x), kMaxTestTravel);
  apply_direction_test(s, 'X', 10, 10, 10.0, false);  // a later test without dial keeps the check
  EXPECT_EQ(direction_test_travel_limit(x), kMaxTestTravel);
  testing::TempDir dir;
  save_state(s, dir / "s.json");
  EXPECT_TRUE(load_state(dir / "s.json").axis('X')->scaling.dial_checked);
  set_scaling(s, 'X', 10);  // a new nominal scaling: unchecked again
  EXPECT_EQ(direction_test_travel_limit(x), kFirstTestTravel);
}

}  // namespace
}  // namespace cnc::commission
