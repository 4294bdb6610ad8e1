// Step 7, tuning, end to end on cncd with a randomised simulated machine
// (sim/cia402/random_machine; CNC_COMMISSION_SEED repeats one): the
// direction and scaling test first (so the configuration moves the axes
// the right way at the right scale), then the tuning tests of each axis on
// a tuning configuration (ceilings above what the simulated drives can
// do), then the checks: every recommended limit lies below the simulated
// drive's true capability less the margin, and cncd runs
// configs/sim/nc_files/demo.ngc to its end on the configuration written
// with the recommendations.
// The simulator's true capability: e2e::capability (e2e_support.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/steps.hpp"
#include "commission/tuning.hpp"
#include "core/ini/ini_file.hpp"
#include "sim/cia402/random_machine.hpp"
#include "sim/cia402/sim_config.hpp"
#include "tests/commission/e2e_support.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

namespace csim = cnc::cia402::sim;

TEST(CommissionTuning, RecommendsLimitsWithinTheSimulatorsCapabilityAndTheDemoRunsOnThem) {
  const auto bin = testing::binary_dir() / "bin";
  if (!std::filesystem::exists(bin / "cncd") || !std::filesystem::exists(bin / "cnc"))
    GTEST_SKIP() << "cncd and cnc are not built";
  const uint64_t seed = e2e::machine_seed();
  testing::TempDir dir;
  const csim::RandomMachine m = csim::make_random_machine(seed, {1, 2, 3}, "virtual:" + testing::unique_name("tune"));
  e2e::write_machine_files(dir.path(), m);
  std::printf("%s", csim::truth_json(m).c_str());
  const auto sim = csim::load_sim_config(ini::IniFile::load(dir / "sim-machine.ini"), "CIA402_SIM");

  // The state as steps 1-3 leave it (the scan's nodes as the bus scan test
  // finds them), a nominal 5 mm lead, then the direction test (step 4)
  // with the simulated table's travel as the dial reading.
  State s;
  s.interface = m.interface;
  for (int j = 0; j < 3; ++j) {
    ScannedNode n;
    n.node_id = j + 1;
    n.cia402 = true;
    n.encoder_increments = static_cast<uint32_t>(m.axes[j].encoder_counts);
    n.encoder_motor_revs = 1;
    s.nodes.push_back(n);
  }
  e2e::include_machine_files(s);
  const char letters[] = {'X', 'Y', 'Z'};
  // Provisional limits inside the random machine's limit switches (about
  // X -30/+215, Y -30/+135, Z -65/+30, each up to 3 mm off): the tests
  // move inside them.
  const double lim[3][2] = {{-20, 200}, {-20, 120}, {-55, 20}};
  for (int j = 0; j < 3; ++j) {
    assign_axis(s, letters[j], j, j + 1);
    set_scaling(s, letters[j], 5.0);
    s.axis(letters[j])->min_limit = lim[j][0];
    s.axis(letters[j])->max_limit = lim[j][1];
    s.axis(letters[j])->limits_source = "entered";
  }
  setenv("CNC_INSTANCE", testing::unique_name("tune").c_str(), 1);
  setenv("CNC_NO_REALTIME", "1", 1);
  const Controller ctl(bin);
  {
    write_config(generate_config(s, dir.path(), "machine"));
    std::string out;
    ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
    ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-direction.log");
    for (int j = 0; j < 3; ++j) {
      char pin[64];
      std::snprintf(pin, sizeof pin, "cia402-sim.0.node.%02d.table-position", j + 1);
      const double before = ctl.getp(pin);
      const JogResult jr = direction_jog(ctl, *s.axis(letters[j]), 5.0, 5.0);
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      const double dial = ctl.getp(pin) - before;
      apply_direction_test(s, letters[j], jr.commanded_mm, jr.feedback_mm, dial, true);
    }
    EXPECT_EQ(d.stop(), 0);
  }
  for (int j = 0; j < 3; ++j) {
    ASSERT_EQ(s.axis(letters[j])->scaling.reverse, m.axes[j].motor_reversed) << letters[j];
    ASSERT_NEAR(s.axis(letters[j])->scaling.counts_per_mm() / m.axes[j].counts_per_mm(), 1.0, 0.005) << letters[j];
  }

  // 7. Tuning, axis by axis, on the tuning configuration (each cncd
  // starts the simulated tables at 0): ceilings above any simulated
  // drive's capability (at most 1000 mm/s, 28000 mm/s^2).
  TuneOptions o;
  o.max_velocity = 1200;
  o.max_acceleration = 32000;
  o.margin_pct = 20;
  o.steps = 6;
  o.progress = [](const std::string& l) { std::printf("progress: %s\n", l.c_str()); };
  o.report = [](const std::string& l) { std::printf("%s\n", l.c_str()); };
  for (int j = 0; j < 3; ++j) {
    const char l = letters[j];
    o.record_dir = dir / (std::string("tuning-") + static_cast<char>(std::tolower(l)));
    const State cfg = tuning_configuration(s, l, o);
    write_config(generate_config(cfg, dir.path(), "tune"));
    std::string out;
    ASSERT_EQ(check_config(bin / "cncd", dir / "tune.ini", out), 0) << out;
    const auto log = dir / (std::string("cncd-tune-") + l + ".log");
    ControllerProcess d(bin, dir / "tune.ini", log);
    try {
      s.axis(l)->tuning = run_tuning(ctl, *s.axis(l), o);
    } catch (const std::exception& e) {
      FAIL() << l << ": " << e.what() << "\n" << e2e::read_text(log);
    }
    EXPECT_EQ(d.stop(), 0) << e2e::read_text(log);
    const AxisTuning& t = *s.axis(l)->tuning;
    const e2e::Capability cap = e2e::capability(sim.nodes.at(j), t.max_velocity);
    std::printf("axis %c: recommended %.1f mm/s, %.0f mm/s2, jerk %.0f, FERROR %.4f, MIN_FERROR %.4f; true %.1f mm/s, "
                "%.0f mm/s2\n  velocity: %s\n  acceleration: %s\n",
                l, t.max_velocity, t.max_acceleration, t.max_jerk, t.ferror, t.min_ferror, cap.velocity, cap.acceleration,
                t.velocity_limit.c_str(), t.acceleration_limit.c_str());
    // Within the capability, with the margin (1 % for the sampled peaks).
    const double keep = 1.0 - o.margin_pct / 100;
    EXPECT_GT(t.max_velocity, 0) << l;
    EXPECT_LE(t.max_velocity, keep * cap.velocity * 1.01) << l;
    EXPECT_GT(t.max_acceleration, 0) << l;
    EXPECT_LE(t.max_acceleration, keep * cap.acceleration * 1.01) << l;
    EXPECT_GT(t.ferror, 0) << l;
    EXPECT_LE(t.min_ferror, t.ferror) << l;
    // The ceiling lies above the true velocity: the velocity series found it.
    EXPECT_EQ(t.velocity_limit.rfind("saturation", 0), 0u) << l << ": " << t.velocity_limit;
    // Every test has its record.
    for (const TuningTest& x : t.tests) {
      ASSERT_TRUE(std::filesystem::exists(x.csv)) << x.csv;
      std::ifstream in(x.csv);
      std::string header;
      std::getline(in, header);
      EXPECT_EQ(header, kTuningCsvHeader);
    }
  }

  // 9. The configuration with the recommendations, and the demo program.
  write_config(generate_config(s, dir.path(), "machine"));
  std::string out;
  ASSERT_EQ(check_config(bin / "cncd", dir / "machine.ini", out), 0) << out;
  const std::string ini = e2e::read_text(dir / "machine.ini");
  char want[64];
  std::snprintf(want, sizeof want, "FERROR = %.10g\n", s.axis('X')->tuning->ferror);
  EXPECT_NE(ini.find(want), std::string::npos) << ini;
  ControllerProcess d(bin, dir / "machine.ini", dir / "cncd-final.log");
  auto must = [&](const std::string& args, int timeout_s = 30) {
    const auto r = testing::run_shell("'" + (bin / "cnc").string() + "' --timeout " + std::to_string(timeout_s) + " " + args);
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
  const auto status = testing::run_shell("'" + (bin / "cnc").string() + "' status --json");
  const auto js = nlohmann::json::parse(status.text);
  EXPECT_EQ(js["task"]["interp_state"], "IDLE") << status.text;
  EXPECT_EQ(js["task"]["state"], "ON") << status.text;  // no following-error trip on the way
  const double expect[3] = {180, 110, 0};
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(js["motion"]["position"][j].get<double>(), expect[j], 1e-6) << letters[j];
  EXPECT_EQ(d.stop(), 0);
}

}  // namespace
}  // namespace cnc::commission
