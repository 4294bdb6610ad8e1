#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <thread>

#include "cia402/error_codes.hpp"
#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/master.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#include "tests/fieldbus/canopen/devices.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::canopen;
using cnc::canopen::test::bytes_of;
using cnc::canopen::test::EchoDevice;
using cnc::canopen::test::Sim;

namespace {

NodeConfig csp_node(uint8_t id, const std::string& name) {
  NodeConfig n;
  n.id = id;
  n.name = name;
  n.vendor_id = 0xCC1;
  n.product_code = 0x402;
  n.heartbeat_ms = 50;
  PdoConfig r;
  r.number = 1;
  r.map = {{0x6040, 0, 16}, {0x607A, 0, 32}};
  PdoConfig t;
  t.number = 1;
  t.map = {{0x6041, 0, 16}, {0x6064, 0, 32}};
  n.rpdos = {r};
  n.tpdos = {t};
  n.rpdo_kinds = {{ValueKind::Unsigned, ValueKind::Signed}};
  n.tpdo_kinds = {{ValueKind::Unsigned, ValueKind::Signed}};
  return n;
}

class MasterTest : public ::testing::Test {
 protected:
  BusConfig config(std::vector<NodeConfig> nodes) {
    BusConfig c;
    c.interface = "virtual:test";
    c.nodes = std::move(nodes);
    c.boot_timeout_ns = 200'000'000;
    c.sdo_timeout_ns = 50'000'000;
    return c;
  }
  void make_master(BusConfig c) {
    master = std::make_unique<Master>(std::move(c), sim.port("master-cyclic"), sim.port("master-acyclic"), &messages);
    sim.actors.push_back([this](int64_t now) {
      if (poll_in_steps) master->poll(now);
      if (cycle_running && now % 1'000'000 == 0) {
        master->cyclic_read(now);
        if (servo) servo(now);
        master->cyclic_write(now);
        ++cycles;
      }
    });
  }
  BootState boot() {
    master->begin_boot();
    sim.run_until([&] { return master->boot_state() != BootState::Running && master->boot_state() != BootState::Idle; },
                  5'000'000'000);
    return master->boot_state();
  }
  std::vector<std::string> errors() {
    std::vector<std::string> out;
    Message m;
    while (messages.pop(m)) {
      if (m.kind == MessageKind::Error) out.push_back(std::string(m.text.view()));
      else texts.push_back(std::string(m.text.view()));
    }
    return out;
  }

  Sim sim;
  MessageQueue messages;
  std::unique_ptr<Master> master;
  std::function<void(int64_t)> servo;
  bool poll_in_steps = true;  // false: the master's own acyclic thread polls
  bool cycle_running = true;  // false: the servo thread stopped
  uint64_t cycles = 0;
  std::vector<std::string> texts;
};

}  // namespace

TEST_F(MasterTest, BootsNodesAndExchangesProcessDataWithOneCycleTransportDelay) {
  EchoDevice a(sim, 3), b(sim, 4);
  make_master(config({csp_node(3, "x-axis"), csp_node(4, "y-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  EXPECT_TRUE(errors().empty());
  EXPECT_EQ(a.node->state(), NmtState::Operational);
  EXPECT_EQ(b.node->state(), NmtState::Operational);
  // The remap landed in the devices.
  EXPECT_EQ(a.od.get<uint32_t>({0x1600, 2}), 0x607A0020u);
  EXPECT_EQ(a.od.get<uint32_t>({0x1A00, 1}), 0x60410010u);
  EXPECT_EQ(a.od.get<uint16_t>({0x1017, 0}), 50);
  EXPECT_EQ(a.od.get<uint32_t>({0x1401, 1}) & cob::kPdoInvalid, cob::kPdoInvalid) << "unused RPDO2 switched off";

  const ProcessSlot target = master->output(3, 0x607A, 0);
  const ProcessSlot control = master->output(3, 0x6040, 0);
  const ProcessSlot actual = master->input(3, 0x6064, 0);
  ASSERT_TRUE(target && control && actual);
  EXPECT_FALSE(master->output(3, 0x6064, 0)) << "an input is not an output";
  std::vector<int32_t> commanded, fed_back;
  bool all_fresh = true;
  servo = [&](int64_t) {
    const CyclicStatus& st = master->cyclic_status();
    if (commanded.size() > 2) all_fresh = all_fresh && st.inputs_fresh && st.inputs_sync_serial == st.sync_serial;
    fed_back.push_back(read_slot<int32_t>(actual));
    const int32_t cmd = static_cast<int32_t>(cycles * 10);
    commanded.push_back(cmd);
    write_slot<int32_t>(target, cmd);
    write_slot<uint16_t>(control, 0x000F);
  };
  sim.run_for(100'000'000);
  ASSERT_GT(commanded.size(), 50u);
  // Outputs of cycle k act at the SYNC ending cycle k; the inputs read in
  // cycle k+1 were sampled at that SYNC, when the echo device still showed
  // what cycle k-1 commanded.
  for (std::size_t k = 10; k < commanded.size(); ++k) ASSERT_EQ(fed_back[k], commanded[k - 2]) << "cycle " << k;
  EXPECT_TRUE(all_fresh) << "every input was sampled at the last SYNC sent";
  EXPECT_EQ(master->cyclic_status().pdo_missed, 0u);
  EXPECT_EQ(a.od.get<uint16_t>({0x6040, 0}), 0x000F);
  EXPECT_TRUE(master->is_ready());
  EXPECT_FALSE(master->has_fault());
  const NodeStatus s = master->node_status(4);
  EXPECT_TRUE(s.operational);
  EXPECT_EQ(s.state, NmtState::Operational);
}

TEST_F(MasterTest, BootFollowsCiA302Order) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  const auto nmt = sim.frames_with_id(0x000);
  ASSERT_GE(nmt.size(), 2u);
  EXPECT_EQ(bytes_of(nmt[0]), (std::vector<uint8_t>{0x82, 3})) << "reset communication first";
  EXPECT_EQ(bytes_of(nmt.back()), (std::vector<uint8_t>{0x01, 3})) << "start last";
  const auto sdo = sim.frames_with_id(0x603);
  ASSERT_GE(sdo.size(), 3u);
  EXPECT_EQ(bytes_of(sdo[0]), (std::vector<uint8_t>{0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0})) << "device type";
  EXPECT_EQ(bytes_of(sdo[1]), (std::vector<uint8_t>{0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0})) << "vendor-ID";
  EXPECT_EQ(bytes_of(sdo[2]), (std::vector<uint8_t>{0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0})) << "product code";
  // The RPDO1 remap: invalidate, clear, entries, count, type, validate.
  std::vector<std::vector<uint8_t>> rpdo1;
  for (const auto& f : sdo) {
    const uint16_t idx = get_le<uint16_t>(&f.data[1]);
    if ((idx == 0x1400 || idx == 0x1600) && (f.data[0] & 0xE0) == 0x20) rpdo1.push_back(bytes_of(f));
  }
  ASSERT_EQ(rpdo1.size(), 7u);
  EXPECT_EQ(rpdo1[0], (std::vector<uint8_t>{0x23, 0x00, 0x14, 0x01, 0x03, 0x02, 0x00, 0x80}));
  EXPECT_EQ(rpdo1[1], (std::vector<uint8_t>{0x2F, 0x00, 0x16, 0x00, 0x00, 0, 0, 0}));
  EXPECT_EQ(rpdo1[2], (std::vector<uint8_t>{0x23, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60}));
  EXPECT_EQ(rpdo1[3], (std::vector<uint8_t>{0x23, 0x00, 0x16, 0x02, 0x20, 0x00, 0x7A, 0x60}));
  EXPECT_EQ(rpdo1[4], (std::vector<uint8_t>{0x2F, 0x00, 0x16, 0x00, 0x02, 0, 0, 0}));
  EXPECT_EQ(rpdo1[5], (std::vector<uint8_t>{0x2F, 0x00, 0x14, 0x02, 0x01, 0, 0, 0}));
  EXPECT_EQ(rpdo1[6], (std::vector<uint8_t>{0x23, 0x00, 0x14, 0x01, 0x03, 0x02, 0x00, 0x00}));
  // The master's own heartbeat: pre-operational during the boot, then operational.
  const auto hb = sim.frames_with_id(0x77F);
  ASSERT_GE(hb.size(), 1u);
  EXPECT_EQ(hb.front().data[0], 0x7F);
  sim.log.clear();
  sim.run_for(250'000'000);
  const auto later = sim.frames_with_id(0x77F);
  ASSERT_GE(later.size(), 2u);
  EXPECT_EQ(later.back().data[0], 0x05);
}

TEST_F(MasterTest, SyncCarriesACounterWhenConfigured) {
  EchoDevice a(sim, 3);
  BusConfig c = config({csp_node(3, "x-axis")});
  c.sync_overflow = 4;
  make_master(c);
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.log.clear();
  const uint64_t before = master->cyclic_status().sync_serial;
  sim.run_for(10'000'000);
  const auto syncs = sim.frames_with_id(0x080);
  ASSERT_EQ(syncs.size(), 10u);
  std::vector<uint8_t> counters;
  for (const auto& f : syncs) {
    ASSERT_EQ(f.len, 1);
    counters.push_back(f.data[0]);
  }
  const uint8_t first = counters[0];
  for (std::size_t i = 0; i < counters.size(); ++i) EXPECT_EQ(counters[i], (first - 1 + i) % 4 + 1);
  EXPECT_EQ(master->cyclic_status().sync_serial - before, 10u);
  EXPECT_EQ(a.node->counters().last_sync_counter, counters.back());
  // RPDOs precede each SYNC so that the devices apply them at it.
  for (std::size_t i = 1; i < sim.log.size(); ++i) {
    if (sim.log[i].id == 0x080) {
      EXPECT_EQ(sim.log[i - 1].id, 0x203u);
    }
  }
}

TEST_F(MasterTest, WrongIdentityStopsTheStartUp) {
  EchoDevice a(sim, 3, {0x00020192, 0x1234, 0x402, 1, 7, "other vendor"});
  make_master(config({csp_node(3, "x-axis")}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): identity 0x1018:01 vendor-ID is 0x00001234, expected "
            "0x00000CC1 (wrong device at this node-ID?)");
  const auto e = errors();
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ("canopen.0: " + e[0], master->boot_error()) << "the message source names the bus";
  EXPECT_EQ(a.node->state(), NmtState::PreOperational) << "never started";
  EXPECT_FALSE(master->is_cyclic_running());
  EXPECT_TRUE(master->has_fault());
}

TEST_F(MasterTest, WrongDeviceTypeStopsTheStartUp) {
  EchoDevice a(sim, 3, {0x00000191, 0xCC1, 0x402, 1, 7, "an I/O module"});
  NodeConfig n = csp_node(3, "x-axis");
  n.device_type = 0x00020192;
  make_master(config({n}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): 0x1000:00 device type is 0x00000191, expected 0x00020192 "
            "(wrong device at this node-ID?)");
}

TEST_F(MasterTest, RefusedSdoWriteStopsTheStartUp) {
  EchoDevice a(sim, 3);
  a.od.set_write_check({0x2000, 0}, [](const OdEntry&, const uint8_t*, std::size_t) -> uint32_t {
    return abort_code::kDeviceState;
  });
  NodeConfig n = csp_node(3, "x-axis");
  n.sdo.push_back(SdoWrite{{0x2000, 0}, {5}, "machine.ini:42", true});
  make_master(config({n}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): writing 0x2000:00 = 0x05 (value from machine.ini:42) "
            "refused: 0x08000022 data cannot be transferred or stored to the application because of the present "
            "device state");
}

TEST_F(MasterTest, UnmappableObjectStopsTheStartUp) {
  EchoDevice a(sim, 3);
  NodeConfig n = csp_node(3, "x-axis");
  n.rpdos[0].map = {{0x6502, 0, 32}};
  make_master(config({n}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): writing 0x1600:01 = 0x65020020 (RPDO1 mapping entry 1) "
            "refused: 0x06040041 object cannot be mapped to the PDO");
}

TEST_F(MasterTest, MissingNodeStopsTheStartUp) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis"), csp_node(9, "z-axis")}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 9 (z-axis): not found: no boot-up message within 200 ms after NMT "
            "reset communication (power, wiring, node-ID, bit rate?)");
}

TEST_F(MasterTest, MissingNodeWithoutResetIsFoundByItsSilence) {
  BusConfig c = config({csp_node(9, "z-axis")});
  c.reset_nodes = false;
  make_master(c);
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 9 (z-axis): not found: no answer to SDO upload 0x1000:00 (device "
            "type) within 50 ms");
}

TEST_F(MasterTest, OptionalNodeMayBeMissing) {
  EchoDevice a(sim, 3);
  NodeConfig opt = csp_node(9, "tool-changer");
  opt.mandatory = false;
  make_master(config({csp_node(3, "x-axis"), opt}));
  ASSERT_EQ(boot(), BootState::Succeeded);
  EXPECT_TRUE(errors().empty());
  ASSERT_FALSE(texts.empty());
  EXPECT_NE(texts[0].find("node 9 (tool-changer): not found"), std::string::npos) << texts[0];
  EXPECT_TRUE(master->is_ready());
  EXPECT_TRUE(master->node_status(9).fault);
}

TEST_F(MasterTest, VerificationCatchesADeviceThatChangesAValue) {
  EchoDevice a(sim, 3);
  a.od.set_after_write({0x2000, 0}, [&](const OdEntry&) { a.od.set<uint8_t>({0x2000, 0}, 1); });  // clamps
  NodeConfig n = csp_node(3, "x-axis");
  n.sdo.push_back(SdoWrite{{0x2000, 0}, {5}, "machine.ini:43", true});
  make_master(config({n}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): verification of 0x2000:00 (value from machine.ini:43) "
            "failed: the device has 0x01 after 0x05 was written");
}

// The writes that switch unused PDOs off are read back too: a device that
// answers OK but keeps the PDO on (its invalid bit does not stick) stops
// the start-up instead of sending frames the plan does not know.
TEST_F(MasterTest, AnUnusedPdoThatDoesNotSwitchOffStopsTheStartUp) {
  EchoDevice a(sim, 3);
  a.od.set_after_write({0x1802, 1}, [&](const OdEntry&) {
    a.od.set<uint32_t>({0x1802, 1}, a.od.get<uint32_t>({0x1802, 1}) & ~cob::kPdoInvalid);
  });
  make_master(config({csp_node(3, "x-axis")}));
  EXPECT_EQ(boot(), BootState::Failed);
  EXPECT_EQ(master->boot_error(),
            "canopen.0: start-up stopped: node 3 (x-axis): verification of 0x1802:01 (TPDO3 off (not configured)) "
            "failed: the device has 0x00000383 after 0x80000383 was written");
}

TEST_F(MasterTest, HeartbeatLossIsDetectedWithinItsTimeout) {
  EchoDevice a(sim, 3);
  NodeConfig n = csp_node(3, "x-axis");
  n.heartbeat_ms = 20;
  n.heartbeat_timeout_ms = 50;
  make_master(config({n}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(100'000'000);
  EXPECT_FALSE(master->node_status(3).heartbeat_lost);
  int64_t last_heartbeat = 0;
  for (const auto& f : sim.frames_with_id(0x703)) last_heartbeat = f.timestamp_ns;
  a.node->set_muted(true);  // the device dies
  int64_t detected = 0;
  sim.run_until([&] {
    if (master->node_status(3).heartbeat_lost && !detected) detected = sim.now();
    return detected != 0;
  }, 1'000'000'000);
  ASSERT_NE(detected, 0);
  for (const auto& f : sim.frames_with_id(0x703)) last_heartbeat = std::max(last_heartbeat, f.timestamp_ns);
  EXPECT_GT(detected - last_heartbeat, 50'000'000) << "not before the timeout";
  EXPECT_LE(detected - last_heartbeat, 50'000'000 + 2 * sim.step_ns) << "right after it";
  EXPECT_TRUE(master->node_status(3).fault);
  EXPECT_FALSE(master->is_ready());
  const auto e = errors();
  ASSERT_FALSE(e.empty());
  EXPECT_EQ(e.back(), "node 3 (x-axis): heartbeat lost: nothing heard for 50 ms (power, cable, termination or bus-off?)");
}

// ---------------------------------------------------------------- the master's heartbeat

namespace {
// Intervals between the master's heartbeats (0x77F) in the log, ns.
std::vector<int64_t> heartbeat_gaps(const Sim& sim) {
  std::vector<int64_t> gaps;
  const auto hb = sim.frames_with_id(0x77F);
  for (std::size_t i = 1; i < hb.size(); ++i) gaps.push_back(hb[i].timestamp_ns - hb[i - 1].timestamp_ns);
  return gaps;
}
NodeConfig watched_node(uint8_t id, const std::string& name) {
  NodeConfig n = csp_node(id, name);
  n.master_heartbeat_timeout_ms = 150;  // the node's 0x1016:1 watches the master
  return n;
}
}  // namespace

// The issue: the heartbeat came from the normal-priority acyclic thread; a
// host that starved it made every drive fault (0x8130) while the servo
// thread ran. Here that thread stops for a second and the heartbeat goes on.
TEST_F(MasterTest, AStalledAcyclicThreadDoesNotStopTheHeartbeat) {
  EchoDevice a(sim, 3);
  make_master(config({watched_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  EXPECT_EQ(a.od.get<uint32_t>({0x1016, 1}), (127u << 16) | 150u);
  sim.run_for(200'000'000);
  EXPECT_TRUE(master->heartbeat_in_cycle());
  sim.log.clear();
  poll_in_steps = false;  // the acyclic thread gets no CPU for 1 s
  sim.run_for(1'000'000'000);
  const auto hb = sim.frames_with_id(0x77F);
  ASSERT_GE(hb.size(), 9u);
  for (const auto& f : hb) EXPECT_EQ(bytes_of(f), (std::vector<uint8_t>{0x05}));
  for (int64_t gap : heartbeat_gaps(sim)) EXPECT_LE(gap, 100'000'000 + sim.step_ns) << "every 100 ms";
  EXPECT_EQ(a.node->counters().heartbeats_lost, 0u) << "the node never missed the master";
}

// ... and when the servo thread stops (or `delf` removes canopen.0.write, or
// canopen.0.enable goes FALSE), the heartbeat stops with it although the
// acyclic thread runs on: the nodes' consumers trip within their time.
TEST_F(MasterTest, TheHeartbeatStopsWithTheServoCycle) {
  EchoDevice a(sim, 3);
  make_master(config({watched_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(200'000'000);
  std::vector<int64_t> lost_at;
  a.node->on_heartbeat_lost = [&](uint8_t) { lost_at.push_back(sim.now()); };
  sim.log.clear();
  cycle_running = false;
  const int64_t stopped = sim.now();
  sim.run_for(500'000'000);
  EXPECT_TRUE(sim.frames_with_id(0x77F).empty()) << "the acyclic thread took the heartbeat back";
  ASSERT_EQ(lost_at.size(), 1u);
  EXPECT_LE(lost_at[0] - stopped, 150'000'000 + 2 * sim.step_ns) << "within the consumer time of 0x1016:1";
  const auto e = sim.frames_with_id(0x083);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(get_le<uint16_t>(&e[0].data[0]), 0x8130);
}

// `halcmd delf canopen.0.write servo-thread` while canopen.0.read runs on:
// no SYNC goes out, so the inputs read are stale. They are marked so, the
// cycle counts as not running (the drives' link health), and it is said.
TEST_F(MasterTest, ReadsWithoutAWriteMarkTheInputsStaleAndSaySo) {
  EchoDevice a(sim, 3);
  bool write = true;
  master = std::make_unique<Master>(config({csp_node(3, "x-axis")}), sim.port("master-cyclic"), sim.port("master-acyclic"),
                                    &messages);
  sim.actors.push_back([&](int64_t now) {
    master->poll(now);
    if (now % 1'000'000 == 0) {
      master->cyclic_read(now);
      if (write) master->cyclic_write(now);
    }
  });
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(20'000'000);
  EXPECT_TRUE(master->cyclic_status().inputs_fresh);
  EXPECT_TRUE(master->is_cyclic_running());
  EXPECT_TRUE(errors().empty());
  write = false;
  sim.run_for(1'000'000);  // this read still finds the SYNC of the last write
  sim.run_for(1'000'000);
  EXPECT_FALSE(master->cyclic_status().inputs_fresh) << "no SYNC since the last read";
  sim.run_for(2'000'000);
  EXPECT_FALSE(master->is_cyclic_running());
  EXPECT_FALSE(master->is_ready());
  EXPECT_EQ(errors(), std::vector<std::string>{"no SYNC sent for 3 cycles (canopen.0.write not running or canopen.0.enable "
                                               "FALSE): the nodes get no set-points"});
  write = true;
  sim.run_for(3'000'000);
  EXPECT_TRUE(master->is_cyclic_running());
  EXPECT_TRUE(master->cyclic_status().inputs_fresh);
  errors();
  ASSERT_FALSE(texts.empty());
  EXPECT_EQ(texts.back(), "SYNC sent again after 4 cycles without");  // the first read after it still finds none
}

// Before the servo thread runs (the boot in on_ready), the acyclic thread
// sends the heartbeat, pre-operational; the first cycle takes it over
// without a gap.
TEST_F(MasterTest, TheFirstCycleTakesTheHeartbeatOverWithoutAGap) {
  EchoDevice a(sim, 3);
  cycle_running = false;
  make_master(config({watched_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  EXPECT_FALSE(master->heartbeat_in_cycle());
  auto hb = sim.frames_with_id(0x77F);
  ASSERT_GE(hb.size(), 1u);
  EXPECT_EQ(hb.front().data[0], 0x7F);
  sim.run_for(250'000'000);
  cycle_running = true;
  sim.run_for(500'000'000);
  EXPECT_TRUE(master->heartbeat_in_cycle());
  for (int64_t gap : heartbeat_gaps(sim)) EXPECT_LE(gap, 100'000'000 + 2'000'000);
  EXPECT_EQ(sim.frames_with_id(0x77F).back().data[0], 0x05);
  EXPECT_EQ(a.node->counters().heartbeats_lost, 0u);
}

namespace {
// A transport whose interface can be taken down (SocketCAN: ENETDOWN).
class DownableTransport final : public can::Transport {
 public:
  explicit DownableTransport(std::unique_ptr<can::Transport> inner) : inner_(std::move(inner)) {}
  const std::string& name() const noexcept override { return name_; }
  can::SendStatus send(const can::Frame& f) noexcept override { return down ? refusal : inner_->send(f); }
  bool receive(can::Frame& out) noexcept override { return !down && inner_->receive(out); }
  bool wait(int64_t timeout_ns) noexcept override { return inner_->wait(timeout_ns); }
  void set_filters(std::span<const can::Filter> filters) override { inner_->set_filters(filters); }
  void set_error_reports(bool on) override { inner_->set_error_reports(on); }
  can::BusState state() const noexcept override { return inner_->state(); }
  can::TransportStats stats() const noexcept override { return inner_->stats(); }
  int64_t now_ns() const noexcept override { return inner_->now_ns(); }
  bool down = false;
  can::SendStatus refusal = can::SendStatus::Down;

 private:
  std::unique_ptr<can::Transport> inner_;
  std::string name_ = "can7";
};
}  // namespace

TEST_F(MasterTest, AnInterfaceTakenDownIsReportedAsSuch) {
  EchoDevice a(sim, 3);
  auto port = std::make_unique<DownableTransport>(sim.port("master-cyclic"));
  DownableTransport* cyclic = port.get();
  master = std::make_unique<Master>(config({csp_node(3, "x-axis")}), std::move(port), sim.port("master-acyclic"), &messages);
  sim.actors.push_back([this](int64_t now) {
    master->poll(now);
    if (now % 1'000'000 == 0) {
      master->cyclic_read(now);
      master->cyclic_write(now);
    }
  });
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(10'000'000);
  EXPECT_TRUE(errors().empty());
  cyclic->down = true;
  sim.run_for(5'000'000);
  EXPECT_TRUE(master->cyclic_status().interface_down);
  EXPECT_GE(master->cyclic_status().send_errors, 5u);
  EXPECT_TRUE(master->has_fault());
  EXPECT_FALSE(master->is_ready());
  // Named first, before what follows from it (the node's TPDOs missing).
  const auto e = errors();
  ASSERT_FALSE(e.empty());
  EXPECT_EQ(e.front(), "CAN interface can7 is down: no SYNC, PDO or heartbeat can be sent");
  cyclic->down = false;
  sim.run_for(5'000'000);
  EXPECT_FALSE(master->cyclic_status().interface_down);
  errors();
  EXPECT_NE(std::find(texts.begin(), texts.end(), "CAN interface can7 is up again"), texts.end());
}

// A driver that only refuses frames (ENOBUFS: the queue of a stopped
// interface) and delivers nothing: the heartbeats of all nodes time out.
// The interface is named once, with the count of refused frames, before
// the nodes' messages, which point to it.
TEST_F(MasterTest, ASilentInterfaceIsReportedOnceWithItsSendErrorsBeforeTheNodesHeartbeats) {
  EchoDevice a(sim, 3), b(sim, 4);
  auto cyc = std::make_unique<DownableTransport>(sim.port("master-cyclic"));
  auto acy = std::make_unique<DownableTransport>(sim.port("master-acyclic"));
  DownableTransport* cyclic = cyc.get();
  DownableTransport* acyclic = acy.get();
  NodeConfig n3 = csp_node(3, "x-axis"), n4 = csp_node(4, "y-axis");
  for (NodeConfig* n : {&n3, &n4}) {
    n->heartbeat_ms = 20;
    n->heartbeat_timeout_ms = 50;
  }
  BusConfig c = config({n3, n4});
  c.pdo_miss_limit = 0;  // only the heartbeats speak
  master = std::make_unique<Master>(c, std::move(cyc), std::move(acy), &messages);
  sim.actors.push_back([this](int64_t now) {
    master->poll(now);
    if (now % 1'000'000 == 0) {
      master->cyclic_read(now);
      master->cyclic_write(now);
    }
  });
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(10'000'000);
  EXPECT_TRUE(errors().empty());
  for (DownableTransport* t : {cyclic, acyclic}) {
    t->refusal = can::SendStatus::WouldBlock;
    t->down = true;
  }
  sim.run_for(200'000'000);
  const auto e = errors();
  ASSERT_EQ(e.size(), 3u) << ::testing::PrintToString(e);
  EXPECT_EQ(e[0].rfind("CAN interface can7 is down or disconnected: nothing received for ", 0), 0u) << e[0];
  EXPECT_NE(e[0].find(" frames refused by it (last: "), std::string::npos) << e[0];
  EXPECT_EQ(std::count_if(e.begin(), e.end(), [](const std::string& m) { return m.find("CAN interface") != std::string::npos; }), 1);
  EXPECT_NE(e[1].find("heartbeat lost: nothing heard for 50 ms (the interface is down, see above)"), std::string::npos) << e[1];
  for (DownableTransport* t : {cyclic, acyclic}) t->down = false;
  sim.run_for(100'000'000);
  errors();
  EXPECT_NE(std::find(texts.begin(), texts.end(), "CAN interface can7: frames received again"), texts.end());
}

// The acyclic thread (heartbeat consumer, SDO timeouts) keeps the bus's
// clock: a simulated bus in simulated time that stands still (its stepping
// thread stalled) is not a silent bus, however long the wall clock runs.
TEST_F(MasterTest, TheAcyclicThreadTimesOutInTheBusClockNotTheWallClock) {
  EchoDevice a(sim, 3);
  NodeConfig n = csp_node(3, "x-axis");
  n.heartbeat_ms = 20;
  n.heartbeat_timeout_ms = 50;
  make_master(config({n}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  poll_in_steps = false;
  master->start_thread();
  auto run_bus = [&](int64_t ns) {  // simulated time, a millisecond per millisecond of wall time at most
    for (int64_t t = 0; t < ns; t += 1'000'000) {
      sim.run_for(1'000'000);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  };
  run_bus(100'000'000);
  ASSERT_FALSE(master->node_status(3).heartbeat_lost);
  // The stepping stalls for 300 ms of wall time: six heartbeat timeouts.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_FALSE(master->node_status(3).heartbeat_lost) << "the master counted wall time";
  run_bus(100'000'000);
  EXPECT_FALSE(master->node_status(3).heartbeat_lost);
  EXPECT_EQ(errors(), std::vector<std::string>{});
  // A device that really goes silent is still found, in bus time.
  a.node->set_muted(true);
  run_bus(100'000'000);
  for (int i = 0; i < 200 && !master->node_status(3).heartbeat_lost; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_TRUE(master->node_status(3).heartbeat_lost);
  master->stop_thread();
  const auto e = errors();
  EXPECT_NE(std::find(e.begin(), e.end(),
                      "node 3 (x-axis): heartbeat lost: nothing heard for 50 ms (power, cable, termination or bus-off?)"),
            e.end());
}

TEST_F(MasterTest, ANodeThatResetsIsAFaultUntilRebooted) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  a.node->start(sim.now());  // power glitch: the device boots again
  sim.run_for(10'000'000);
  EXPECT_TRUE(master->node_status(3).fault);
  EXPECT_FALSE(master->node_status(3).booted);
  const auto e = errors();
  ASSERT_FALSE(e.empty());
  EXPECT_EQ(e.back(), "node 3 (x-axis): restarted (boot-up message) while in operation: its configuration is lost; reboot the node");
  master->request_reboot(3);
  ASSERT_TRUE(sim.run_until([&] { return master->node_status(3).operational; }, 2'000'000'000));
  EXPECT_FALSE(master->node_status(3).fault);
  EXPECT_EQ(a.od.get<uint32_t>({0x1600, 2}), 0x607A0020u) << "configured again";
  EXPECT_TRUE(master->is_ready());
}

TEST_F(MasterTest, EmcyIsDecodedIntoTheErrorChannel) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  errors();
  const uint8_t vendor[5] = {0xDE, 0xAD, 0, 0, 1};
  a.node->emcy(0x8611, kErrRegProfile, vendor);
  sim.run_for(5'000'000);
  auto e = errors();
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0], "node 3 (x-axis): EMCY 0x8611 following error (error register 0x21: generic, profile; vendor DE AD 00 00 01)");
  EXPECT_EQ(master->node_status(3).emcy_code, 0x8611);
  EXPECT_EQ(master->node_status(3).error_register, 0x21);
  a.node->clear_emcy();
  sim.run_for(5'000'000);
  EXPECT_TRUE(errors().empty()) << "an error reset is information";
  ASSERT_FALSE(texts.empty());
  EXPECT_EQ(texts.back(), "node 3 (x-axis): EMCY 0x0000 error reset or no error (error register 0x00: none; vendor 00 00 00 00 00)");
  EXPECT_EQ(master->node_status(3).emcy_code, 0);
}

// The EMCY decoder, the drive layer and the screen read one table: a code
// reads the same in a CANopen EMCY message as in a drive's fault text.
TEST_F(MasterTest, EmcyTextsComeFromTheOneErrorCodeTable) {
  for (uint16_t code : {0x2310, 0x2399, 0x3210, 0x5530, 0x7305, 0x8130, 0x8611, 0xFF04}) {
    Emcy e;
    e.code = code;
    char buf[160];
    const std::string text = format_emcy(e, buf, sizeof buf);
    EXPECT_NE(text.find(cia402::error_code_text(code)), std::string::npos) << text;
  }
}

TEST_F(MasterTest, ErrorRegisterBitsDecode) {
  char buf[96];
  EXPECT_STREQ(error_register_text(0x9E, buf, sizeof buf), "current, voltage, temperature, communication, manufacturer");
}

TEST_F(MasterTest, MissedTpdosFaultTheNode) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(20'000'000);
  errors();
  EXPECT_EQ(master->node_status(3).pdo_missed, 0u);
  sim.bus->drop_next(can::Filter::exact(0x183), 2);
  sim.run_for(10'000'000);
  EXPECT_EQ(master->node_status(3).pdo_missed, 2u);
  EXPECT_FALSE(master->node_status(3).fault) << "two in a row are tolerated";
  sim.bus->drop_next(can::Filter::exact(0x183), 3);
  sim.run_for(10'000'000);
  EXPECT_TRUE(master->node_status(3).fault);
  const auto e = errors();
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0], "node 3: TPDO1 missed 3 SYNCs in a row (COB-ID 0x183)");
}

TEST_F(MasterTest, BusOffIsReportedAndRecovers) {
  EchoDevice a(sim, 3);
  auto cyclic = sim.port("master-cyclic");
  can::VirtualPort* cyclic_port = cyclic.get();
  master = std::make_unique<Master>(config({csp_node(3, "x-axis")}), std::move(cyclic), sim.port("master-acyclic"), &messages);
  sim.actors.push_back([this](int64_t now) {
    master->poll(now);
    if (now % 1'000'000 == 0) {
      master->cyclic_read(now);
      master->cyclic_write(now);
    }
  });
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  sim.run_for(10'000'000);
  errors();
  // The answer to the last SYNC before the bus-off is lost too.
  sim.bus->drop_next(can::Filter::exact(0x183), 1);
  sim.run_for(1'000'000);
  sim.bus->force_bus_off(*cyclic_port);
  sim.run_for(5'000'000);
  EXPECT_EQ(master->cyclic_status().bus_state, can::BusState::BusOff);
  EXPECT_TRUE(master->has_fault());
  EXPECT_GT(master->cyclic_status().send_errors, 0u);
  auto e = errors();
  ASSERT_EQ(e.size(), 1u) << "a TPDO missing for the last SYNC sent is not missed again at every refused SYNC";
  EXPECT_EQ(e[0], "CAN controller bus-off (bus-off)");
  cyclic_port->restart();
  sim.run_for(5'000'000);
  EXPECT_EQ(master->cyclic_status().bus_state, can::BusState::ErrorActive);
  EXPECT_FALSE(master->has_fault());
  EXPECT_TRUE(errors().empty());
  ASSERT_FALSE(texts.empty());
  EXPECT_EQ(texts.back(), "CAN controller error-active (controller restarted)");
}

TEST_F(MasterTest, RealtimeSdoRequests) {
  EchoDevice a(sim, 3);
  make_master(config({csp_node(3, "x-axis")}));
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  const int read = master->rt_sdo_read(3, {0x1018, 2});
  const int write = master->rt_sdo_write(3, {0x2000, 0}, 42, 1);
  const int bad = master->rt_sdo_read(3, {0x5555, 0});
  ASSERT_GE(read, 0);
  ASSERT_GE(write, 0);
  ASSERT_GE(bad, 0);
  RtSdoResult r1, r2, r3;
  ASSERT_TRUE(sim.run_until([&] { return master->rt_sdo_poll(read, r1); }));
  ASSERT_TRUE(sim.run_until([&] { return master->rt_sdo_poll(write, r2); }));
  ASSERT_TRUE(sim.run_until([&] { return master->rt_sdo_poll(bad, r3); }));
  EXPECT_EQ(r1.abort_code, 0u);
  EXPECT_EQ(r1.value, 0x402u);
  EXPECT_EQ(r1.size, 4);
  EXPECT_EQ(r2.abort_code, 0u);
  EXPECT_EQ(a.od.get<uint8_t>({0x2000, 0}), 42);
  EXPECT_EQ(r3.abort_code, abort_code::kNoObject);
  EXPECT_FALSE(master->rt_sdo_poll(read, r1)) << "a result is handed out once";
}

TEST_F(MasterTest, CyclicFunctionsDoNotAllocate) {
  EchoDevice a(sim, 3), b(sim, 4);
  BusConfig c = config({csp_node(3, "x-axis"), csp_node(4, "y-axis")});
  c.sync_overflow = 10;
  master = std::make_unique<Master>(std::move(c), sim.port("master-cyclic"), sim.port("master-acyclic"), &messages);
  sim.actors.push_back([this](int64_t now) { master->poll(now); });
  ASSERT_EQ(boot(), BootState::Succeeded) << master->boot_error();
  const ProcessSlot target = master->output(3, 0x607A, 0);
  const ProcessSlot actual = master->input(3, 0x6064, 0);
  uint64_t allocations = 0;
  int32_t last = 0;
  for (int cycle = 0; cycle < 2000; ++cycle) {
    sim.run_for(1'000'000);
    cnc::testing::ScopedAllocationCheck check;
    master->cyclic_read(sim.now());
    last = read_slot<int32_t>(actual);
    write_slot<int32_t>(target, cycle);
    master->cyclic_write(sim.now());
    allocations += check.allocations();
  }
  if (cnc::testing::AllocationCounter::available()) {
    EXPECT_EQ(allocations, 0u);
  }
  EXPECT_EQ(last, 1997);
  EXPECT_EQ(master->cyclic_status().pdo_missed, 0u);
}

TEST(MasterSlots, BitPackingAndSignExtension) {
  uint8_t image[8] = {};
  const ProcessSlot a{image, 0, 1}, b{image, 1, 7}, c{image, 8, 16}, d{image, 24, 32};
  write_slot<bool>(a, true);
  write_slot<int32_t>(b, -3);
  write_slot<uint16_t>(c, 0xBEEF);
  write_slot<int32_t>(d, -100000);
  EXPECT_EQ(image[0], 0x01 | (0x7D << 1));
  EXPECT_TRUE(read_slot<bool>(a));
  EXPECT_EQ(read_slot<int32_t>(b), -3);
  EXPECT_EQ(read_slot<uint32_t>(b), 0x7Du) << "unsigned reads do not sign-extend";
  EXPECT_EQ(read_slot<uint16_t>(c), 0xBEEF);
  EXPECT_EQ(read_slot<int32_t>(d), -100000);
  uint8_t f[4] = {};
  write_slot<double>(ProcessSlot{f, 0, 32}, 1.5);
  EXPECT_EQ(read_slot<double>(ProcessSlot{f, 0, 32}), 1.5);
  EXPECT_EQ(read_slot<int32_t>(ProcessSlot{}), 0);
}
