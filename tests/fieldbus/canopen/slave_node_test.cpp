#include <gtest/gtest.h>

#include <optional>

#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#include "fieldbus/canopen/sdo_client.hpp"
#include "fieldbus/canopen/slave_node.hpp"
#include "tests/fieldbus/canopen/sim.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::canopen;
using cnc::canopen::test::bytes_of;
using cnc::canopen::test::Sim;

namespace {

constexpr uint8_t kNode = 3;

class SlaveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    using D = DataType;
    using A = Access;
    od.add({0x6040, 0}, D::Unsigned16, A::ReadWrite, 0, true, "Controlword");
    od.add({0x6041, 0}, D::Unsigned16, A::ReadOnly, 0x0250, true, "Statusword");
    od.add({0x6064, 0}, D::Integer32, A::ReadOnly, 0, true, "Position actual value");
    od.add({0x607A, 0}, D::Integer32, A::ReadWrite, 0, true, "Target position");
    od.add({0x6060, 0}, D::Integer8, A::ReadWrite, 0, true, "Modes of operation");
    od.add({0x6502, 0}, D::Unsigned32, A::ReadOnly, 0x80, false, "Supported drive modes");
    od.add({0x2100, 0}, D::Unsigned64, A::ReadWrite, 0, true);
    od.add({0x2101, 0}, D::Unsigned8, A::ReadWrite, 7, false);
    node_port = sim.port("node");
    master = sim.port("master");
    SlaveOptions o;
    o.node_id = kNode;
    o.identity = {0x00020192, 0x1234, 0x55, 3, 42, "slave test"};
    node = std::make_unique<SlaveNode>(od, *node_port, o);
    client = std::make_unique<SdoClient>(*master, kNode);
    sim.actors.push_back([this](int64_t now) { node->process(now); });
    sim.actors.push_back([this](int64_t now) {
      can::Frame f;
      while (master->receive(f)) client->on_frame(f, now);
      client->poll(now);
    });
  }

  void send(uint32_t id, std::vector<uint8_t> bytes) {
    master->send(can::Frame::make(id, bytes.data(), bytes.size()));
    sim.run_for(500'000);
  }
  void nmt(NmtCommand c, uint8_t target = kNode) { send(0x000, {static_cast<uint8_t>(c), target}); }
  void sync(std::optional<uint8_t> counter = std::nullopt) {
    if (counter) send(0x080, {*counter});
    else send(0x080, {});
  }
  uint32_t write(ObjectAddress a, std::vector<uint8_t> data) {
    std::optional<SdoResult> r;
    client->download(a, std::move(data), [&](const SdoResult& x) { r = x; });
    EXPECT_TRUE(sim.run_until([&] { return r.has_value(); }));
    return r ? r->abort_code : 0xFFFFFFFF;
  }
  uint32_t write_u32(ObjectAddress a, uint32_t v) { return write(a, {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)}); }
  uint32_t write_u16(ObjectAddress a, uint16_t v) { return write(a, {uint8_t(v), uint8_t(v >> 8)}); }
  uint32_t write_u8(ObjectAddress a, uint8_t v) { return write(a, {v}); }

  // The remap procedure of CiA 301: disable, clear, entries, count, enable.
  void map_pdo(bool tpdo, unsigned n, std::vector<uint32_t> entries, uint8_t type) {
    const uint16_t comm = tpdo ? tpdo_comm_index(n) : rpdo_comm_index(n);
    const uint16_t map = tpdo ? tpdo_map_index(n) : rpdo_map_index(n);
    const uint32_t cob = default_pdo_cob(tpdo, n, kNode);
    ASSERT_EQ(write_u32({comm, 1}, cob | cob::kPdoInvalid), 0u);
    ASSERT_EQ(write_u8({map, 0}, 0), 0u);
    for (std::size_t i = 0; i < entries.size(); ++i) ASSERT_EQ(write_u32({map, static_cast<uint8_t>(i + 1)}, entries[i]), 0u);
    ASSERT_EQ(write_u8({map, 0}, static_cast<uint8_t>(entries.size())), 0u);
    ASSERT_EQ(write_u8({comm, 2}, type), 0u);
    ASSERT_EQ(write_u32({comm, 1}, cob), 0u);
  }
  void start() {
    node->start(sim.now());
    sim.run_for(1'000'000);
  }

  Sim sim;
  ObjectDictionary od;
  std::unique_ptr<can::VirtualPort> node_port, master;
  std::unique_ptr<SlaveNode> node;
  std::unique_ptr<SdoClient> client;
};

}  // namespace

