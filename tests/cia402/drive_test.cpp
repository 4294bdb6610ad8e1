// The master-side drive control against simulated drives over CANopen on a
// virtual bus (tests/cia402/rig.hpp): enable, disable, faults, modes,
// homing, probes, scaling, following error, watchdog, lost master.
#include <gtest/gtest.h>

#include <cmath>

#include "tests/cia402/rig.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::cia402;
using cnc::cia402::test::Rig;
using cnc::cia402::test::one_axis_ini;

TEST(Cia402Drive, EnablesThroughEveryStateAndFollows) {
  Rig rig(one_axis_ini());
  rig.configure();
  rig.cycles(50);
  EXPECT_EQ(rig.fb().state, State::SwitchOnDisabled);
  EXPECT_EQ(rig.fb().mode_display, Mode::CyclicSyncPosition);
  ASSERT_TRUE(rig.enable()) << rig.drain_messages().size();
  EXPECT_EQ(rig.fb().state, State::OperationEnabled);
  EXPECT_EQ(rig.sim().state(), State::OperationEnabled);
  const double start = rig.fb().pos_fb;
  // A 10 mm move at 50 mm/s.
  double cmd = start;
  rig.cycles(400, [&](Rig& r) {
    cmd = std::min(cmd + 0.05, start + 10.0);
    r.cmd().pos_cmd = cmd;
  });
  rig.cycles(100, [&](Rig& r) { r.cmd().pos_cmd = cmd; });
  EXPECT_NEAR(rig.fb().pos_fb, start + 10.0, 0.002);
  EXPECT_NEAR(rig.sim().plant().table_position() * 1000.0, start + 10.0, 0.01);
}

TEST(Cia402Drive, DebugTrace) {
  Rig rig(one_axis_ini());
  rig.configure();
  rig.cycles(30);
  ASSERT_TRUE(rig.enable());
  printf("enabled at cycle %llu pos %.6f\n", (unsigned long long)rig.cycle_count(), rig.fb().pos_fb);
  const double start = rig.fb().pos_fb;
  double cmd = start, maxfe = 0, maxsimfe=0;
  for (int i = 0; i < 600; ++i) {
    rig.cycle([&](Rig& r) { cmd = std::min(cmd + 0.05, start + 10.0); r.cmd().pos_cmd = cmd; });
    maxfe = std::max(maxfe, std::fabs(rig.fb().ferror));
    maxsimfe = std::max(maxsimfe, std::fabs(rig.sim().following_error()));
    if (i >= 100 && i < 104) printf("  sim: omega %.3f rad/s torque %.4f demand %.1f meas %.1f fe %.2f vel_act %d\n", rig.sim().plant().motor_velocity(), rig.sim().plant().torque(), rig.sim().demand(), (double)rig.sim().position(), rig.sim().following_error(), (int)rig.sim().plant().encoder());
    if (i % 100 == 0) printf("i %d cmd %.4f fb %.4f fe %.5f vel %.3f torque %.2f sw 0x%04X table %.4f\n", i, cmd, rig.fb().pos_fb, rig.fb().ferror, rig.fb().vel_fb, rig.fb().torque, rig.fb().statusword, rig.sim().plant().table_position()*1000);
  }
  printf("max ferror %.5f mm, sim %.1f counts\n", maxfe, maxsimfe);
  for (auto& l : rig.drain_messages()) printf("%s\n", l.c_str());
}
