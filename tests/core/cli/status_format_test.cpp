// What `cnc status` prints, as text and as JSON.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <memory>

#include "core/cli/status_format.hpp"

using namespace cnc;

namespace {
std::unique_ptr<ipc::Status> status_with_a_late_thread() {
  auto s = std::make_unique<ipc::Status>();
  ipc::ThreadStatus& t = s->threads[0];
  t.name.assign("servo-thread");
  t.period_ns = 1'000'000;
  t.cycles = 60'000;
  t.overruns = 14;
  t.missed_cycles = 2015;
  t.overrun_streak = 2;
  t.longest_streak = 5;
  t.longest_gap = 2001;
  t.late_wakes = 3;
  t.overrun_function.assign("motion-controller");
  t.overrun_function_count = 11;
  t.overrun_function_max_ns = 1'420'000;
  return s;
}
}  // namespace

TEST(StatusFormat, ThreadOverrunsStreaksGapsAndTheFunctionToBlameAreShown) {
  const auto s = status_with_a_late_thread();
  const std::string text = cli::format_status(*s);
  EXPECT_NE(text.find("servo-thread   period 1000000 ns, 60000 cycles, 14 overruns"), std::string::npos) << text;
  EXPECT_NE(text.find("overruns: streak 2 now, longest 5; 2015 periods missed, longest gap 2001; 3 blamed on late "
                      "wake-ups, 11 on motion-controller (max 1420.0 us)"),
            std::string::npos)
      << text;
}

TEST(StatusFormat, ThreadWithoutOverrunsHasNoOverrunLine) {
  auto s = std::make_unique<ipc::Status>();
  s->threads[0].name.assign("servo-thread");
  s->threads[0].period_ns = 1'000'000;
  EXPECT_EQ(cli::format_status(*s).find("overruns:"), std::string::npos);
}

TEST(StatusFormat, JsonCarriesEveryOverrunFigure) {
  const auto s = status_with_a_late_thread();
  const auto j = nlohmann::json::parse(cli::status_json(*s));
  const auto& t = j["threads"][0];
  EXPECT_EQ(t["overruns"], 14);
  EXPECT_EQ(t["missed_cycles"], 2015);
  EXPECT_EQ(t["overrun_streak"], 2);
  EXPECT_EQ(t["longest_streak"], 5);
  EXPECT_EQ(t["longest_gap"], 2001);
  EXPECT_EQ(t["late_wakes"], 3);
  EXPECT_EQ(t["overrun_function"], "motion-controller");
  EXPECT_EQ(t["overrun_function_count"], 11);
  EXPECT_EQ(t["overrun_function_max_ns"], 1'420'000);
}

