// Steps 5 and 6 end to end on a randomised simulated machine
// (sim/cia402/random_machine): limit and home switch positions and their
// active level are drawn from a seed (CNC_COMMISSION_SEED, else a random
// one, printed) and known only to the simulator. Steps 1-4 are taken as
// done (random_machine_e2e_test.cpp covers them): the test gives the state
// the scaling and direction the direction test finds. The switch search
// runs on cncd for each axis, its findings are compared with the truth,
// soft limits follow from them, controller homing runs 5 times per axis,
// and the configuration written from the state runs
// configs/sim/nc_files/demo.ngc to its end.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/homing_check.hpp"
#include "commission/steps.hpp"
#include "commission/switches.hpp"
#include "sim/cia402/random_machine.hpp"
#include "tests/commission/e2e_support.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

namespace csim = cnc::cia402::sim;

// How close the switch search must come to the simulator's truth (each
// edge is crossed again slowly until two polls around it are within
// 0.02 mm, at most three tries), and the homing spread it must reach (the
// controller latches in the servo cycle).
constexpr double kSwitchTolerance = 0.1;   // mm
constexpr double kHomingSpreadBound = 0.01;  // mm

// A state for machine `m` with steps 1-4 done: nodes scanned, axes
// assigned, scaling and direction as the direction test finds them.
State commissioned_to_step4(const csim::RandomMachine& m, const char* letters) {
  State s;
  s.interface = m.interface;
  for (std::size_t j = 0; j < m.axes.size(); ++j) {
    ScannedNode n;
    n.node_id = m.axes[j].node;
    n.cia402 = true;
    n.encoder_increments = static_cast<uint32_t>(m.axes[j].encoder_counts);
    s.nodes.push_back(n);
  }
  for (std::size_t j = 0; j < m.axes.size(); ++j) {
    assign_axis(s, letters[j], static_cast<int>(j), m.axes[j].node);
    set_scaling(s, letters[j], m.axes[j].lead_mm, 0, m.axes[j].gear, 1);
    Axis& a = *s.axis(letters[j]);
    a.scaling.reverse = m.axes[j].motor_reversed;
    a.min_limit = -300;  // provisional: not homed, the soft limits do not act yet
    a.max_limit = 300;
    a.max_velocity = 30;
    a.max_acceleration = 300;
  }
  e2e::include_machine_files(s);
  return s;
}

bool built() {
  const auto bin = testing::binary_dir() / "bin";
  return std::filesystem::exists(bin / "cncd") && std::filesystem::exists(bin / "cnc") &&
         std::filesystem::exists(bin / "halcmd");
}