TEST_F(SlaveTest, BootUpMessageThenPreOperational) {
  start();
  const auto hb = sim.frames_with_id(0x700 + kNode);
  ASSERT_EQ(hb.size(), 1u);
  EXPECT_EQ(bytes_of(hb[0]), (std::vector<uint8_t>{0x00}));
  EXPECT_EQ(node->state(), NmtState::PreOperational);
}

TEST_F(SlaveTest, HeartbeatFollowsTheProducerTimeAndTheState) {
  start();
  ASSERT_EQ(write_u16({0x1017, 0}, 100), 0u);
  sim.log.clear();
  sim.run_for(1'000'000'000);
  auto hb = sim.frames_with_id(0x700 + kNode);
  ASSERT_EQ(hb.size(), 10u);
  EXPECT_EQ(hb[0].data[0], 0x7F);
  for (std::size_t i = 1; i < hb.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(hb[i].timestamp_ns - hb[i - 1].timestamp_ns), 100e6, 100e3);
  }
  nmt(NmtCommand::Start);
  sim.log.clear();
  sim.run_for(200'000'000);
  hb = sim.frames_with_id(0x700 + kNode);
  ASSERT_FALSE(hb.empty());
  EXPECT_EQ(hb.back().data[0], 0x05);
}

TEST_F(SlaveTest, NmtCommandsByNodeAndBroadcast) {
  std::vector<NmtState> states;
  node->on_state_change = [&](NmtState s) { states.push_back(s); };
  start();
  nmt(NmtCommand::Start, kNode + 1);
  EXPECT_EQ(node->state(), NmtState::PreOperational) << "addressed to another node";
  nmt(NmtCommand::Start, 0);
  EXPECT_EQ(node->state(), NmtState::Operational);
  nmt(NmtCommand::Stop);
  EXPECT_EQ(node->state(), NmtState::Stopped);
  nmt(NmtCommand::EnterPreOperational);
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(states, (std::vector<NmtState>{NmtState::PreOperational, NmtState::Operational, NmtState::Stopped,
                                           NmtState::PreOperational}));
}

TEST_F(SlaveTest, ResetsRestoreDefaultsAndBootAgain) {
  bool app_reset = false;
  node->on_reset_application = [&] { app_reset = true; };
  start();
  ASSERT_EQ(write_u16({0x1017, 0}, 50), 0u);
  ASSERT_EQ(write_u8({0x2101, 0}, 99), 0u);
  nmt(NmtCommand::Start);
  sim.log.clear();
  nmt(NmtCommand::ResetCommunication);
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(od.get<uint16_t>({0x1017, 0}), 0) << "communication area back to defaults";
  EXPECT_EQ(od.get<uint8_t>({0x2101, 0}), 99) << "application area kept";
  EXPECT_FALSE(app_reset);
  ASSERT_FALSE(sim.frames_with_id(0x700 + kNode).empty());
  EXPECT_EQ(sim.frames_with_id(0x700 + kNode)[0].data[0], 0x00) << "boot-up";
  nmt(NmtCommand::ResetNode);
  EXPECT_TRUE(app_reset);
  EXPECT_EQ(od.get<uint8_t>({0x2101, 0}), 7);
}

TEST_F(SlaveTest, StoppedNodeAnswersNoSdo) {
  start();
  nmt(NmtCommand::Stop);
  std::optional<SdoResult> r;
  client->upload({0x1000, 0}, [&](const SdoResult& x) { r = x; });
  ASSERT_TRUE(sim.run_until([&] { return r.has_value(); }));
  EXPECT_EQ(r->abort_code, abort_code::kTimeout);
}

