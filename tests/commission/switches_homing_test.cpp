// Steps 5 and 6 of commissioning without a machine: the analysis of a
// switch search (edges, active level, switches that never change), soft
// limits from the switches, the homing methods and plan, the spread, the
// state's JSON and what the configuration writer makes of them.
#include <gtest/gtest.h>

#include "commission/config_writer.hpp"
#include "commission/homing_check.hpp"
#include "commission/steps.hpp"
#include "commission/switches.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

// A search leg from `from` by `step` per poll, `n` polls; the inputs as
// functions of the position.
template <class Neg, class Pos, class Home>
std::vector<SwitchSample> leg(double from, double step, int n, Neg neg, Pos pos, Home home) {
  std::vector<SwitchSample> v;
  for (int i = 0; i <= n; ++i) {
    const double x = from + step * i;
    v.push_back({x, neg(x), pos(x), home(x)});
  }
  return v;
}

// Limits at -20 and +100, home switch active in [-15, -10]; `low` inverts
// all three inputs (normally closed switches).
std::pair<std::vector<SwitchSample>, std::vector<SwitchSample>> search(bool low, double step = 0.1) {
  auto neg = [low](double x) { return (x <= -20) != low; };
  auto pos = [low](double x) { return (x >= 100) != low; };
  auto home = [low](double x) { return (x >= -15 && x <= -10) != low; };
  // Each leg stops a poll after its limit changed, as the search does.
  return {leg(0, -step, static_cast<int>(20 / step) + 1, neg, pos, home),
          leg(0, step, static_cast<int>(100 / step) + 1, neg, pos, home)};
}

TEST(CommissionSwitches, FindsEachSwitchEdgeAndItsActiveLevel) {
  for (bool low : {false, true}) {
    const auto [n, p] = search(low);
    const AxisSwitches r = analyse_switch_search('X', n, p, 150, 5, "cia402.0.drive.00.");
    EXPECT_TRUE(r.problems.empty()) << r.problems.front();
    EXPECT_TRUE(r.neg_limit.seen);
    EXPECT_NEAR(r.neg_limit.position, -20, 0.1);
    EXPECT_TRUE(r.pos_limit.seen);
    EXPECT_NEAR(r.pos_limit.position, 100, 0.1);
    EXPECT_TRUE(r.home.seen);
    EXPECT_NEAR(r.home.position, -15, 0.1);
    ASSERT_TRUE(r.home.has_high);
    EXPECT_NEAR(r.home.position_high, -10, 0.1);
    EXPECT_EQ(r.neg_limit.active_high, !low);
    EXPECT_EQ(r.pos_limit.active_high, !low);
    EXPECT_EQ(r.home.active_high, !low);
    EXPECT_EQ(r.neg_limit.pin, "cia402.0.drive.00.neg-lim-sw");
  }
}

TEST(CommissionSwitches, PlacesAnEdgeHalfwayBetweenThePollsAroundIt) {
  std::vector<SwitchSample> s = {{0, false, false, false}, {-1, false, false, false}, {-2, true, false, false}};
  double at = 0;
  ASSERT_TRUE(first_change(s, &SwitchSample::neg, at));
  EXPECT_DOUBLE_EQ(at, -1.5);
  EXPECT_FALSE(first_change(s, &SwitchSample::pos, at));
}

