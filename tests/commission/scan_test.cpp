// The bus scan on simulated CiA 402 drives over the in-process CAN bus on
// the real-time clock (the drives in the simulator host's own thread), as
// it runs over SocketCAN: the scan code only sees a can::Transport.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "commission/lss_assign.hpp"
#include "commission/scan.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_host.hpp"
#include "sim/ethercat/segment.hpp"
#include "tests/commission/sim_bus_scan.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

using Bus = e2e::SimulatedCanDrives;

std::filesystem::path eds_dir() { return testing::source_dir() / "configs/canopen-mill/drives"; }

// The simulated drives run in a thread of their own, which a loaded test
// host may leave waiting for a while: a generous SDO time-out (a real bus
// scan uses the default 200 ms).
ScanOptions options() {
  ScanOptions o;
  o.timeout_ns = 1'000'000'000;
  return o;
}

TEST(CommissionScan, FindsEveryDriveWithIdentityModesEncoderAndEds) {
  Bus b;
  b.add(1);
  b.add(2);
  b.add(7);
  b.start();
  ScanOptions o = options();
  o.eds_dir = eds_dir();
  o.expected = {1, 2, 7};
  const ScanResult r = scan_canopen(*b.client, o);
  ASSERT_EQ(r.nodes.size(), 3u) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_TRUE(r.ok()) << describe(r.nodes[0]);
  const ScannedNode& n = r.nodes[2];
  EXPECT_EQ(n.node_id, 7);
  EXPECT_EQ(n.vendor_id, 0xCC1u);
  EXPECT_EQ(n.product_code, 0x402u);
  EXPECT_EQ(n.serial, 7u);
  EXPECT_EQ(n.device_type & 0xFFFF, 402u);
  EXPECT_EQ(n.name, "cnc simulated servo drive");
  EXPECT_TRUE(n.cia402);
  EXPECT_FALSE(n.fault);
  EXPECT_EQ(n.encoder_increments.value_or(0), 10000u);
  EXPECT_EQ(n.max_torque.value_or(0), 3000u) << "0x6072, the tuning's torque limit (300 % of rated)";
  EXPECT_EQ(n.eds, "servo.eds");
}

// Drives that come without node-ID (LSS, CiA 305): the scan says so, LSS
// gives them the free node-IDs after those in use, and the next scan finds
// them as drives like the others.
TEST(CommissionScan, DrivesWithoutNodeIdAreReportedThenGivenFreeIdsByLss) {
  Bus b;
  b.add(1);
  b.add(2);
  b.add(20, 0x402, 0x5000, /*lss_unconfigured=*/true);
  b.add(21, 0x402, 0x4000, /*lss_unconfigured=*/true);
  b.start();
  ScanOptions o = options();
  o.last = 10;
  o.lss_window_ns = 50'000'000;
  const ScanResult before = scan_canopen(*b.client, o);
  ASSERT_EQ(before.nodes.size(), 2u);
  ASSERT_EQ(before.problems.size(), 1u);
  EXPECT_NE(before.problems[0].find("without node-ID answer LSS"), std::string::npos) << before.problems[0];

  LssOptions lo;
  lo.first = 1;
  lo.taken = {1, 2};
  lo.window_ns = 20'000'000;  // a loaded test host (a real bus: 10 ms)
  lo.timeout_ns = 500'000'000;
  const LssResult r = assign_node_ids(*b.client, lo);
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_EQ(r.assigned.size(), 2u);
  // Fastscan finds the lower serial first.
  EXPECT_EQ(r.assigned[0].address.serial, 0x4000u);
  EXPECT_EQ(r.assigned[0].node_id, 3);
  EXPECT_EQ(r.assigned[1].address.serial, 0x5000u);
  EXPECT_EQ(r.assigned[1].node_id, 4);
  EXPECT_NE(describe(r.assigned[0]).find("serial 0x00004000 -> node-ID 3"), std::string::npos) << describe(r.assigned[0]);

  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // their boot-up
  const ScanResult after = scan_canopen(*b.client, o);
  EXPECT_TRUE(after.ok()) << (after.problems.empty() ? "" : after.problems[0]);
  ASSERT_EQ(after.nodes.size(), 4u);
  EXPECT_EQ(after.nodes[2].node_id, 3);
  EXPECT_EQ(after.nodes[2].serial, 0x4000u);
  EXPECT_TRUE(after.nodes[2].cia402);
  EXPECT_EQ(after.nodes[3].node_id, 4);
}