TEST_F(SlaveTest, PdoMappingRoundTripAppliesAtSyncAndSamplesAtSync) {
  start();
  map_pdo(false, 1, {0x60400010, 0x607A0020}, 1);
  map_pdo(true, 1, {0x60410010, 0x60640020}, 1);
  std::vector<int32_t> seen_in_sync;
  node->on_sync = [&](uint8_t, int64_t) {
    seen_in_sync.push_back(od.get<int32_t>({0x607A, 0}));
    od.set<int32_t>({0x6064, 0}, od.get<int32_t>({0x607A, 0}));  // the plant follows
  };
  nmt(NmtCommand::Start);
  sim.log.clear();
  send(0x200 + kNode, {0x0F, 0x00, 0x10, 0x27, 0x00, 0x00});  // controlword 0x000F, target 10000
  EXPECT_EQ(od.get<uint16_t>({0x6040, 0}), 0) << "synchronous RPDOs wait for the SYNC";
  sync();
  EXPECT_EQ(od.get<uint16_t>({0x6040, 0}), 0x000F);
  EXPECT_EQ(od.get<int32_t>({0x607A, 0}), 10000);
  auto tpdo = sim.frames_with_id(0x180 + kNode);
  ASSERT_EQ(tpdo.size(), 1u);
  EXPECT_EQ(bytes_of(tpdo[0]), (std::vector<uint8_t>{0x50, 0x02, 0, 0, 0, 0})) << "position sampled at the SYNC, before the cycle";
  sync();
  tpdo = sim.frames_with_id(0x180 + kNode);
  ASSERT_EQ(tpdo.size(), 2u);
  EXPECT_EQ(get_le<int32_t>(&tpdo[1].data[2]), 10000) << "one cycle later";
  EXPECT_EQ(seen_in_sync, (std::vector<int32_t>{10000, 10000}));
  EXPECT_EQ(od.get<uint32_t>({0x1A00, 1}), 0x60410010u);
  EXPECT_EQ(od.get<uint8_t>({0x1A00, 0}), 2);
}

TEST_F(SlaveTest, MappingWritesAreValidated) {
  start();
  map_pdo(false, 1, {0x60400010}, 1);
  const uint16_t comm = 0x1400, map = 0x1600;
  EXPECT_EQ(write_u32({map, 1}, 0x607A0020), abort_code::kUnsupportedAccess) << "PDO valid";
  ASSERT_EQ(write_u32({comm, 1}, cob::rpdo(1, kNode) | cob::kPdoInvalid), 0u);
  EXPECT_EQ(write_u32({map, 1}, 0x607A0020), abort_code::kUnsupportedAccess) << "sub 0 not cleared";
  ASSERT_EQ(write_u8({map, 0}, 0), 0u);
  EXPECT_EQ(write_u32({map, 1}, 0x65020020), abort_code::kNotMappable) << "not PDO-mappable";
  EXPECT_EQ(write_u32({map, 1}, 0x60410010), abort_code::kNotMappable) << "read-only in an RPDO";
  EXPECT_EQ(write_u32({map, 1}, 0x70000010), abort_code::kNoObject);
  EXPECT_EQ(write_u32({map, 1}, 0x607A0010), abort_code::kNotMappable) << "wrong length";
  ASSERT_EQ(write_u32({map, 1}, 0x21000040), 0u);
  ASSERT_EQ(write_u32({map, 2}, 0x60400010), 0u);
  EXPECT_EQ(write_u8({map, 0}, 2), abort_code::kPdoLength) << "80 bits";
  EXPECT_EQ(write_u8({map, 0}, 9), abort_code::kValueTooHigh);
  ASSERT_EQ(write_u32({map, 1}, 0x00050008), 0u) << "a dummy byte";
  ASSERT_EQ(write_u8({map, 0}, 2), 0u);
  EXPECT_EQ(write_u8({comm, 2}, 245), abort_code::kValueRange) << "reserved transmission type";
  EXPECT_EQ(write_u8({comm, 2}, 252), abort_code::kValueRange) << "RTR types are TPDO-only";
  ASSERT_EQ(write_u32({comm, 1}, cob::rpdo(1, kNode)), 0u);
  EXPECT_EQ(write_u32({comm, 1}, 0x321), abort_code::kValueRange) << "identifier of a valid PDO";
  EXPECT_EQ(write_u32({0x1800, 1}, 0x20000181), abort_code::kValueRange) << "29-bit identifiers";
}

