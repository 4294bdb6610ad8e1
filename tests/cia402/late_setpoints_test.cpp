// Set-points that arrive late and in bursts, as on the emulated machine of
// the VM test (tests/cia402/vm): the master's cycles come late at random,
// and the drives' process stalls in the middle of a pass, so that the
// frames queued meanwhile are read together by a pass whose clock was read
// before the stall. There the X drive ran away (hundreds of millimetres,
// then EMCY 0x8611): the SYNCs read by such a pass all got the pass's old
// time, each restarted the drive's interpolation with no time between them,
// the demand fell behind by one set-point per SYNC and caught up in one
// period, the torque saturated and the velocity loop wound up.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>

#include "tests/cia402/rig.hpp"

using namespace cnc;
using namespace cnc::cia402;
using cnc::cia402::test::one_axis_ini;
using cnc::cia402::test::Rig;

namespace {

constexpr double kCountsPerMm = 2000;

// The VM test's cycle and drives (tests/cia402/vm): 10 ms, 200 us plant steps, 100 Hz
// velocity loop, generous timeouts, a 5 mm following-error window.
void vm_like(ini::IniFile& ini) {
  ini.set("EMCMOT", "SERVO_PERIOD", "10000000");
  ini.set("CANOPEN", "PDO_MISS_LIMIT", "0");
  // The VM's stalls are ridden through: no stale-feedback budget either.
  ini.set("CIA402", "STALE_LIMIT", "0");
  ini.set("CANOPEN_NODE_1", "HEARTBEAT_TIMEOUT_MS", "60000");
  ini.set("CANOPEN_NODE_1", "MASTER_HEARTBEAT_TIMEOUT_MS", "60000");
  ini.set("CIA402_DRIVE_0", "FERROR_WINDOW", "5");
  ini.set("CIA402_DRIVE_0", "FERROR_TIMEOUT_MS", "50");
  ini.set("CIA402_DRIVE_0", "ENABLE_TIMEOUT_MS", "10000");
  ini.set("CIA402_SIM", "STEP_US", "200");
  ini.set("CIA402_SIM_NODE_1", "VELOCITY_BANDWIDTH", "100");
  ini.set("CIA402_SIM_NODE_1", "SYNC_TIMEOUT_MS", "10000");
}

// Back and forth between 0 and 20 mm at 20 mm/s, 200 mm/s^2, one 10 ms
// cycle per call (what motion commands, cycle by cycle).
struct BackAndForth {
  double p = 0, v = 0, goal = 20;
  double next() {
    constexpr double kVmax = 20, kAccel = 200, kDt = 0.01;
    const double d = goal - p;
    const double want = std::copysign(std::min(kVmax, std::sqrt(2 * kAccel * std::fabs(d))), d);
    v = want > v ? std::min(want, v + kAccel * kDt) : std::max(want, v - kAccel * kDt);
    p += v * kDt;
    if (std::fabs(goal - p) < 1e-3 && std::fabs(v) < 1e-3) goal = goal > 10 ? 0 : 20;
    return p;
  }
};

}  // namespace

TEST(Cia402LateSetPoints, FramesReadByAStalledPassKeepTheirReceptionTimes) {
  Rig rig(one_axis_ini(), vm_like);
  rig.configure();
  rig.cycles(20);
  ASSERT_TRUE(rig.enable());
  BackAndForth path;
  path.p = rig.fb().pos_fb;
  rig.cycles(30, [&](Rig& r) { r.cmd().pos_cmd = path.next(); });  // cruising at 20 mm/s
  // The drives' process stalls for 85 ms: 8 SYNCs with their set-points
  // wait in its socket, then one pass reads them all.
  const int64_t stall_from = rig.now(), stall_to = stall_from + 85'000'000;
  rig.sim_stalled = [&](int64_t now) { return now >= stall_from && now < stall_to; };
  double lag_counts = -1;
  bool stalled = false;
  rig.after_step = [&](Rig& r) {
    const bool now_stalled = r.sim_stalled(r.now());
    if (stalled && !now_stalled && lag_counts < 0) {
      // Right after the pass that read the backlog: each SYNC ran its own
      // period, so the demand is at the last set-point received.
      lag_counts = std::fabs(r.host().at(0).od().get<int32_t>({0x607A, 0}) - r.sim().demand());
    }
    stalled = now_stalled;
  };
  rig.cycles(12, [&](Rig& r) { r.cmd().pos_cmd = path.next(); });
  ASSERT_GE(lag_counts, 0.0) << "the stall did not end inside the cycles run";
  EXPECT_LT(lag_counts, 1.0) << "the drive's demand lags its newest set-point by " << lag_counts / kCountsPerMm
                             << " mm after reading a backlog of SYNCs";
  EXPECT_EQ(rig.sim().state(), State::OperationEnabled);
}

TEST(Cia402LateSetPoints, AnAxisRidesThroughLateCyclesAndStalledDrivesWithoutAFault) {
  for (unsigned seed = 1; seed <= 8; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::exponential_distribution<double> late_s(1.0 / 0.004);
    Rig rig(one_axis_ini(), vm_like);
    rig.configure();
    rig.cycles(20);
    ASSERT_TRUE(rig.enable());
    int64_t stall_until = 0;
    rig.sim_stalled = [&](int64_t now) { return now < stall_until; };
    double worst_drive_ferror = 0;
    bool bit13 = false;
    rig.after_step = [&](Rig& r) {
      worst_drive_ferror = std::max(worst_drive_ferror, std::fabs(r.sim().following_error()) / kCountsPerMm);
      bit13 = bit13 || (r.sim().statusword() & sw::kBit13);
    };
    BackAndForth path;
    path.p = rig.fb().pos_fb;
    for (int k = 0; k < 1500 && rig.sim().state() == State::OperationEnabled; ++k) {
      rig.cycle([&](Rig& r) { r.cmd().pos_cmd = path.next(); });
      // 30 % of the cycles come late (4 ms on average, exponential); 5 %
      // of them stall the drives' process for up to 100 ms.
      if (u(rng) < 0.3) rig.run_for(static_cast<int64_t>(late_s(rng) * 1e9) / Rig::kStepNs * Rig::kStepNs);
      if (u(rng) < 0.05) stall_until = rig.now() + static_cast<int64_t>(u(rng) * 100e6);
    }
    const double end = path.p;
    rig.cycles(50, [&](Rig& r) { r.cmd().pos_cmd = end; });
    EXPECT_EQ(rig.sim().state(), State::OperationEnabled) << "drive error 0x" << std::hex << rig.sim().error_code();
    EXPECT_FALSE(bit13) << "the drive's following-error window (5 mm) was exceeded";
    EXPECT_LT(worst_drive_ferror, 0.2);  // mm: the drive's own tracking, 20 mm/s
    EXPECT_NEAR(rig.sim().plant().table_position() * 1000.0, end, 0.01);
  }
}