TEST(CommissionSwitches, ASwitchThatNeverChangesIsAProblemNamingItAndWhatToCheck) {
  auto never = [](double) { return false; };
  auto neg = [](double x) { return x <= -20; };
  auto home = [](double x) { return x >= -15 && x <= -10; };
  const auto n = leg(0, -0.5, 41, neg, never, home);
  const auto p = leg(0, 0.5, 100, neg, never, home);  // 50 mm searched, no positive limit
  const AxisSwitches r = analyse_switch_search('Y', n, p, 50, 5, "cia402.0.drive.01.");
  EXPECT_FALSE(r.pos_limit.seen);
  ASSERT_EQ(r.problems.size(), 1u);
  const std::string& m = r.problems[0];
  EXPECT_NE(m.find("axis Y"), std::string::npos) << m;
  EXPECT_NE(m.find("positive limit switch never changed"), std::string::npos) << m;
  EXPECT_NE(m.find("cia402.0.drive.01.pos-lim-sw"), std::string::npos) << m;
  EXPECT_NE(m.find("wiring"), std::string::npos) << m;
  EXPECT_NE(m.find("polarity"), std::string::npos) << m;
  EXPECT_NE(m.find("0x60FD bit 1"), std::string::npos) << m;
}

TEST(CommissionSwitches, ALimitChangingOnTheWayToTheOtherEndIsAProblem) {
  // The limit inputs swapped: "neg" changes at the + end.
  auto neg = [](double x) { return x >= 100; };
  auto pos = [](double x) { return x <= -20; };
  auto home = [](double x) { return x >= -15 && x <= -10; };
  const auto n = leg(0, -0.5, 41, neg, pos, home);
  const auto p = leg(0, 0.5, 201, neg, pos, home);
  const AxisSwitches r = analyse_switch_search('X', n, p, 150, 5, "d.");
  ASSERT_FALSE(r.problems.empty());
  bool swapped = false;
  for (const auto& m : r.problems) swapped = swapped || m.find("swapped") != std::string::npos;
  EXPECT_TRUE(swapped);
}

TEST(CommissionSwitches, HomeSwitchToTheEndOfTravelHasOneEdgeAndTheShorterLevelIsActive) {
  auto neg = [](double x) { return x <= -20; };
  auto pos = [](double x) { return x >= 100; };
  auto home = [](double x) { return x >= 90; };  // a cam from 90 to the end
  const auto n = leg(0, -0.5, 41, neg, pos, home);
  const auto p = leg(0, 0.5, 201, neg, pos, home);
  const AxisSwitches r = analyse_switch_search('X', n, p, 150, 5, "d.");
  EXPECT_TRUE(r.home.seen);
  EXPECT_TRUE(r.home.active_high);
  EXPECT_FALSE(r.home.has_high);
  EXPECT_NEAR(r.home.position, 90, 0.5);
}

Axis axis_with_switches() {
  Axis a;
  a.letter = 'X';
  const auto [n, p] = search(false);
  a.switches = analyse_switch_search('X', n, p, 150, 5, "cia402.0.drive.00.");
  return a;
}

TEST(CommissionSwitches, TheLatchedEdgeReplacesThePollsHalfwayWhenItIsTheOnlyOneOfItsKind) {
  // Polls 2 mm apart (a slow host at 10 mm/s); the latch saw the home
  // switch's upper edge (rising going down, active high) at -10.004.
  const auto [n, p] = search(false, 2.0);
  const AxisSwitches r = analyse_switch_search('X', n, p, 150, 10, "cia402.0.drive.00.");
  double upper = r.home.position_high;
  EXPECT_NEAR(upper, -9.0, 1e-9) << "halfway between the polls at -8 and -10";
  LatchedEdges home;
  home.rises = 1;
  home.rise_position = -10.004;
  home.falls = 1;
  home.fall_position = -14.996;
  ASSERT_TRUE(latched_change(n, &SwitchSample::home, home, upper));
  EXPECT_DOUBLE_EQ(upper, -10.004);
  double lower = r.home.position;
  ASSERT_TRUE(latched_change(n, &SwitchSample::home, home, lower));
  EXPECT_DOUBLE_EQ(lower, -14.996) << "the lower edge falls going down";
  // The other leg never crossed the home switch: nothing to take from it.
  double other = r.home.position;
  EXPECT_FALSE(latched_change(p, &SwitchSample::home, home, other));
  EXPECT_EQ(other, r.home.position);
}

