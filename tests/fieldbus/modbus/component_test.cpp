#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"
#include "core/util/messages.hpp"
#include "fieldbus/modbus/component.hpp"
#include "fieldbus/modbus/link.hpp"
#include "tests/fieldbus/modbus/sim_fixture.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::modbus;
using namespace cnc::modbus::testing;

namespace {

struct HalRig {
  explicit HalRig(modbus_sim::Server& server, const std::string& extra = "")
      : ini(ini::IniFile::parse(link_ini(server, true, "delta", extra), "machine.ini")) {
    hal::register_core_components(registry);
    register_components(registry);
    halcmd = std::make_unique<hal::CommandInterpreter>(hal, registry, &ini, &messages);
    halcmd->run_text(
        "loadrt threads name1=servo-thread period1=1000000\n"
        "loadrt modbus\n"
        "addf modbus.0.read servo-thread\n"
        "addf modbus.0.write servo-thread\n",
        "test.hal");
    for (hal::Component* c : hal.components()) {
      c->on_ready();
      if (auto* s = dynamic_cast<ipc::ControllerService*>(c)) service = s;
    }
    servo = hal.find_thread("servo-thread");
    info.period_ns = 1'000'000;
  }
  void cycle() {
    info.now_ns = monotonic_ns();
    servo->run_cycle(info);
    ++info.cycle;
  }
  // Runs servo cycles (1 ms apart) until `pred` holds.
  bool cycles_until(const std::function<bool()>& pred) {
    return eventually([&] {
      cycle();
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      return pred();
    });
  }
  std::string pin(const std::string& name) { return hal.get_value("modbus.0.vfd.01." + name); }
  double pin_f(const std::string& name) { return std::stod(pin(name)); }

  ini::IniFile ini;
  hal::Hal hal;
  hal::ComponentRegistry registry;
  MessageQueue messages;
  std::unique_ptr<hal::CommandInterpreter> halcmd;
  ipc::ControllerService* service = nullptr;
  hal::Thread* servo = nullptr;
  rt::CycleInfo info;
};

}  // namespace

// The spindle pins as motion drives them: on, forward, speed; the VFD ramps
// and at-speed follows; the servo thread's functions never allocate.
TEST(ModbusComponent, SpindlePinsDriveTheVfdAndReportAtSpeed) {
  modbus_sim::Server server(sim_config(modbus_sim::Family::Delta, true));
  server.start();
  HalRig rig(server);
  ASSERT_NE(rig.service, nullptr);
  ASSERT_TRUE(rig.hal.has_pin("modbus.0.vfd.01.at-speed"));
  rig.cycle();
  EXPECT_EQ(rig.pin("comm-ok"), "FALSE") << "polling starts with the first task cycle";
  rig.service->update(monotonic_ns());
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("comm-ok") == "TRUE"; }));

  rig.hal.set_value("modbus.0.vfd.01.speed-cmd", "9000");
  rig.hal.set_value("modbus.0.vfd.01.forward", "1");
  rig.hal.set_value("modbus.0.vfd.01.on", "1");
  rig.cycle();
  EXPECT_EQ(rig.pin("at-speed"), "FALSE");
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("at-speed") == "TRUE"; }));
  EXPECT_NEAR(rig.pin_f("speed-fb"), 9000, 9000 * 0.02);
  EXPECT_NEAR(rig.pin_f("frequency"), 150, 3);
  EXPECT_GE(rig.pin_f("fb-age"), 0.0);
  EXPECT_EQ(rig.pin("fault"), "FALSE");
  {
    uint64_t allocations = 0;
    for (int i = 0; i < 300; ++i) {
      rig.info.now_ns = monotonic_ns();
      cnc::testing::ScopedAllocationCheck check;
      rig.servo->run_cycle(rig.info);
      allocations += check.allocations();
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
    if (cnc::testing::AllocationCounter::available()) {
      EXPECT_EQ(allocations, 0u);
    }
  }
  rig.hal.set_value("modbus.0.vfd.01.forward", "0");
  rig.hal.set_value("modbus.0.vfd.01.reverse", "1");
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("at-speed") == "TRUE" && rig.pin_f("speed-fb") < 0; }));
  EXPECT_NEAR(rig.pin_f("speed-fb"), -9000, 9000 * 0.02);
}

// A running spindle whose VFD stops answering faults (spindle.N.amp-fault-in
// then stops motion and the program); the drive panel says why.
TEST(ModbusComponent, LostCommunicationWhileRunningRaisesTheFault) {
  modbus_sim::Server server(sim_config(modbus_sim::Family::Delta, true));
  server.start();
  HalRig rig(server);
  rig.service->update(monotonic_ns());
  rig.hal.set_value("modbus.0.vfd.01.speed-cmd", "6000");
  rig.hal.set_value("modbus.0.vfd.01.on", "1");
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("at-speed") == "TRUE"; }));
  server.set_silent(true);
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("fault") == "TRUE"; }));
  EXPECT_EQ(rig.pin("comm-ok"), "FALSE");
  EXPECT_EQ(rig.pin("at-speed"), "FALSE");
  EXPECT_EQ(rig.pin("drive-fault"), "FALSE");
  EXPECT_GT(rig.pin_f("fb-age"), 1.0) << "older than STALE_MS";
  ipc::Status status{};
  rig.service->contribute_status(status);
  EXPECT_TRUE(status.drives[0].present);
  EXPECT_EQ(status.drives[0].joint, -1);
  EXPECT_STREQ(status.drives[0].name.c_str(), "spindle");
  EXPECT_NE(std::string(status.drives[0].fault_text.c_str()).find("no communication"), std::string::npos)
      << status.drives[0].fault_text.c_str();
  server.set_silent(false);
  EXPECT_TRUE(rig.cycles_until([&] { return rig.pin("fault") == "FALSE" && rig.pin("comm-ok") == "TRUE"; }));
  EXPECT_NE(rig.pin("timeouts"), "0");
}

TEST(ModbusComponent, LostCommunicationWhileStoppedOrWithWarnIsNoFault) {
  modbus_sim::Server server(sim_config(modbus_sim::Family::Delta, true));
  server.start();
  HalRig rig(server, "ON_COMM_LOSS = WARN\n");
  rig.service->update(monotonic_ns());
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("comm-ok") == "TRUE"; }));
  server.set_silent(true);
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("comm-ok") == "FALSE"; }));
  EXPECT_EQ(rig.pin("fault"), "FALSE") << "stopped";
  rig.hal.set_value("modbus.0.vfd.01.speed-cmd", "6000");
  rig.hal.set_value("modbus.0.vfd.01.on", "1");
  for (int i = 0; i < 50; ++i) rig.cycle();
  EXPECT_EQ(rig.pin("fault"), "FALSE") << "ON_COMM_LOSS = WARN";
}

TEST(ModbusComponent, DriveFaultIsAFaultWithItsCode) {
  modbus_sim::Server server(sim_config(modbus_sim::Family::Delta, true));
  server.start();
  HalRig rig(server);
  rig.service->update(monotonic_ns());
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("comm-ok") == "TRUE"; }));
  server.trip_overcurrent();
  ASSERT_TRUE(rig.cycles_until([&] { return rig.pin("fault") == "TRUE"; }));
  EXPECT_EQ(rig.pin("drive-fault"), "TRUE");
  EXPECT_EQ(rig.pin("fault-code"), "1");
  rig.hal.set_value("modbus.0.vfd.01.fault-reset", "1");
  EXPECT_TRUE(rig.cycles_until([&] { return rig.pin("fault") == "FALSE"; }));
}