TEST(StatusFormat, LimitsInForceAreShownAsTextAndJson) {
  auto s = std::make_unique<ipc::Status>();
  s->motion.joints = 1;
  s->motion.spindles = 1;
  s->motion.axis_mask = 1;
  s->motion.max_linear_velocity = 5;
  s->motion.max_linear_acceleration = 1000;
  s->motion.max_linear_jerk = 1e99;
  ipc::AxisStatus& x = s->axes[0];
  x.min_position_limit = -1;
  x.max_position_limit = 300;
  x.max_velocity = 10;
  x.max_acceleration = 1000;
  x.max_jerk = 50000;
  x.velocity_limit = 10;
  x.acceleration_limit = 1000;
  ipc::JointStatus& j = s->joints[0];
  j.min_position_limit = -1e99;
  j.max_position_limit = 1e99;
  j.max_velocity = 105;
  j.velocity_limit = 105;
  ipc::SpindleStatus& sp = s->spindles[0];
  sp.max_forward = 10000;
  sp.max_reverse = 0;
  sp.speed = 50000;
  sp.override_scale = 1.1;
  sp.speed_out = 10000;
  sp.speed_limited = true;
  const std::string text = cli::format_status(*s);
  EXPECT_NE(text.find("path       velocity 5  acceleration 1000  jerk none"), std::string::npos) << text;
  EXPECT_NE(text.find("axis X     -1..300  velocity 10  acceleration 1000  jerk 50000  (moves use 10, 1000)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("joint 0    none..none  velocity 105"), std::string::npos) << text;
  EXPECT_NE(text.find("spindle 0  forward 0..10000 rpm, reverse not allowed; commanded 50000 rpm x 110%, out 10000 rpm "
                      "(held at a limit)"),
            std::string::npos)
      << text;
  const auto js = nlohmann::json::parse(cli::status_json(*s));
  EXPECT_EQ(js["motion"]["max_linear_velocity"], 5);
  EXPECT_EQ(js["axes"][0]["max_velocity"], 10);
  EXPECT_EQ(js["joints"][0]["max_velocity"], 105);
  EXPECT_EQ(js["spindles"][0]["speed_out"], 10000);
  EXPECT_EQ(js["spindles"][0]["speed_limited"], true);
}

// The servo thread's time is split between the product's functions and the
// simulators' that run in it; a simulator on a thread of its own shows its
// time apart (docs/architecture.md, "Simulators").
TEST(StatusFormat, ServoTimeOfProductAndSimulatorsIsShownApart) {
  auto s = std::make_unique<ipc::Status>();
  ipc::ThreadStatus& t = s->threads[0];
  t.name.assign("servo-thread");
  t.period_ns = 1'000'000;
  t.exec_last_ns = 48'000;
  t.exec_max_ns = 90'000;
  t.product_exec_last_ns = 45'000;
  t.product_exec_max_ns = 85'000;
  t.sim_exec_last_ns = 3'000;
  t.sim_exec_max_ns = 7'500;
  ipc::SimulatorStatus& sim = s->simulators[0];
  sim.name.assign("cia402-sim");
  sim.steps = 61'000;
  sim.late_steps = 2;
  sim.helped_steps = 1;
  sim.wakes = 3;
  sim.exec_last_ns = 120'000;
  sim.exec_max_ns = 410'000;
  const std::string text = cli::format_status(*s);
  EXPECT_NE(text.find("of which product functions 45.0 us (max 85.0), simulators 3.0 us (max 7.5)"), std::string::npos)
      << text;
  EXPECT_NE(text.find("cia402-sim     simulator on its own thread: 61000 periods, 2 late (1 caught up in the "
                      "HAL thread), woken 3 times; "
                      "exec 120.0 us (max 410.0)"),
            std::string::npos)
      << text;
  const auto j = nlohmann::json::parse(cli::status_json(*s));
  EXPECT_EQ(j["threads"][0]["product_exec_max_ns"], 85'000);
  EXPECT_EQ(j["threads"][0]["sim_exec_last_ns"], 3'000);
  EXPECT_EQ(j["simulators"][0]["name"], "cia402-sim");
  EXPECT_EQ(j["simulators"][0]["late_steps"], 2);
  EXPECT_EQ(j["simulators"][0]["helped_steps"], 1);
  EXPECT_EQ(j["simulators"][0]["wakes"], 3);
  EXPECT_EQ(j["simulators"][0]["exec_max_ns"], 410'000);
}

TEST(StatusFormat, AlarmsListActiveOnesWithCountsAndJsonCarriesAll) {
  auto s = std::make_unique<ipc::Status>();
  ipc::AlarmStatus& a = s->alarms;
  a.available = true;
  a.active = 1;
  a.list[0].id = 3;
  a.list[0].count = 1;
  a.list[0].acknowledged = true;
  a.list[0].text.assign("old one");
  a.list[1].id = 4;
  a.list[1].count = 3;
  a.list[1].cause.assign("joint 1");
  a.list[1].text.assign("joint 1 amplifier fault");
  const std::string active = cli::format_alarms(a);
  EXPECT_NE(active.find("Alarms: 1 active"), std::string::npos) << active;
  EXPECT_NE(active.find("#4 "), std::string::npos) << active;
  EXPECT_NE(active.find("x3: joint 1 amplifier fault"), std::string::npos) << active;
  EXPECT_EQ(active.find("old one"), std::string::npos) << active;
  EXPECT_NE(cli::format_alarms(a, true).find("(acknowledged): old one"), std::string::npos);
  EXPECT_NE(cli::format_status(*s).find("Alarms: 1 active"), std::string::npos);
  const auto j = nlohmann::json::parse(cli::status_json(*s));
  EXPECT_EQ(j["alarms"]["active"], 1);
  ASSERT_EQ(j["alarms"]["list"].size(), 2u);
  EXPECT_EQ(j["alarms"]["list"][1]["cause"], "joint 1");
  EXPECT_EQ(j["alarms"]["list"][1]["count"], 3);
}