TEST_F(SlaveTest, DummyEntriesSkipBytes) {
  start();
  map_pdo(false, 1, {0x00050008, 0x60400010}, 255);
  nmt(NmtCommand::Start);
  int applied = 0;
  node->on_rpdo = [&](unsigned n) { applied += static_cast<int>(n); };
  send(0x200 + kNode, {0xAA, 0x34, 0x12});
  EXPECT_EQ(od.get<uint16_t>({0x6040, 0}), 0x1234) << "event-driven RPDO applied at once";
  EXPECT_EQ(applied, 1);
}

TEST_F(SlaveTest, TransmissionTypesOfTpdos) {
  start();
  map_pdo(true, 1, {0x60410010}, 3);    // every 3rd SYNC
  map_pdo(true, 2, {0x60640020}, 0);    // synchronous, on change
  map_pdo(true, 3, {0x60400010}, 254);  // event timer
  ASSERT_EQ(write_u16({0x1802, 5}, 10), 0u);
  nmt(NmtCommand::Start);
  sim.log.clear();
  for (int i = 0; i < 9; ++i) sync();
  EXPECT_EQ(sim.frames_with_id(0x180 + kNode).size(), 3u);
  EXPECT_EQ(sim.frames_with_id(0x280 + kNode).size(), 1u) << "type 0: sent once, then only on change";
  od.set<int32_t>({0x6064, 0}, 5);
  sync();
  EXPECT_EQ(sim.frames_with_id(0x280 + kNode).size(), 2u);
  sim.log.clear();
  sim.run_for(100'000'000);
  const auto ev = sim.frames_with_id(0x380 + kNode);
  EXPECT_GE(ev.size(), 9u);
  EXPECT_LE(ev.size(), 11u);
}

