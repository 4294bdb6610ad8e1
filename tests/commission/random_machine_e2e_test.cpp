// Bring-up of part of a machine on cncd (label slow): a drive disabled in
// the configuration and missing from the bus. (The randomised machine's
// steps 1-4 and 9 end to end are in full_run_e2e_test.cpp, with all the
// other steps.)
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