TEST(CommissionSwitches, ALatchThatSawTwoEdgesOfAKindOrOneOutsideThePollsIsNotUsed) {
  const auto [n, p] = search(true, 2.0);  // active low: the limit falls when reached
  const AxisSwitches r = analyse_switch_search('X', n, p, 150, 10, "cia402.0.drive.00.");
  LatchedEdges neg;
  neg.falls = 2;  // a bounce
  neg.fall_position = -20.001;
  double at = r.neg_limit.position;
  EXPECT_FALSE(latched_change(n, &SwitchSample::neg, neg, at));
  EXPECT_EQ(at, r.neg_limit.position);
  neg.falls = 1;
  neg.fall_position = -25.0;  // not between the polls around the change (-18 and -20)
  EXPECT_FALSE(latched_change(n, &SwitchSample::neg, neg, at));
  neg.fall_position = -20.001;
  neg.rises = 1;  // a rise is another kind: it does not matter here
  EXPECT_TRUE(latched_change(n, &SwitchSample::neg, neg, at));
  EXPECT_DOUBLE_EQ(at, -20.001);
  LatchedEdges none;
  at = r.neg_limit.position;
  EXPECT_FALSE(latched_change(n, &SwitchSample::neg, none, at)) << "no edge latched";
}

TEST(CommissionSwitches, AnArmedLatchGivesTheFirstChangeOfALegThroughChatterOnTheEdge) {
  // A drive halted at its negative limit switch sits on the edge: the
  // input chatters (two falls, active low), the armed latch kept the first.
  const auto [n, p] = search(true, 2.0);
  const AxisSwitches r = analyse_switch_search('X', n, p, 150, 10, "cia402.0.drive.00.");
  LatchedEdges neg;
  neg.falls = 2;
  neg.rises = 1;
  neg.fall_position = -20.0004;
  neg.changed = true;
  neg.changed_position = -20.0011;
  double at = r.neg_limit.position;
  ASSERT_TRUE(latched_change(n, &SwitchSample::neg, neg, at));
  EXPECT_DOUBLE_EQ(at, -20.0011);
  neg.changed_position = -25.0;  // not between the polls around the change
  at = r.neg_limit.position;
  EXPECT_FALSE(latched_change(n, &SwitchSample::neg, neg, at));
  // Not armed in this leg: two falls are a bounce, the polls' edge stays.
  neg.changed = false;
  neg.changed_position = -20.0011;
  EXPECT_FALSE(latched_change(n, &SwitchSample::neg, neg, at));
  // The home switch's upper edge is not the leg's first change of its
  // input... it is here (the first the leg met): a later edge is not.
  LatchedEdges home;
  home.changed = true;
  home.changed_position = -10.002;
  home.rises = 2;
  home.falls = 2;
  double lower = r.home.position;  // the second change going down
  EXPECT_FALSE(latched_change(n, &SwitchSample::home, home, lower)) << "not the first change, and two of its kind";
}

TEST(CommissionSwitches, LatchDifferencesCountAcrossTheCountersWrap) {
  SwitchLatchReading before, after;
  before.home.rises = 2147483647;
  after.home.rises = -2147483647 - 1;
  after.home.rise_position = 3.5;
  before.neg.falls = 4;
  after.neg.falls = 5;
  const SwitchLatchReading d = latch_difference(before, after);
  EXPECT_EQ(d.home.rises, 1);
  EXPECT_EQ(d.home.rise_position, 3.5);
  EXPECT_EQ(d.neg.falls, 1);
  EXPECT_EQ(d.pos.rises, 0);
}

TEST(CommissionSwitches, SoftLimitsAreTheLimitSwitchesLessTheMargin) {
  Axis a = axis_with_switches();
  soft_limits_from_switches(a, 2);
  EXPECT_NEAR(a.min_limit, -18, 0.1);
  EXPECT_NEAR(a.max_limit, 98, 0.1);
}

