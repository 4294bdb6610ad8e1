#include <gtest/gtest.h>

#include <thread>

#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"
#include "sim/can/virtual_bus.hpp"
#include "fieldbus/canopen/components.hpp"
#include "fieldbus/canopen/master.hpp"
#include "fieldbus/canopen/slave_runner.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {

// A device on a named real-time virtual bus, run by its own thread, as the
// simulated machine does it.
struct Device {
  Device(const std::string& bus, uint8_t id) {
    using D = DataType;
    using A = Access;
    od.add({0x6040, 0}, D::Unsigned16, A::ReadWrite, 0, true);
    od.add({0x6041, 0}, D::Unsigned16, A::ReadOnly, 0x0250, true);
    od.add({0x6064, 0}, D::Integer32, A::ReadOnly, 0, true);
    od.add({0x607A, 0}, D::Integer32, A::ReadWrite, 0, true);
    od.add({0x60FD, 0}, D::Unsigned32, A::ReadOnly, 0x4, true);
    can::register_virtual_transport();  // the master opens INTERFACE = virtual:<bus>
    port = can::VirtualBus::named(bus, {1'000'000, can::Stuffing::WorstCase, false, -1})->open_port("device");
    SlaveOptions o;
    o.node_id = id;
    o.identity = {0x00020192, 0xCC1, 0x402, 1, 99, "hal test device"};
    node = std::make_unique<SlaveNode>(od, *port, o);
    node->on_sync = [this](uint8_t, int64_t) { od.set<int32_t>({0x6064, 0}, od.get<int32_t>({0x607A, 0})); };
    runner = std::make_unique<SlaveRunner>(*port);
    runner->add(*node);
    runner->start();
  }
  ~Device() { runner->stop(); }
  ObjectDictionary od;
  std::unique_ptr<can::VirtualPort> port;
  std::unique_ptr<SlaveNode> node;
  std::unique_ptr<SlaveRunner> runner;
};

}  // namespace

TEST(CanopenComponent, LoadrtBootsTheBusAndRunsInTheServoThread) {
  const std::string bus = cnc::testing::unique_name("haltest");
  Device device(bus, 3);
  // Real threads on a real clock: no PDO-miss limit and a generous heartbeat
  // timeout, so that a slow machine cannot fault the node in this test.
  const std::string ini_text = "[EMCMOT]\nSERVO_PERIOD = 1000000\n[CANOPEN]\nINTERFACE = virtual:" + bus +
                               "\nPDO_MISS_LIMIT = 0\nNODE = 3\n[CANOPEN_NODE_3]\nNAME = x-axis\nVENDOR_ID = 0xCC1\n"
                               "HEARTBEAT_MS = 50\nHEARTBEAT_TIMEOUT_MS = 5000\n"
                               "RPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n"
                               "TPDO2 = 0x60FD:0:u32\nEXPORT_PINS = YES\n";
  const auto ini = ini::IniFile::parse(ini_text, "machine.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  register_components(registry);
  MessageQueue messages;
  hal::CommandInterpreter halcmd(hal, registry, &ini, &messages);
  halcmd.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt canopen\n"
      "addf canopen.0.read servo-thread\n"
      "addf canopen.0.write servo-thread\n",
      "test.hal");
  for (hal::Component* c : hal.components()) c->on_ready();  // boots: blocking
  Master* m = find_master(hal, "canopen.0");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->boot_state(), BootState::Succeeded) << m->boot_error();
  EXPECT_EQ(find_master(hal, "canopen.1"), nullptr);
  EXPECT_TRUE(hal.has_pin("canopen.0.node.03.607a-00"));
  EXPECT_EQ(hal.type_of_name("canopen.0.node.03.6064-00"), hal::Type::S32);
  EXPECT_EQ(hal.type_of_name("canopen.0.node.03.60fd-00"), hal::Type::U32);
  EXPECT_EQ(hal.get_value("canopen.0.transport-delay"), "1");

  hal.set_value("canopen.0.node.03.607a-00", "-12345");
  hal.set_value("canopen.0.node.03.6040-00", "15");
  hal::Thread* servo = hal.find_thread("servo-thread");
  ASSERT_NE(servo, nullptr);
  rt::CycleInfo info;
  info.period_ns = 1'000'000;
  bool seen = false;
  for (int i = 0; i < 2000 && !seen; ++i) {
    info.now_ns = monotonic_ns();
    servo->run_cycle(info);
    ++info.cycle;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    seen = hal.get_value("canopen.0.node.03.6064-00") == "-12345";
  }
  EXPECT_TRUE(seen) << "the position followed the target through the device";
  {
    // The servo thread's functions (read, pins, write) never allocate.
    uint64_t allocations = 0;
    for (int i = 0; i < 200; ++i) {
      info.now_ns = monotonic_ns();
      cnc::testing::ScopedAllocationCheck check;
      servo->run_cycle(info);
      allocations += check.allocations();
      ++info.cycle;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    if (cnc::testing::AllocationCounter::available()) {
      EXPECT_EQ(allocations, 0u);
    }
  }
  EXPECT_EQ(hal.get_value("canopen.0.node.03.60fd-00"), "4");
  EXPECT_EQ(hal.get_value("canopen.0.node.03.operational"), "TRUE");
  EXPECT_EQ(hal.get_value("canopen.0.ready"), "TRUE");
  EXPECT_EQ(hal.get_value("canopen.0.fault"), "FALSE");
  EXPECT_NE(hal.get_value("canopen.0.sync-count"), "0");
  EXPECT_EQ(device.od.get<uint16_t>({0x6040, 0}), 15);
  EXPECT_EQ(device.node->state(), NmtState::Operational);
  // Blocking SDO from a non-realtime thread while the cycle runs.
  const SdoResult r = m->sdo_upload_wait(3, {0x1018, 4});
  EXPECT_TRUE(r.ok()) << r.message();
  EXPECT_EQ(r.as<uint32_t>(), 99u);
  hal.clear();
}