// A device's processing time (SlaveOptions::sync_response_ns, the
// simulated drives' SYNC_RESPONSE_US): the TPDO sampled at a SYNC is
// queued that long after the SYNC's reception, not at once.
TEST_F(SlaveTest, SynchronousTpdosGoAfterTheDevicesSyncResponseTime) {
  for (const int64_t response : {int64_t{0}, int64_t{300'000}}) {
    SlaveOptions o;
    o.node_id = kNode;
    o.sync_response_ns = response;
    node = std::make_unique<SlaveNode>(od, *node_port, o);
    start();
    map_pdo(true, 1, {0x60410010}, 1);
    nmt(NmtCommand::Start);
    sim.log.clear();
    sync();
    const auto s = sim.frames_with_id(0x080);
    const auto t = sim.frames_with_id(0x180 + kNode);
    ASSERT_EQ(s.size(), 1u);
    ASSERT_EQ(t.size(), 1u);
    // Received at the end of the frames: the TPDO's own 75 bit times
    // (2 bytes, 1 Mbit/s) after it was queued, plus one 20 us step.
    const int64_t after_sync = t[0].timestamp_ns - s[0].timestamp_ns;
    EXPECT_GE(after_sync, response + 60'000) << response;
    EXPECT_LE(after_sync, response + 120'000) << response;
  }
}

TEST_F(SlaveTest, SyncStartValueWaitsForTheCounter) {
  start();
  ASSERT_EQ(write_u8({0x1019, 0}, 10), 0u);
  map_pdo(true, 1, {0x60410010}, 2);
  ASSERT_EQ(write_u32({0x1800, 1}, cob::tpdo(1, kNode) | cob::kPdoInvalid), 0u);
  ASSERT_EQ(write_u8({0x1800, 6}, 4), 0u);
  ASSERT_EQ(write_u32({0x1800, 1}, cob::tpdo(1, kNode)), 0u);
  nmt(NmtCommand::Start);
  sim.log.clear();
  std::vector<uint8_t> sent_at;
  for (uint8_t c = 1; c <= 10; ++c) {
    sync(c);
    if (sim.frames_with_id(0x180 + kNode).size() > sent_at.size()) sent_at.push_back(c);
  }
  EXPECT_EQ(sent_at, (std::vector<uint8_t>{4, 6, 8, 10}));
  EXPECT_EQ(node->counters().last_sync_counter, 10);
}

TEST_F(SlaveTest, SyncWithoutTheExpectedCounterRaisesEmcy8240) {
  start();
  ASSERT_EQ(write_u8({0x1019, 0}, 5), 0u);
  nmt(NmtCommand::Start);
  sim.log.clear();
  sync();
  const auto e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 1u);
  Emcy m;
  ASSERT_TRUE(decode_emcy(e[0], m));
  EXPECT_EQ(m.code, 0x8240);
  EXPECT_TRUE(m.error_register & kErrRegCommunication);
  EXPECT_EQ(write_u8({0x1019, 0}, 1), abort_code::kValueRange);
}

TEST_F(SlaveTest, ShortRpdoAndMissedDeadlineRaiseEmcy) {
  start();
  map_pdo(false, 1, {0x60400010, 0x607A0020}, 255);
  ASSERT_EQ(write_u16({0x1400, 5}, 20), 0u);
  unsigned timeouts = 0;
  node->on_rpdo_timeout = [&](unsigned n) { timeouts += n; };
  nmt(NmtCommand::Start);
  sim.log.clear();
  send(0x200 + kNode, {1, 2, 3});
  auto e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(get_le<uint16_t>(&e[0].data[0]), 0x8210);
  sim.run_for(50'000'000);
  EXPECT_EQ(timeouts, 0u) << "the deadline starts with the first good RPDO";
  send(0x200 + kNode, {1, 2, 3, 4, 5, 6});
  sim.run_for(19'000'000);
  EXPECT_EQ(timeouts, 0u);
  sim.run_for(2'000'000);
  EXPECT_EQ(timeouts, 1u);
  e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(get_le<uint16_t>(&e[1].data[0]), 0x8250);
}

TEST_F(SlaveTest, HeartbeatConsumerDetectsALostMaster) {
  start();
  ASSERT_EQ(write_u32({0x1016, 1}, (0x7Fu << 16) | 50), 0u);
  EXPECT_EQ(write_u32({0x1016, 2}, (0x7Fu << 16) | 80), abort_code::kParameterIncompatible) << "same node twice";
  std::vector<uint8_t> lost;
  node->on_heartbeat_lost = [&](uint8_t n) { lost.push_back(n); };
  sim.run_for(200'000'000);
  EXPECT_TRUE(lost.empty()) << "monitoring starts with the first heartbeat";
  for (int i = 0; i < 5; ++i) {
    send(0x77F, {0x05});
    sim.run_for(30'000'000);
  }
  EXPECT_TRUE(lost.empty());
  sim.log.clear();
  sim.run_for(60'000'000);
  EXPECT_EQ(lost, (std::vector<uint8_t>{0x7F}));
  const auto e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(get_le<uint16_t>(&e[0].data[0]), 0x8130);
}

// A device whose loop runs late reads a heartbeat with its reception
// time after the consumer time ran out: that is a loss, not a rescue.
TEST_F(SlaveTest, AHeartbeatHeardAfterTheConsumerTimeStillTripsIt) {
  start();
  ASSERT_EQ(write_u32({0x1016, 1}, (0x7Fu << 16) | 50), 0u);
  std::vector<uint8_t> lost;
  node->on_heartbeat_lost = [&](uint8_t n) { lost.push_back(n); };
  const can::Frame hb = can::Frame::make(0x77F, {0x05});
  const int64_t t0 = sim.now();
  node->on_frame(hb, t0);
  node->on_frame(hb, t0 + 40'000'000);
  EXPECT_TRUE(lost.empty());
  node->on_frame(hb, t0 + 40'000'000 + 51'000'000);  // no poll in between
  EXPECT_EQ(lost, (std::vector<uint8_t>{0x7F}));
  EXPECT_EQ(node->counters().heartbeats_lost, 1u);
  node->poll(t0 + 40'000'000 + 60'000'000);
  EXPECT_EQ(lost.size(), 1u) << "heard again: monitoring goes on, no second trip";
}

TEST_F(SlaveTest, EmcyInhibitTimeHistoryAndReset) {
  start();
  ASSERT_EQ(write_u16({0x1015, 0}, 100), 0u);  // 10 ms
  sim.log.clear();
  const uint8_t vendor[5] = {1, 2, 3, 4, 5};
  node->emcy(0x2310, kErrRegCurrent, vendor);
  node->emcy(0x4210, kErrRegTemperature);
  sim.run_for(5'000'000);
  auto e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 1u) << "the second waits for the inhibit time";
  EXPECT_EQ(bytes_of(e[0]), (std::vector<uint8_t>{0x10, 0x23, 0x03, 1, 2, 3, 4, 5}));
  sim.run_for(10'000'000);
  e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_GE(e[1].timestamp_ns - e[0].timestamp_ns, 10'000'000);
  EXPECT_EQ(e[1].data[2], kErrRegGeneric | kErrRegCurrent | kErrRegTemperature);
  EXPECT_EQ(od.get<uint8_t>({0x1003, 0}), 2);
  EXPECT_EQ(od.get<uint32_t>({0x1003, 1}), 0x4210u) << "newest first";
  EXPECT_EQ(od.get<uint32_t>({0x1003, 2}), 0x2310u);
  sim.run_for(20'000'000);
  node->clear_emcy();
  sim.run_for(1'000'000);
  e = sim.frames_with_id(0x080 + kNode);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_EQ(bytes_of(e[2]), (std::vector<uint8_t>{0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<uint8_t>({0x1001, 0}), 0);
  ASSERT_EQ(write_u8({0x1003, 0}, 0), 0u);
  EXPECT_EQ(od.get<uint32_t>({0x1003, 1}), 0u);
  EXPECT_EQ(write_u8({0x1003, 0}, 1), abort_code::kValueRange);
}

TEST_F(SlaveTest, NodeGuardingAnswersWithAToggle) {
  start();
  sim.log.clear();
  master->send(can::Frame::remote(0x700 + kNode, 1));
  sim.run_for(500'000);
  master->send(can::Frame::remote(0x700 + kNode, 1));
  sim.run_for(500'000);
  const auto r = sim.frames_with_id(0x700 + kNode);
  std::vector<uint8_t> answers;
  for (const auto& f : r) {
    if (!f.is_remote()) answers.push_back(f.data[0]);
  }
  EXPECT_EQ(answers, (std::vector<uint8_t>{0x7F, 0xFF}));
}

TEST_F(SlaveTest, RemoteRequestedTpdo) {
  start();
  map_pdo(true, 1, {0x60410010}, 253);
  nmt(NmtCommand::Start);
  sim.log.clear();
  master->send(can::Frame::remote(0x180 + kNode, 2));
  sim.run_for(500'000);
  std::vector<can::Frame> data;
  for (const auto& f : sim.frames_with_id(0x180 + kNode)) {
    if (!f.is_remote()) data.push_back(f);
  }
  ASSERT_EQ(data.size(), 1u);
  EXPECT_EQ(bytes_of(data[0]), (std::vector<uint8_t>{0x50, 0x02}));
}

TEST_F(SlaveTest, CyclicProcessingDoesNotAllocate) {
  start();
  map_pdo(false, 1, {0x60400010, 0x607A0020}, 1);
  map_pdo(true, 1, {0x60410010, 0x60640020}, 1);
  node->on_sync = [&](uint8_t, int64_t) { od.set<int32_t>({0x6064, 0}, od.get<int32_t>({0x607A, 0})); };
  nmt(NmtCommand::Start);
  auto drive_port = std::move(master);  // raw frames only from here on
  sim.actors.pop_back();
  int64_t now = sim.now();
  uint64_t allocations = 0;
  for (int cycle = 0; cycle < 2000; ++cycle) {
    uint8_t rpdo[6] = {0x0F, 0, 0, 0, 0, 0};
    put_le<int32_t>(rpdo + 2, cycle);
    drive_port->send(can::Frame::make(0x200 + kNode, rpdo, 6));
    drive_port->send(can::Frame::make(0x080, {}));
    sim.bus->advance(1'000'000);
    now += 1'000'000;
    can::Frame f;
    cnc::testing::ScopedAllocationCheck check;
    node->process(now);
    while (drive_port->receive(f)) {}
    allocations += check.allocations();
  }
  if (cnc::testing::AllocationCounter::available()) {
    EXPECT_EQ(allocations, 0u);
  }
  EXPECT_EQ(od.get<int32_t>({0x6064, 0}), 1999);
  EXPECT_EQ(node->counters().tpdos, 2000u);
}