TEST(CommissionSwitches, SoftLimitsAreRefusedWithoutBothLimitSwitchesAndTheAxisIsUnchanged) {
  Axis a;
  a.letter = 'Z';
  EXPECT_THROW(soft_limits_from_switches(a, 2), std::invalid_argument);
  a = axis_with_switches();
  a.switches->pos_limit.seen = false;
  try {
    soft_limits_from_switches(a, 2);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("positive limit switch was not found"), std::string::npos) << e.what();
  }
  EXPECT_EQ(a.min_limit, -10);
  EXPECT_EQ(a.max_limit, 10);
  a = axis_with_switches();
  EXPECT_THROW(soft_limits_from_switches(a, 70), std::invalid_argument);  // no travel left
}

TEST(CommissionHoming, SpreadIsMaxMinusMin) {
  EXPECT_DOUBLE_EQ(spread({}), 0);
  EXPECT_DOUBLE_EQ(spread({1.5}), 0);
  EXPECT_NEAR(spread({1.001, 0.999, 1.0005}), 0.002, 1e-12);
}

TEST(CommissionHoming, MethodsListTheControllerAndTheDriveMethods) {
  const auto& m = homing_methods();
  ASSERT_FALSE(m.empty());
  EXPECT_EQ(m.front().id, "controller");
  bool has17 = false;
  for (const auto& x : m) has17 = has17 || x.id == "drive:17";
  EXPECT_TRUE(has17);
  EXPECT_EQ(drive_method("drive:19"), 19);
  EXPECT_EQ(drive_method("controller"), 0);
}

TEST(CommissionHoming, ControllerHomingSearchesTowardsTheHomeSwitchAndLatchesOnItsNearEdge) {
  Axis a = axis_with_switches();
  soft_limits_from_switches(a, 2);
  const AxisHoming h = plan_homing(a, "controller");
  EXPECT_LT(h.search_velocity, 0);  // the switch lies below the start
  EXPECT_GT(h.latch_velocity, 0);   // latch leaving it
  EXPECT_NEAR(h.home_offset, -10, 0.1);  // its upper edge is met first
  EXPECT_NEAR(h.home, -5, 0.1);
}

TEST(CommissionHoming, UnknownMethodOrNoHomeSwitchIsRefusedNamingTheAxis) {
  Axis a = axis_with_switches();
  EXPECT_THROW(plan_homing(a, "drive:99"), std::invalid_argument);
  EXPECT_THROW(plan_homing(a, "sideways"), std::invalid_argument);
  a.switches->home.seen = false;
  try {
    plan_homing(a, "controller");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis X: the home switch was not found"), std::string::npos) << e.what();
  }
}

TEST(CommissionHoming, ADriveMethodLookingOnTheWrongSideIsRefusedNamingTheRightOne) {
  Axis a = axis_with_switches();  // home switch below the start
  EXPECT_NO_THROW(plan_homing(a, "drive:22"));
  try {
    plan_homing(a, "drive:20");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("use drive:22"), std::string::npos) << e.what();
  }
  a.scaling.reverse = true;  // the drive's plus is the table's minus
  EXPECT_NO_THROW(plan_homing(a, "drive:20"));
  try {
    plan_homing(a, "drive:21");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("(the axis is REVERSE): use drive:19"), std::string::npos) << e.what();
  }
  EXPECT_NEAR(plan_homing(a, "drive:17").home_offset, 100, 0.1);  // the drive's negative limit: the table's + one
}

State machine_with_steps56(bool low) {
  State s;
  s.interface = "virtual:w";
  ScannedNode n;
  n.node_id = 1;
  n.cia402 = true;
  n.encoder_increments = 10000;
  s.nodes.push_back(n);
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5);
  Axis& a = *s.axis('X');
  const auto [ng, p] = search(low);
  a.switches = analyse_switch_search('X', ng, p, 150, 5, drive_pin_prefix(a));
  soft_limits_from_switches(a, 2);
  a.homing = plan_homing(a, "controller");
  a.homing->references = {1, 1.001};
  a.homing->spread = 0.001;
  return s;
}