TEST(CanopenComponent, AFailedBootStopsTheStartUp) {
  const std::string bus = cnc::testing::unique_name("haltest");
  Device device(bus, 3);
  const std::string ini_text = "[CANOPEN]\nINTERFACE = virtual:" + bus +
                               "\nBOOT_TIMEOUT_MS = 300\nNODE = 3\n[CANOPEN_NODE_3]\nPRODUCT_CODE = 0x999\n";
  const auto ini = ini::IniFile::parse(ini_text, "machine.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  register_components(registry);
  MessageQueue messages;
  hal::CommandInterpreter halcmd(hal, registry, &ini, &messages);
  halcmd.run_text("loadrt canopen\n", "test.hal");
  try {
    for (hal::Component* c : hal.components()) c->on_ready();
    FAIL() << "the boot should fail";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()),
              "canopen.0: start-up stopped: node 3: identity 0x1018:02 product code is 0x00000402, expected 0x00000999 "
              "(wrong device at this node-ID?)");
  }
  hal.clear();
}

TEST(CanopenComponent, NeedsAnIniAndKnownArguments) {
  hal::Hal hal;
  hal::ComponentRegistry registry;
  register_components(registry);
  hal::CommandInterpreter halcmd(hal, registry, nullptr, nullptr);
  EXPECT_THROW(halcmd.execute("loadrt canopen"), hal::HalError);
  const auto ini = ini::IniFile::parse("[CANOPEN]\nINTERFACE = virtual:x\nNODE = 1\n[CANOPEN_NODE_1]\n", "m.ini");
  hal::CommandInterpreter with_ini(hal, registry, &ini, nullptr);
  EXPECT_THROW(with_ini.execute("loadrt canopen speed=1"), hal::HalError);
  EXPECT_THROW(with_ini.execute("loadrt canopen buses=NOPE"), std::exception);
}

// The SYNC period is the period of the thread that runs the bus (SYNC goes
// out every cycle of it): a configured period that differs is refused at
// start-up naming both, before anything is sent.
TEST(CanopenComponent, SyncPeriodThatDiffersFromItsThreadStopsStartUp) {
  const std::string bus = cnc::testing::unique_name("syncmismatch");
  const auto ini = ini::IniFile::parse("[CANOPEN]\nINTERFACE = virtual:" + bus +
                                           "\nSYNC_PERIOD_US = 2000\nNODE = 3\n[CANOPEN_NODE_3]\nNAME = x\n",
                                       "machine.ini");
  can::register_virtual_transport();  // INTERFACE = virtual:<bus>
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  register_components(registry);
  hal::CommandInterpreter halcmd(hal, registry, &ini, nullptr);
  halcmd.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt canopen\n"
      "addf canopen.0.read servo-thread\n"
      "addf canopen.0.write servo-thread\n",
      "test.hal");
  try {
    for (hal::Component* c : hal.components()) c->on_ready();
    FAIL() << "started with SYNC every 1 ms planned as 2 ms";
  } catch (const std::exception& e) {
    EXPECT_EQ(std::string(e.what()),
              "machine.ini:3: [CANOPEN]SYNC_PERIOD_US = 2000 us, but canopen.0.write runs in servo-thread with a "
              "period of 1000 us: SYNC is sent every cycle of that thread; make them equal (or leave SYNC_PERIOD_US "
              "out)");
  }
  hal.clear();
}

TEST(CanopenComponent, SyncPeriodComesFromTheThreadThatRunsTheBus) {
  const std::string bus = cnc::testing::unique_name("syncthread");
  Device device(bus, 3);
  const auto ini = ini::IniFile::parse("[EMCMOT]\nSERVO_PERIOD = 1000000\n[CANOPEN]\nINTERFACE = virtual:" + bus +
                                           "\nPDO_MISS_LIMIT = 0\nNODE = 3\n[CANOPEN_NODE_3]\nNAME = x\n"
                                           "HEARTBEAT_TIMEOUT_MS = 5000\n",
                                       "machine.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  register_components(registry);
  hal::CommandInterpreter halcmd(hal, registry, &ini, nullptr);
  halcmd.run_text(
      "loadrt threads name1=servo-thread period1=1000000 name2=bus-thread period2=4000000\n"
      "loadrt canopen\n"
      "addf canopen.0.read bus-thread\n"
      "addf canopen.0.write bus-thread\n",
      "test.hal");
  for (hal::Component* c : hal.components()) c->on_ready();
  Master* m = find_master(hal, "canopen.0");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->config().cycle_ns, 4'000'000) << "neither [EMCMOT]SERVO_PERIOD nor the servo thread's";
  hal.clear();
}