TEST(CommissionScan, NamesASilentExpectedNode) {
  Bus b;
  b.add(1);
  b.start();
  ScanOptions o = options();
  o.expected = {1, 4};
  o.last = 10;
  const ScanResult r = scan_canopen(*b.client, o);
  ASSERT_EQ(r.nodes.size(), 1u);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_NE(r.problems[0].find("node 4 does not answer"), std::string::npos) << r.problems[0];
  EXPECT_FALSE(r.ok());
}

TEST(CommissionScan, SaysWhenNoEdsDescribesANode) {
  Bus b;
  b.add(3, 0x999);
  b.start();
  ScanOptions o = options();
  o.eds_dir = eds_dir();
  o.last = 5;
  const ScanResult r = scan_canopen(*b.client, o);
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_TRUE(r.nodes[0].eds.empty());
  ASSERT_EQ(r.nodes[0].problems.size(), 1u);
  EXPECT_NE(r.nodes[0].problems[0].find("no description file"), std::string::npos) << r.nodes[0].problems[0];
  EXPECT_NE(r.nodes[0].problems[0].find("0x00000999"), std::string::npos);
}

TEST(CommissionScan, ReportsTwoDevicesOnOneNodeId) {
  Bus b;
  b.add(5, 0x402, 100);
  b.add(5, 0x402, 200);
  b.start();
  ScanOptions o = options();
  o.last = 8;
  const ScanResult r = scan_canopen(*b.client, o);
  ASSERT_EQ(r.nodes.size(), 1u);
  ASSERT_FALSE(r.nodes[0].problems.empty());
  EXPECT_NE(r.nodes[0].problems[0].find("two or more devices answer on node-ID 5"), std::string::npos)
      << r.nodes[0].problems[0];
}

TEST(CommissionScan, ReportsADriveInFaultWithItsErrorCode) {
  Bus b;
  b.add(2);
  b.start();
  EXPECT_EQ(b.host->inject("drive 2 encoder-loss", 1, true), "");
  ScanOptions o = options();
  o.last = 3;
  // The drive's fault reaction takes its own time: scan until it shows (a
  // loaded host may delay the simulator's thread).
  ScanResult r;
  for (int i = 0; i < 50; ++i) {
    r = scan_canopen(*b.client, o);
    if (r.nodes.size() == 1 && r.nodes[0].fault) break;
  }
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_TRUE(r.nodes[0].fault);
  ASSERT_FALSE(r.nodes[0].problems.empty());
  EXPECT_NE(r.nodes[0].problems[0].find("in fault"), std::string::npos) << r.nodes[0].problems[0];
  EXPECT_NE(r.nodes[0].problems[0].find("0x7305"), std::string::npos) << r.nodes[0].problems[0];
}

TEST(CommissionScan, AnEmptyBusGivesNoNodes) {
  Bus b;
  b.start();
  ScanOptions o = options();
  o.last = 127;
  const ScanResult r = scan_canopen(*b.client, o);
  EXPECT_TRUE(r.nodes.empty());
  EXPECT_TRUE(r.ok());
}

TEST(CommissionScan, FindsEthercatSlavesWithTheirSiiIdentityAndEsi) {
  auto segment = std::make_shared<ethercat::sim::Segment>();
  segment->add_drives(2);
  const std::string name = testing::unique_name("commission-ecat");
  ethercat::sim::register_sim_link_kind();
  ethercat::sim::register_segment(name, segment);
  const EthercatScanResult r = scan_ethercat("sim:" + name, testing::source_dir() / "configs/ethercat-mill/drives");
  ethercat::sim::unregister_segment(name);
  ASSERT_EQ(r.slaves.size(), 2u) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_TRUE(r.ok()) << describe(r.slaves[0]);
  EXPECT_EQ(r.slaves[1].position, 2u);
  EXPECT_EQ(r.slaves[0].vendor_id, 0xCC1u);
  EXPECT_EQ(r.slaves[0].product_code, 0x402u);
  EXPECT_TRUE(r.slaves[0].coe);
  EXPECT_EQ(r.slaves[0].esi, "servo.xml");
  EXPECT_EQ(r.slaves[1].max_torque.value_or(0), 3000u) << "0x6072 over CoE";
}

TEST(CommissionScan, AnEthercatSegmentThatCannotBeOpenedIsAProblem) {
  const EthercatScanResult r = scan_ethercat("sim:" + testing::unique_name("no-such-segment"), "");
  EXPECT_TRUE(r.slaves.empty());
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_FALSE(r.ok());
}

}  // namespace
}  // namespace cnc::commission