TEST(CommissionSwitches, StateKeepsSwitchesAndHomingThroughJson) {
  const State s = machine_with_steps56(true);
  const State t = from_json_text(to_json_text(s), "t.json");
  const Axis& a = *t.axis('X');
  ASSERT_TRUE(a.switches);
  EXPECT_NEAR(a.switches->neg_limit.position, -20, 0.1);
  EXPECT_FALSE(a.switches->home.active_high);
  EXPECT_TRUE(a.switches->home.has_high);
  ASSERT_TRUE(a.homing);
  EXPECT_EQ(a.homing->method, "controller");
  EXPECT_EQ(a.homing->references.size(), 2u);
  EXPECT_DOUBLE_EQ(a.homing->home_offset, s.axis('X')->homing->home_offset);
  EXPECT_EQ(to_json_text(t), to_json_text(s));
}

TEST(CommissionWriter, WritesSwitchNetsWithTheirPolarityAndTheHomingKeys) {
  testing::TempDir dir;
  for (bool low : {false, true}) {
    const State st = machine_with_steps56(low);
    const auto files = generate_config(st, dir.path(), "m");
    const std::string& ini = files[0].content;
    const std::string& hal = files[1].content;
    EXPECT_NE(ini.find("HOME_SEARCH_VEL = -5\nHOME_LATCH_VEL = 0.5\n"), std::string::npos) << ini;
    char offset[64];
    std::snprintf(offset, sizeof offset, "HOME_OFFSET = %.10g\n", st.axis('X')->homing->home_offset);
    EXPECT_NEAR(st.axis('X')->homing->home_offset, -10, 0.1);
    EXPECT_NE(ini.find(offset), std::string::npos) << ini;
    if (!low) {
      EXPECT_NE(hal.find("net x-neg-lim cia402.0.drive.00.neg-lim-sw => joint.0.neg-lim-sw-in"), std::string::npos) << hal;
      EXPECT_NE(hal.find("net x-home-sw cia402.0.drive.00.home-sw => joint.0.home-sw-in"), std::string::npos) << hal;
      EXPECT_EQ(hal.find("loadrt not"), std::string::npos) << hal;
    } else {
      EXPECT_NE(hal.find("loadrt not names=x-neg-lim-inv,x-pos-lim-inv,x-home-sw-inv"), std::string::npos) << hal;
      EXPECT_NE(hal.find("net x-pos-lim-in cia402.0.drive.00.pos-lim-sw => x-pos-lim-inv.in"), std::string::npos) << hal;
      EXPECT_NE(hal.find("net x-pos-lim x-pos-lim-inv.out => joint.0.pos-lim-sw-in"), std::string::npos) << hal;
      EXPECT_NE(hal.find("addf x-pos-lim-inv servo-thread"), std::string::npos) << hal;
    }
  }
}

TEST(CommissionWriter, DriveHomingWritesHomeModeDriveAndTheMethod) {
  State s = machine_with_steps56(false);
  s.axis('X')->homing = plan_homing(*s.axis('X'), "drive:22");
  testing::TempDir dir;
  const auto files = generate_config(s, dir.path(), "m");
  const std::string& ini = files[0].content;
  EXPECT_NE(ini.find("HOME_MODE = DRIVE"), std::string::npos) << ini;
  EXPECT_NE(ini.find("HOME_METHOD = 22\nHOME_SEARCH_VEL = 5\nHOME_LATCH_VEL = 0.5\n"), std::string::npos) << ini;
  const std::string& hal = files[1].content;
  EXPECT_NE(hal.find("net x-home-start joint.0.drive-home-start => cia402.0.drive.00.home-start"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net x-home-done cia402.0.drive.00.home-done => joint.0.drive-home-done"), std::string::npos) << hal;
}

}  // namespace
}  // namespace cnc::commission
