// Step 8 end to end on a randomised simulated machine
// (sim/cia402/random_machine: pitch error and backlash per axis, drawn from
// a seed, CNC_COMMISSION_SEED or a random one, printed): the direction and
// scaling test first, then X's ISO 230-2 cycle on cncd with the laser
// reading the simulator's true table position (the HAL pin
// cia402-sim.0.node.01.table-position, which the simulator publishes; the
// commissioning code only gets its name), the fit, the configuration
// written with the table, the cycle again on the new configuration: ISO
// 230-2 A measured lower than before. Then configs/sim/nc_files/demo.ngc
// runs on it to its end.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <random>
#include <thread>
#include <nlohmann/json.hpp>

#include "commission/compensation.hpp"
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

TEST(CommissionCompensationE2E, CompensationFittedOnCncdLowersMeasuredIsoAAndTheDemoProgramRuns) {
  const auto bin = testing::binary_dir() / "bin";
  if (!std::filesystem::exists(bin / "cncd") || !std::filesystem::exists(bin / "cnc"))
    GTEST_SKIP() << "cncd and cnc are not built";
  const uint64_t seed = e2e::machine_seed();
  testing::TempDir dir;
  const csim::RandomMachine m = csim::make_random_machine(seed, {1, 2, 3}, "virtual:" + testing::unique_name("comp"));
  e2e::write_machine_files(dir.path(), m);
  std::printf("%s", csim::truth_json(m).c_str());
  std::printf("X: backlash %.4f mm, pitch error", m.axes[0].backlash_mm);
  for (const auto& [x, e] : m.axes[0].pitch_error) std::printf(" %g:%.4f", x, e);
  std::printf(" (mm)\n");

  // The bus scan, on the same machine hosted here (cncd hosts its own copy).
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
    so.timeout_ns = 1'000'000'000;
    so.last = 16;
    so.expected = {1, 2, 3};
    const ScanResult r = scan_canopen(*scanner, so);
    host.stop();
    ASSERT_TRUE(r.ok()) << (r.problems.empty() ? describe(r.nodes.at(0)) : r.problems[0]);
    s.nodes = r.nodes;
  }
  s.interface = m.interface;
  e2e::include_machine_files(s);
  const char letters[] = {'X', 'Y', 'Z'};
  const double lim[3][2] = {{-20, 200}, {-20, 120}, {-55, 20}};  // inside the switches
  for (int j = 0; j < 3; ++j) {
    assign_axis(s, letters[j], j, j + 1);
    set_scaling(s, letters[j], 5.0);
    Axis& a = *s.axis(letters[j]);
    a.min_limit = lim[j][0];
    a.max_limit = lim[j][1];
    a.limits_source = "entered";
    a.max_velocity = 30;
    a.max_acceleration = 300;
  }
  setenv("CNC_INSTANCE", testing::unique_name("commission-comp").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  const Controller ctl(bin);
  const std::string laser = "cia402-sim.0.node.01.table-position";
  auto start_cncd = [&](const std::string& tag) {
    write_config(generate_config(s, dir.path(), "machine"));
    std::string out;
    EXPECT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
    return std::make_unique<ControllerProcess>(bin, dir / "machine.ini", dir / ("cncd-" + tag + ".log"));
  };

  // Step 4 first: direction and scaling of each axis, the dial reading the table.
  {
    auto d = start_cncd("direction");
    for (int j = 0; j < 3; ++j) {
      char pin[64];
      std::snprintf(pin, sizeof pin, "cia402-sim.0.node.%02d.table-position", j + 1);
      const double before = ctl.getp(pin);
      JogResult jr;
      try {
        jr = direction_jog(ctl, *s.axis(letters[j]), 10.0, 5.0);  // 2 mm while the scaling is unchecked (kFirstTestTravel)
      } catch (const std::exception& e) {
        FAIL() << e.what() << "\n" << e2e::read_text(dir / "cncd-direction.log");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      std::printf("%s\n", apply_direction_test(s, letters[j], jr.commanded_mm, jr.feedback_mm, ctl.getp(pin) - before, true)
                              .verdict.c_str());
    }
    EXPECT_EQ(d->stop(), 0);
  }
  for (int j = 0; j < 3; ++j) EXPECT_EQ(s.axis(letters[j])->scaling.reverse, m.axes[j].motor_reversed) << letters[j];

  // Step 8: X's cycle over 0..190 mm, 3 runs each way, at the axis's speed.
  AxisCompensation c = default_compensation(*s.axis('X'));
  c.x_min = 0;
  c.x_max = 190;
  c.runs = 3;
  c.dwell_s = 0.5;
  c.feed_mm_min = 1800;
  c.program = (dir / "comp-x.ngc").string();
  check_cycle(*s.axis('X'), c);
  e2e::write_text(c.program, comp::iso_cycle_gcode(cycle_options(*s.axis('X'), c)));
  s.axis('X')->compensation = c;
  auto measure = [&](const std::string& tag) {
    auto d = start_cncd(tag);
    CompRunResult r;
    try {
      r = run_comp_cycle(ctl, *s.axis('X'), c, c.program, laser, [](int i, int n, const std::string& what) {
        if (i % 10 == 0 || i == n) std::printf("progress: %d/%d %s\n", i, n, what.c_str());
      });
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what() << "\n" << e2e::read_text(dir / ("cncd-" + tag + ".log"));
    }
    EXPECT_EQ(d->stop(), 0);
    return r;
  };
  const CompRunResult before = measure("measure");
  ASSERT_EQ(before.readings_mm.size(), before.stops.size());
  const CompFigures& measured = set_measurement(s, 'X', points_from_readings(before.stops, before.readings_mm), "laser pin " + laser);
  std::printf("before: %s\n", describe(measured).c_str());
  const std::string report = fit_compensation(s, 'X', dir / "comp-x", true);
  std::printf("%s", report.c_str());

  // Step 9 with the table, and the cycle again on the new configuration.
  const CompRunResult after = measure("check");
  ASSERT_EQ(after.readings_mm.size(), after.stops.size());
  const CompFigures checked = set_measurement(s, 'X', points_from_readings(after.stops, after.readings_mm), "check", true);
  const AxisCompensation& r = *s.axis('X')->compensation;
  std::printf("ISO 230-2, axis X: A measured before %.3f um, predicted %.3f um, measured after %.3f um\n", r.before.A,
              r.predicted.A, checked.A);
  std::printf("  before: %s\n  after:  %s\n", describe(r.before).c_str(), describe(checked).c_str());
  EXPECT_NE(e2e::read_text(dir / "machine.ini").find("COMP_FILE = machine-x.comp"), std::string::npos);
  EXPECT_LT(checked.A, r.before.A);
  EXPECT_LT(checked.A, 0.6 * r.before.A);

  // The demo program on the compensated configuration, to its end.
  auto d = start_cncd("demo");
  auto must = [&](const std::string& args, int timeout_s = 30) {
    const auto res = testing::run_shell(e2e::cnc_cmd("--timeout " + std::to_string(timeout_s) + " " + args));
    ASSERT_EQ(res.code, 0) << "cnc " << args << ": " << res.text << "\n" << e2e::read_text(dir / "cncd-demo.log");
  };
  must("wait-ready");
  must("estop-reset");
  must("on");
  must("home all", 60);
  must("mode auto");
  must("open '" + (testing::source_dir() / "configs/sim/nc_files/demo.ngc").string() + "'");
  must("run");
  must("wait-program", 500);
  const auto js = nlohmann::json::parse(testing::run_shell(e2e::cnc_cmd("status --json")).text);
  EXPECT_EQ(js["task"]["interp_state"], "IDLE");
  const double expect[3] = {180, 110, 0};
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(js["motion"]["position"][j].get<double>(), expect[j], 1e-6) << letters[j];
  EXPECT_EQ(d->stop(), 0);
}

}  // namespace
}  // namespace cnc::commission
