// LSS (CiA 305): the master's services against devices built on SlaveNode
// over the in-process bus on the real clock (the master blocks on answers,
// as it does on SocketCAN; the devices run in a thread of their own).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "fieldbus/canopen/lss.hpp"
#include "fieldbus/canopen/pdo.hpp"
#include "fieldbus/canopen/slave_node.hpp"
#include "sim/can/virtual_bus.hpp"

namespace cnc::canopen {
namespace {

struct Device {
  std::unique_ptr<can::VirtualPort> port;
  std::unique_ptr<ObjectDictionary> od;
  std::unique_ptr<SlaveNode> node;
};

struct Bench {
  std::shared_ptr<can::VirtualBus> bus;
  std::unique_ptr<can::VirtualPort> master_port, sniffer;
  std::vector<Device> devices;
  std::mutex m;  // the devices, between the test and the device thread
  std::atomic<bool> stop{false};
  std::thread thread;

  Bench() {
    can::VirtualBusOptions o;
    o.manual_clock = false;
    bus = can::VirtualBus::create(o);
    master_port = bus->open_port("lss-master");
    sniffer = bus->open_port("sniffer");
    // Boot-up and heartbeat messages only (the hundreds of LSS frames of a
    // fastscan would overflow its queue).
    const can::Filter f = can::Filter::range_mask(0x700, 0x780);
    sniffer->set_filters({&f, 1});
  }
  ~Bench() {
    stop = true;
    if (thread.joinable()) thread.join();
  }
  SlaveNode& add(uint8_t node_id, uint32_t serial, bool lss = true) {
    Device d;
    d.port = bus->open_port("device-" + std::to_string(devices.size()));
    d.od = std::make_unique<ObjectDictionary>();
    SlaveOptions o;
    o.node_id = node_id;
    o.lss = lss;
    o.identity = {0x402, 0xCC1, 0x0402, 0x00010000, serial, "lss test device"};
    d.node = std::make_unique<SlaveNode>(*d.od, *d.port, o);
    devices.push_back(std::move(d));
    return *devices.back().node;
  }
  void start() {
    for (auto& d : devices) d.node->start(bus->now_ns());
    thread = std::thread([this] {
      while (!stop) {
        {
          std::lock_guard<std::mutex> lock(m);
          for (auto& d : devices) d.node->process(bus->now_ns());
        }
        std::this_thread::sleep_for(std::chrono::microseconds(100));
      }
    });
  }
  // Boot-up/heartbeat frames seen so far with this identifier and first byte.
  int count(uint32_t id, uint8_t first_byte) {
    int n = 0;
    can::Frame f;
    while (sniffer->receive(f)) seen.push_back(f);
    for (const auto& s : seen) {
      if (s.id == id && s.len >= 1 && s.data[0] == first_byte) ++n;
    }
    return n;
  }
  std::vector<can::Frame> seen;
};

// A loaded test machine may leave the device thread waiting: a generous
// answer time-out (a real bus uses a few ms).
constexpr int64_t kTimeout = 200'000'000;

TEST(Lss, FastscanFindsEveryUnconfiguredDeviceAndGivesEachANodeIdItBootsWith) {
  Bench b;
  b.add(lss::kUnconfigured, 0x00001234);
  b.add(lss::kUnconfigured, 0x00001235);
  b.add(lss::kUnconfigured, 0xABCDEF01);
  SlaveNode& configured = b.add(5, 0x00001233);  // has a node-ID: takes no part
  b.start();
  lss::Master master(*b.master_port, kTimeout);

  std::set<uint32_t> serials;
  uint8_t next_id = 10;
  while (auto a = master.fastscan()) {
    EXPECT_EQ(a->vendor, 0xCC1u);
    EXPECT_EQ(a->product, 0x0402u);
    EXPECT_EQ(a->revision, 0x00010000u);
    serials.insert(a->serial);
    // The device found is in configuration mode: it answers inquiries.
    const auto inquired = master.inquire_address();
    ASSERT_TRUE(inquired.has_value());
    EXPECT_EQ(*inquired, *a);
    master.configure_node_id(next_id);
    master.store();
    master.switch_global(false);
    ++next_id;
    ASSERT_LT(next_id, 20) << "fastscan does not end";
  }
  EXPECT_EQ(serials, (std::set<uint32_t>{0x1234, 0x1235, 0xABCDEF01}));

  // Each device booted (boot-up message) under its new node-ID, with its
  // SDO server and predefined PDOs there; the configured one kept its ID.
  ASSERT_TRUE([&] {
    for (int i = 0; i < 200; ++i) {
      if (b.count(0x70A, 0) + b.count(0x70B, 0) + b.count(0x70C, 0) == 3) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }());
  std::lock_guard<std::mutex> lock(b.m);
  std::set<int> ids;
  for (int i = 0; i < 3; ++i) {
    SlaveNode& n = *b.devices[i].node;
    ids.insert(n.node_id());
    EXPECT_EQ(n.state(), NmtState::PreOperational);
    EXPECT_EQ(n.sdo_server().request_cob(), 0x600u + n.node_id());
    EXPECT_EQ(n.od().get<uint32_t>({0x1800, 1}) & 0x7FF, 0x180u + n.node_id());
    EXPECT_EQ(n.od().get<uint32_t>({0x1014, 0}), 0x80u + n.node_id());
    EXPECT_EQ(n.lss()->stored_node_id(), n.node_id());
  }
  EXPECT_EQ(ids, (std::set<int>{10, 11, 12}));
  EXPECT_EQ(configured.node_id(), 5);
}

TEST(Lss, NoUnconfiguredDeviceMeansAnEmptyFastscan) {
  Bench b;
  b.add(3, 0x77);
  b.add(4, 0x78, /*lss=*/false);
  b.start();
  lss::Master master(*b.master_port, 20'000'000);
  EXPECT_FALSE(master.any_unconfigured());
  EXPECT_FALSE(master.fastscan().has_value());
}

TEST(Lss, SelectiveSwitchChangesAConfiguredDevicesNodeIdAtItsNextReset) {
  Bench b;
  SlaveNode& n = b.add(5, 0x5555);
  b.add(6, 0x6666);
  b.start();
  lss::Master master(*b.master_port, kTimeout);
  ASSERT_TRUE(master.switch_selective({0xCC1, 0x0402, 0x00010000, 0x5555}));
  EXPECT_EQ(master.inquire(lss::kInquireNodeId), 5u);
  master.configure_node_id(9);
  master.switch_global(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    std::lock_guard<std::mutex> lock(b.m);
    EXPECT_EQ(n.node_id(), 5) << "a configured device keeps its ID until a reset";
  }
  // NMT reset communication of node 5.
  ASSERT_EQ(b.master_port->send(can::Frame::make(0x000, {0x82, 5})), can::SendStatus::Ok);
  ASSERT_TRUE([&] {
    for (int i = 0; i < 200; ++i) {
      if (b.count(0x709, 0) == 1) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
  }());
  std::lock_guard<std::mutex> lock(b.m);
  EXPECT_EQ(n.node_id(), 9);
  EXPECT_EQ(n.od().get<uint32_t>({0x1400, 1}) & 0x7FF, 0x209u);
}

TEST(Lss, WrongAddressesAndNodeIdsAreRefused) {
  Bench b;
  b.add(5, 0x5555);
  b.start();
  lss::Master master(*b.master_port, 50'000'000);
  EXPECT_FALSE(master.switch_selective({0xCC1, 0x0402, 0x00010000, 0x5556})) << "no device has that serial";
  EXPECT_THROW(master.configure_node_id(7), std::runtime_error) << "nobody is in configuration mode";
  ASSERT_TRUE(master.switch_selective({0xCC1, 0x0402, 0x00010000, 0x5555}));
  try {
    master.configure_node_id(0);
    FAIL() << "node-ID 0 accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("refused node-ID 0"), std::string::npos) << e.what();
  }
  EXPECT_THROW(master.configure_bit_timing(300'000), std::runtime_error) << "not in the table";
  master.configure_bit_timing(500'000);
}

TEST(Lss, ANodeIdOf255NeedsLssAndOthersMustBe1To127) {
  can::VirtualBusOptions o;
  auto bus = can::VirtualBus::create(o);
  auto port = bus->open_port("p");
  ObjectDictionary od1, od2;
  SlaveOptions s;
  s.node_id = lss::kUnconfigured;
  EXPECT_THROW(SlaveNode(od1, *port, s), std::invalid_argument);
  s.node_id = 0;
  s.lss = true;
  EXPECT_THROW(SlaveNode(od2, *port, s), std::invalid_argument);
}

TEST(Lss, BitRateTableOfCia305) {
  EXPECT_EQ(lss::bitrate_of_index(0), 1'000'000u);
  EXPECT_EQ(lss::bitrate_of_index(4), 125'000u);
  EXPECT_EQ(lss::bitrate_of_index(5), 0u);
  EXPECT_EQ(lss::index_of_bitrate(250'000), std::optional<uint8_t>(3));
  EXPECT_FALSE(lss::index_of_bitrate(300'000).has_value());
}

}  // namespace
}  // namespace cnc::canopen
