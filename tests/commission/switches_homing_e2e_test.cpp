// Steps 5 and 6 on cncd (label slow): a home switch that never changes is
// reported by name, and bad input exits with a clear message, the state
// unchanged. (The switch search, soft limits and homing of a random
// machine end to end are in full_run_e2e_test.cpp, with all the other
// steps.)
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
