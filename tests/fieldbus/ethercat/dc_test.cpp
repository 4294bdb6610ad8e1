// Distributed clocks: delays and offsets from latched times, the phase
// lock's controller, and the simulated slaves' drift loops.
#include <gtest/gtest.h>

#include "fieldbus/ethercat/dc.hpp"
#include "tests/fieldbus/ethercat/bus.hpp"

namespace cnc::ethercat {
namespace {

TEST(EthercatDc, LineDelaysFromPortTimes) {
  // Four slaves, 800 ns per hop each way: the frame passes slave i at
  // t + 800 i and comes back on its port 1 at t + 800 (6 - i).
  std::vector<PortTimes> t(4);
  const int64_t local0[4] = {1'000'000, 50'000'000, 7, 123'456'789'000};
  for (int i = 0; i < 4; ++i) {
    t[i].port0 = static_cast<uint32_t>(local0[i] + 800 * i);
    t[i].port1 = static_cast<uint32_t>(local0[i] + 800 * (6 - i));
    t[i].port1_open = i < 3;
    t[i].local_at_latch = local0[i] + 800 * i;
  }
  const auto d = line_delays(t);
  EXPECT_EQ(d, (std::vector<int64_t>{0, 800, 1600, 2400}));
  const auto o = system_offsets(t, d, 5'000);
  EXPECT_EQ(o[0], 5'000);
  for (int i = 1; i < 4; ++i) {
    // System time of slave i at its latch = reference system time at the latch + delay.
    EXPECT_EQ(t[i].local_at_latch + o[i], t[0].local_at_latch + 5'000 + d[i]);
  }
}

TEST(EthercatDc, PortTimesWrapAround32Bits) {
  std::vector<PortTimes> t(2);
  t[0] = {0xFFFFFF00u, 0x00000100u, true, 0};
  t[1] = {0x10u, 0x10u, false, 0};
  EXPECT_EQ(line_delays(t)[1], 0x200 / 2);
}

TEST(EthercatDc, PhaseLockFollowsADriftingClock) {
  PhaseLock::Options o;
  o.cycle_ns = 250'000;
  PhaseLock lock(o);
  // The reference runs 40 ppm fast and starts 100 us into its cycle.
  int64_t wake = 0;
  for (int k = 0; k < 5000; ++k) {
    const int64_t st = 100'000 + static_cast<int64_t>(static_cast<double>(wake) * (1 + 40e-6));
    wake += o.cycle_ns + lock.update(st);
  }
  EXPECT_TRUE(lock.is_locked());
  EXPECT_LT(std::abs(lock.offset_ns()), 50);
  EXPECT_LT(lock.stats().max_abs, 5'000);
  EXPECT_NEAR(lock.stats().mean, 0, 100);
}

TEST(EthercatDc, OffsetStatistics) {
  OffsetStats s;
  for (int v : {-2, 4, 4, 4, 5, 5, 7, 9}) s.add(v);
  EXPECT_EQ(s.count, 8u);
  EXPECT_DOUBLE_EQ(s.mean, 4.5);
  EXPECT_NEAR(s.stddev(), 3.16, 0.01);
  EXPECT_EQ(s.min, -2);
  EXPECT_EQ(s.max, 9);
  EXPECT_EQ(s.max_abs, 9);
}

TEST(EthercatDc, SlaveClocksAgreeAfterSetUp) {
  test::Bus bus(4);
  ASSERT_TRUE(bus.master->uses_dc());
  const auto& s = bus.master->slaves();
  EXPECT_EQ(s[0].dc_delay_ns, 0);
  EXPECT_EQ(s[1].dc_delay_ns, 750);  // the segment's hop delay
  EXPECT_EQ(s[3].dc_delay_ns, 2250);
  const int64_t t = bus.time.load();
  for (std::size_t i = 1; i < 4; ++i) {
    // After the static drift compensation every system time matches the
    // reference's within a microsecond despite clocks drifting by tens of ppm.
    const int64_t diff = bus.segment->slave(i).system_time(t + 750 * static_cast<int64_t>(i)) -
                         bus.segment->slave(0).system_time(t) - 750 * static_cast<int64_t>(i);
    EXPECT_LT(std::abs(diff), 1000) << "slave " << i + 1;
  }
  EXPECT_TRUE(bus.segment->slave(2).sync0_active());
  EXPECT_EQ(bus.segment->slave(2).sync0_cycle_ns(), 1'000'000u);
  EXPECT_EQ(bus.segment->drive(2)->od().get<uint16_t>({0x1C32, 1}), 2);  // DC SYNC0
}

}  // namespace
}  // namespace cnc::ethercat
