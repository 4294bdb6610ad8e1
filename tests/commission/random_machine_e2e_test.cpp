// End to end on a randomised simulated machine (sim/cia402/random_machine):
// encoder resolution, gear, screw lead and motor direction of each axis are
// drawn from a seed (CNC_COMMISSION_SEED, else a random one, printed) and
// known only to the simulator. The commissioning steps scan the bus, take
// a nominal 5 mm lead for every axis, write a provisional configuration,
// run the direction test on cncd with a dial reading (the simulated table's
// true travel), correct direction and scaling, write the final
// configuration and run configs/sim/nc_files/demo.ngc on it to its end.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <random>
#include <thread>
#include <nlohmann/json.hpp>

#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/scan.hpp"
#include "commission/steps.hpp"
#include "core/ini/ini_file.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/random_machine.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"
#include "tests/commission/e2e_support.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

namespace csim = cnc::cia402::sim;

TEST(CommissionRandomMachine, DiscoversDirectionAndScalingAndRunsTheDemoProgram) {
  const auto bin = testing::binary_dir() / "bin";
  if (!std::filesystem::exists(bin / "cncd") || !std::filesystem::exists(bin / "cnc"))
    GTEST_SKIP() << "cncd and cnc are not built";
  const uint64_t seed = e2e::machine_seed();
  testing::TempDir dir;
  const std::string bus_name = testing::unique_name("commission");
  const csim::RandomMachine m = csim::make_random_machine(seed, {1, 2, 3}, "virtual:" + bus_name);
  e2e::write_machine_files(dir.path(), m);
  std::printf("%s", csim::truth_json(m).c_str());

  // 1. The bus scan, on the same machine hosted here (cncd hosts its own copy).
  State s;
  {
    const auto cfg = csim::load_sim_config(ini::IniFile::load(dir / "sim-machine.ini"), "CIA402_SIM");
    can::VirtualBusOptions o;
    o.manual_clock = false;
    auto vbus = can::VirtualBus::create(o);
    auto host_port = vbus->open_port("host");
    auto scanner = vbus->open_port("scanner");
    csim::SimHost host(*host_port);
    for (const auto& n : cfg.nodes) host.add(n, vbus->open_port("node-" + std::to_string(n.node_id)));
    host.start();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ScanOptions so;
    so.timeout_ns = 1'000'000'000;  // the simulator's thread may wait on a loaded host
    so.last = 16;
    so.expected = {1, 2, 3};
    so.eds_dir = testing::source_dir() / "configs/canopen-mill/drives";
    const ScanResult r = scan_canopen(*scanner, so);
    host.stop();
    ASSERT_TRUE(r.ok()) << (r.problems.empty() ? describe(r.nodes.at(0)) : r.problems[0]);
    s.nodes = r.nodes;
  }
  s.interface = m.interface;
  e2e::include_machine_files(s);

  // 2, 3. Axes and nominal scaling: the builder believes in 5 mm screws, direct drive.
  const char letters[] = {'X', 'Y', 'Z'};
  for (int j = 0; j < 3; ++j) {
    assign_axis(s, letters[j], j, j + 1);
    set_scaling(s, letters[j], 5.0);
    EXPECT_DOUBLE_EQ(s.axis(letters[j])->scaling.encoder_counts, m.axes[j].encoder_counts);
  }

  setenv("CNC_INSTANCE", testing::unique_name("commission").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  const Controller ctl(bin);

  // 4. Direction and scaling tests, twice: the second confirms the first.
  for (int round = 0; round < 2; ++round) {
    write_config(generate_config(s, dir.path(), "machine"));
    std::string out;
    ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
    ControllerProcess d(bin, dir / "machine.ini", dir / ("cncd-" + std::to_string(round) + ".log"));
    for (int j = 0; j < 3; ++j) {
      char pin[64];
      std::snprintf(pin, sizeof pin, "cia402-sim.0.node.%02d.table-position", j + 1);
      const double before = ctl.getp(pin);
      JogResult jr;
      try {
        jr = direction_jog(ctl, *s.axis(letters[j]), 10.0, 5.0);  // 2 mm while the scaling is unchecked (kFirstTestTravel)
      } catch (const std::exception& e) {
        FAIL() << e.what() << "\n" << e2e::read_text(dir / ("cncd-" + std::to_string(round) + ".log"));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      const double dial = ctl.getp(pin) - before;
      const DirectionTest& t = apply_direction_test(s, letters[j], jr.commanded_mm, jr.feedback_mm, dial, true);
      std::printf("round %d: %s (dial %.4f mm)\n", round, t.verdict.c_str(), dial);
      if (round == 1) {
        EXPECT_FALSE(t.reversed) << letters[j];
        EXPECT_NEAR(t.correction, 1.0, 0.005) << letters[j];
      }
    }
    EXPECT_EQ(d.stop(), 0);
  }
  for (int j = 0; j < 3; ++j) {
    const Axis& a = *s.axis(letters[j]);
    EXPECT_EQ(a.scaling.reverse, m.axes[j].motor_reversed) << letters[j];
    EXPECT_NEAR(a.scaling.counts_per_mm() / m.axes[j].counts_per_mm(), 1.0, 0.005) << letters[j];
  }

  // 9. The final configuration, and the demo program on it.
  const double lim[3][2] = {{-10, 250}, {-10, 150}, {-150, 10}};
  for (int j = 0; j < 3; ++j) {
    Axis& a = *s.axis(letters[j]);
    a.min_limit = lim[j][0];
    a.max_limit = lim[j][1];
    a.max_velocity = 30;
    a.max_acceleration = 300;
  }
  write_config(generate_config(s, dir.path(), "machine"));
  std::string out;
  ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
  ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-final.log");
  auto must = [&](const std::string& args, int timeout_s = 30) {
    const auto r = testing::run_shell(e2e::cnc_cmd("--timeout " + std::to_string(timeout_s) + " " + args));
    ASSERT_EQ(r.code, 0) << "cnc " << args << ": " << r.text << "\n" << e2e::read_text(dir / "cncd-final.log");
  };
  must("wait-ready");
  must("estop-reset");
  must("on");
  must("home all", 60);
  must("mode auto");
  must("open '" + (testing::source_dir() / "configs/sim/nc_files/demo.ngc").string() + "'");
  must("run");
  must("wait-program", 500);
  const auto status = testing::run_shell(e2e::cnc_cmd("status --json"));
  const auto js = nlohmann::json::parse(status.text);
  EXPECT_EQ(js["task"]["interp_state"], "IDLE") << status.text;
  // G53 G0 Z0 after the drilling at G54 X80 Y60 (offset X100 Y50): X180 Y110 Z0.
  const double expect[3] = {180, 110, 0};
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(js["motion"]["position"][j].get<double>(), expect[j], 1e-6) << letters[j];
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace cnc::commission

namespace cnc::commission {
namespace {

// Bring-up of part of a machine: Z's drive is disabled in the configuration
// and missing from the bus; the controller starts, says so, and X moves.
TEST(CommissionPartialMachine, StartsWithADisabledDriveMissingFromTheBusAndSaysSo) {
  const auto bin = testing::binary_dir() / "bin";
  if (!std::filesystem::exists(bin / "cncd") || !std::filesystem::exists(bin / "cnc"))
    GTEST_SKIP() << "cncd and cnc are not built";
  testing::TempDir dir;
  const csim::RandomMachine m = csim::make_random_machine(11, {1}, "virtual:" + testing::unique_name("partial"));
  e2e::write_machine_files(dir.path(), m);
  State s;
  s.interface = m.interface;
  for (int id : {1, 2}) {
    ScannedNode n;
    n.node_id = id;
    n.cia402 = true;
    n.encoder_increments = static_cast<uint32_t>(m.axes[0].encoder_counts);
    s.nodes.push_back(n);
  }
  assign_axis(s, 'X', 0, 1);
  set_scaling(s, 'X', 5.0);
  assign_axis(s, 'Z', 1, 2);
  s.axis('Z')->enabled = false;  // its drive is not wired yet
  e2e::include_machine_files(s);
  write_config(generate_config(s, dir.path(), "partial"));
  std::string out;
  ASSERT_EQ(check_config(bin / "cncd", dir / "partial.ini", out), 0) << out;

  setenv("CNC_INSTANCE", testing::unique_name("partial").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  const Controller ctl(bin);
  ControllerProcess d(bin, dir / "partial.ini", dir / "cncd.log");
  EXPECT_NE(e2e::read_text(dir / "cncd.log").find("DISABLED for commissioning"), std::string::npos) << e2e::read_text(dir / "cncd.log");
  const JogResult x = direction_jog(ctl, *s.axis('X'), 2.0, 2.0);
  EXPECT_NEAR(x.feedback_mm, 2.0, 0.01);
  const JogResult z = direction_jog(ctl, *s.axis('Z'), 2.0, 2.0);  // follows its command, moves nothing
  EXPECT_NEAR(z.feedback_mm, 2.0, 1e-9);
  EXPECT_EQ(d.stop(), 0) << e2e::read_text(dir / "cncd.log");
}

}  // namespace
}  // namespace cnc::commission