TEST(CommissionSwitchesHoming, FindsTheSwitchesHomesRepeatablyAndRunsTheDemoProgram) {
  if (!built()) GTEST_SKIP() << "cncd, cnc and halcmd are not built";
  const auto bin = testing::binary_dir() / "bin";
  uint64_t seed = std::random_device{}();
  if (const char* e = std::getenv("CNC_COMMISSION_SEED")) seed = std::strtoull(e, nullptr, 10);
  std::printf("random machine seed %llu (CNC_COMMISSION_SEED=%llu repeats it)\n", static_cast<unsigned long long>(seed),
              static_cast<unsigned long long>(seed));
  testing::TempDir dir;
  const csim::RandomMachine m = csim::make_random_machine(seed, {1, 2, 3}, "virtual:" + testing::unique_name("sw"));
  e2e::write_machine_files(dir.path(), m);
  std::printf("%s", csim::truth_json(m).c_str());
  const char letters[] = {'X', 'Y', 'Z'};
  State s = commissioned_to_step4(m, letters);
  setenv("CNC_INSTANCE", testing::unique_name("sw").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  const Controller ctl(bin);

  // 5. The switch search on each axis, on the provisional configuration.
  {
    write_config(generate_config(s, dir.path(), "machine"));
    ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-switches.log");
    const double search[3] = {250, 170, 100};
    for (int j = 0; j < 3; ++j) {
      AxisSwitches r;
      try {
        r = find_switches(ctl, *s.axis(letters[j]), search[j], 5.0, stdout);
      } catch (const std::exception& e) {
        FAIL() << e.what() << "\n" << e2e::read_text(dir / "cncd-switches.log");
      }
      const auto& t = m.axes[static_cast<std::size_t>(j)];
      std::printf("axis %c: neg %.3f (truth %.3f), pos %.3f (truth %.3f), home %.3f..%.3f (truth %.3f..%.3f), "
                  "active %s (truth %s)\n", letters[j], r.neg_limit.position, t.neg_limit_mm, r.pos_limit.position,
                  t.pos_limit_mm, r.home.position, r.home.position_high, t.home_min_mm, t.home_max_mm,
                  r.home.active_high ? "high" : "low", t.switches_active_low ? "low" : "high");
      EXPECT_TRUE(r.problems.empty()) << letters[j] << ": " << r.problems.front();
      EXPECT_NEAR(r.neg_limit.position, t.neg_limit_mm, kSwitchTolerance) << letters[j];
      EXPECT_NEAR(r.pos_limit.position, t.pos_limit_mm, kSwitchTolerance) << letters[j];
      EXPECT_NEAR(r.home.position, t.home_min_mm, kSwitchTolerance) << letters[j];
      EXPECT_TRUE(r.home.has_high) << letters[j];
      EXPECT_NEAR(r.home.position_high, t.home_max_mm, kSwitchTolerance) << letters[j];
      for (const SwitchFinding* f : {&r.neg_limit, &r.pos_limit, &r.home})
        EXPECT_EQ(f->active_high, !t.switches_active_low) << letters[j] << " " << f->pin;
      EXPECT_NEAR(ctl.motor_position(j), r.start, 0.01) << letters[j] << ": back at the start";
      s.axis(letters[j])->switches = r;
      soft_limits_from_switches(*s.axis(letters[j]), 2.0);
    }
    EXPECT_EQ(d.stop(), 0) << e2e::read_text(dir / "cncd-switches.log");
  }

  // 6. Controller homing, 5 runs per axis, on a configuration with the
  // switches wired to the joints (their polarity as found) and the method.
  for (int j = 0; j < 3; ++j) s.axis(letters[j])->homing = plan_homing(*s.axis(letters[j]), "controller");
  {
    write_config(generate_config(s, dir.path(), "machine"));
    std::string out;
    ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
    ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-homing.log");
    for (int j = 0; j < 3; ++j) {
      Axis& a = *s.axis(letters[j]);
      std::vector<double> refs;
      try {
        refs = run_homing(ctl, a, 5, 5.0, stdout);
      } catch (const std::exception& e) {
        FAIL() << e.what() << "\n" << e2e::read_text(dir / "cncd-homing.log");
      }
      ASSERT_EQ(refs.size(), 5u);
      a.homing->references = refs;
      a.homing->spread = spread(refs);
      std::printf("axis %c: controller homing, spread %.4f mm\n", letters[j], a.homing->spread);
      EXPECT_LT(a.homing->spread, kHomingSpreadBound) << letters[j];
    }
    EXPECT_EQ(d.stop(), 0) << e2e::read_text(dir / "cncd-homing.log");
  }

  // 9. The final configuration, and the demo program on it.
  write_config(generate_config(s, dir.path(), "machine"));
  std::string out;
  ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
  ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-final.log");
  auto must = [&](const std::string& args, int timeout_s = 30) {
    const auto r = testing::run_shell(e2e::cnc_cmd("--timeout " + std::to_string(timeout_s) + " " + args));
    ASSERT_EQ(r.code, 0) << "cnc " << args << ": " << r.text << "\n" << e2e::read_text(dir / "cncd-final.log");
  };
  must("estop-reset");
  must("on");
  must("home all", 120);
  must("mode auto");
  must("open '" + (testing::source_dir() / "configs/sim/nc_files/demo.ngc").string() + "'");
  must("run");
  must("wait-program", 500);
  const auto js = nlohmann::json::parse(testing::run_shell(e2e::cnc_cmd("status --json")).text);
  EXPECT_EQ(js["task"]["interp_state"], "IDLE");
  const double expect[3] = {180, 110, 0};
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(js["motion"]["position"][j].get<double>(), expect[j], 1e-6) << letters[j];
  EXPECT_EQ(d.stop(), 0);
}

TEST(CommissionSwitchesHoming, AHomeSwitchThatNeverChangesIsReportedByName) {
  if (!built()) GTEST_SKIP() << "cncd, cnc and halcmd are not built";
  const auto bin = testing::binary_dir() / "bin";
  testing::TempDir dir;
  csim::RandomMachine m = csim::make_random_machine(21, {1}, "virtual:" + testing::unique_name("swdead"));
  m.axes[0].home_min_mm = 5000;  // a broken home switch: never actuated
  m.axes[0].home_max_mm = 5001;
  e2e::write_machine_files(dir.path(), m);
  const char letters[] = {'X'};
  State s = commissioned_to_step4(m, letters);
  write_config(generate_config(s, dir.path(), "machine"));
  setenv("CNC_INSTANCE", testing::unique_name("swdead").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  ControllerProcess d(bin, dir / "machine.ini", dir / "cncd.log");
  const AxisSwitches r = find_switches(Controller(bin), *s.axis('X'), 40, 10.0);
  EXPECT_TRUE(r.neg_limit.seen);
  EXPECT_FALSE(r.pos_limit.seen);  // 40 mm do not reach it
  EXPECT_FALSE(r.home.seen);
  std::string all;
  for (const auto& p : r.problems) all += p + "\n";
  EXPECT_NE(all.find("axis X: the home switch never changed within 40.000 mm of the start "
                     "(cia402.0.drive.00.home-sw)"), std::string::npos) << all;
  EXPECT_NE(all.find("axis X: the positive limit switch never changed"), std::string::npos) << all;
  EXPECT_EQ(d.stop(), 0) << e2e::read_text(dir / "cncd.log");
}

TEST(CommissionSwitchesHoming, BadInputExitsWithAClearMessageAndLeavesTheStateUnchanged) {
  const auto prog = testing::binary_dir() / "bin/cnc-commission";
  if (!std::filesystem::exists(prog)) GTEST_SKIP() << "cnc-commission is not built";
  testing::TempDir dir;
  const csim::RandomMachine m = csim::make_random_machine(5, {1}, "virtual:none");
  const char letters[] = {'X'};
  const State s = commissioned_to_step4(m, letters);
  save_state(s, dir / "state.json");
  const std::string before = e2e::read_text(dir / "state.json");
  const std::string cc = "'" + prog.string() + "' --state '" + (dir / "state.json").string() + "' ";
  auto r = testing::run_shell(cc + "axis Q switches 2>&1");
  EXPECT_EQ(r.code, 2) << r.text;
  EXPECT_NE(r.text.find("axis Q has no drive yet"), std::string::npos) << r.text;
  r = testing::run_shell(cc + "axis X soft-limits 2>&1");
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_NE(r.text.find("axis X: no switch search yet"), std::string::npos) << r.text;
  r = testing::run_shell(cc + "axis X homing --method controller 2>&1");
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_NE(r.text.find("axis X: the home switch was not found"), std::string::npos) << r.text;
  r = testing::run_shell(cc + "axis X homing 2>&1");
  EXPECT_EQ(r.code, 2) << r.text;
  r = testing::run_shell(cc + "homing-methods");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.text.find("drive:17"), std::string::npos) << r.text;
  EXPECT_EQ(e2e::read_text(dir / "state.json"), before);
}

}  // namespace
}  // namespace cnc::commission
