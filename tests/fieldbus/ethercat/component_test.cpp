// The HAL components end to end, in-process: loadrt ethercat_sim, ethercat
// and cia402 (BUS = ethercat.0, the same drive keys as on CANopen), the
// start-up in on_ready, the servo thread's functions moving the drives;
// and the INI errors naming file, line and key.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <thread>

#include "cia402/components.hpp"
#include "core/hal/commands.hpp"
#include "core/hal/component.hpp"
#include "core/hal/hal.hpp"
#include "core/hal/thread.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"
#include "fieldbus/canopen/components.hpp"
#include "fieldbus/ethercat/components.hpp"
#include "fieldbus/ethercat/config.hpp"
#include "fieldbus/ethercat/master.hpp"
#include "sim/register.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using ::testing::HasSubstr;

namespace {

std::string machine_ini(const std::string& seg) {
  return "[EMCMOT]\nSERVO_PERIOD = 1000000\n"
         "[ETHERCAT]\nINTERFACE = sim:" + seg + "\nSLAVE = 1 2\nMISS_LIMIT = 0\n"
         "[ETHERCAT_SLAVE_1]\nNAME = x-axis\nVENDOR_ID = 0x00000CC1\n"
         "[ETHERCAT_SLAVE_2]\nNAME = y-axis\nSDO = 0x6065:0:u32 20000\n"
         "RXPDO = 0x6040:0:u16 0x607A:0:s32 0x6060:0:s8\nTXPDO = 0x6041:0:u16 0x6064:0:s32 0x6061:0:s8 0x606C:0:s32\n"
         "[CIA402]\nBUS = ethercat.0\nDRIVE = 0 1\n"
         "[CIA402_DRIVE_0]\nADDRESS = 1\nNAME = x-axis\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n"
         "[CIA402_DRIVE_1]\nADDRESS = 2\nNAME = y-axis\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n";
}

}  // namespace

TEST(EthercatComponent, LoadrtRunsCia402DrivesOverTheSimulatedBus) {
  const std::string seg = cnc::testing::unique_name("ecathal");
  const auto ini = ini::IniFile::parse(machine_ini(seg), "machine.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  canopen::register_components(registry);
  ethercat::register_components(registry);
  cia402::register_components(registry);
  sim::register_components(registry);
  MessageQueue messages;
  hal::CommandInterpreter halcmd(hal, registry, &ini, &messages);
  halcmd.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt ethercat_sim name=" + seg + " drives=2\n"
      "loadrt ethercat\n"
      "loadrt cia402\n"
      "addf ethercat.0.read servo-thread\n"
      "addf cia402.0.read servo-thread\n"
      "addf cia402.0.write servo-thread\n"
      "addf ethercat.0.write servo-thread\n",
      "test.hal");
  for (hal::Component* c : hal.components()) c->on_ready();  // start-up to SAFEOP, drive configuration
  ethercat::Master* m = ethercat::find_master(hal, "ethercat.0");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->slave_count(), 2u);
  EXPECT_TRUE(m->output(2, 0x607A, 0));
  EXPECT_TRUE(m->input(2, 0x606C, 0));   // the configured mapping
  EXPECT_FALSE(m->input(1, 0x606C, 0));  // SII default
  EXPECT_EQ(m->sdo_upload(2, 0x6065, 0).data, (std::vector<uint8_t>{0x20, 0x4E, 0, 0}));

  hal::Thread* servo = hal.find_thread("servo-thread");
  ASSERT_NE(servo, nullptr);
  rt::CycleInfo info;
  info.period_ns = 1'000'000;
  auto cycles = [&](int n, const std::function<bool()>& until) {
    for (int i = 0; i < n; ++i) {
      info.now_ns = monotonic_ns();
      servo->run_cycle(info);
      ++info.cycle;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      if (until && until()) return true;
    }
    return false;
  };
  ASSERT_TRUE(cycles(5000, [&] { return hal.get_value("ethercat.0.ready") == "TRUE"; }));
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.al-state"), "8");
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.operational"), "TRUE");
  hal.set_value("cia402.0.drive.00.enable", "TRUE");
  hal.set_value("cia402.0.drive.01.enable", "TRUE");
  ASSERT_TRUE(cycles(5000, [&] {
    return hal.get_value("cia402.0.drive.00.enabled") == "TRUE" && hal.get_value("cia402.0.drive.01.enabled") == "TRUE";
  }));
  hal.set_value("cia402.0.drive.01.pos-cmd", "0.5");  // a small step, within the drive's following window
  EXPECT_TRUE(cycles(5000, [&] { return std::abs(std::stod(hal.get_value("cia402.0.drive.01.pos-fb")) - 0.5) < 0.001; }))
      << hal.get_value("cia402.0.drive.01.pos-fb");
  {
    // The servo thread's functions (bus read, drives, bus write) never allocate.
    uint64_t allocations = 0;
    for (int i = 0; i < 300; ++i) {
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
  EXPECT_EQ(hal.get_value("ethercat.0.fault"), "FALSE");
  EXPECT_EQ(hal.get_value("ethercat.0.working-counter"), "6");
  EXPECT_NE(hal.get_value("ethercat.0.cycles"), "0");
  hal.clear();
}

TEST(EthercatComponent, CiaDriveOnAMissingBusNamesIt) {
  const auto ini = ini::IniFile::parse("[CIA402]\nBUS = ethercat.3\nDRIVE = 0\n[CIA402_DRIVE_0]\nADDRESS = 1\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n", "m.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  ethercat::register_components(registry);
  cia402::register_components(registry);
  sim::register_components(registry);
  MessageQueue messages;
  hal::CommandInterpreter halcmd(hal, registry, &ini, &messages);
  try {
    halcmd.run_text("loadrt cia402\n", "t.hal");
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("no fieldbus \"ethercat.3\" is loaded"));
  }
}

TEST(EthercatConfig, ErrorsNameFileLineAndKey) {
  auto fails = [](const std::string& text) -> std::string {
    try {
      ethercat::load_bus_settings(ini::IniFile::parse(text, "machine.ini"), "ETHERCAT", "ethercat.0");
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = eth0\n"), HasSubstr("machine.ini:2"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = eth0\n"), HasSubstr("expected raw:<interface> or sim:<segment>"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = raw:eth0\nSLAVE = 1 2 1\n"), HasSubstr("slave 1 listed twice"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = raw:eth0\nSLAVE = 1\n[ETHERCAT_SLAVE_1]\nRXPDO = 0x6040:0:u17\n"),
              HasSubstr("machine.ini:5"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = raw:eth0\nSLAVE = 1\n[ETHERCAT_SLAVE_1]\nSDO = 0x6060:0:s8\n"),
              HasSubstr("machine.ini:5"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = raw:eth0\nSLAVE = 1\n[ETHERCAT_SLAVE_1]\nWATCHDOG_MS = 1\n"),
              HasSubstr("machine.ini:5: [ETHERCAT_SLAVE_1]WATCHDOG_MS: 1 ms is shorter than two cycles (2000 us)"));
  EXPECT_THAT(fails("[ETHERCAT]\nINTERFACE = raw:eth0\nWATCHDOG_MS = 7000\n"), HasSubstr("machine.ini:3"));
  const auto wd = ethercat::load_bus_settings(
      ini::IniFile::parse("[ETHERCAT]\nINTERFACE = raw:eth0\nWATCHDOG_MS = 50\nSLAVE = 1 2\n"
                          "[ETHERCAT_SLAVE_1]\nNAME = x\n[ETHERCAT_SLAVE_2]\nWATCHDOG_MS = 0\n",
                          "machine.ini"),
      "ETHERCAT", "ethercat.0");
  EXPECT_EQ(wd.master.watchdog_ms, 50u);
  EXPECT_EQ(wd.master.slaves[0].watchdog_ms, 50u) << "the bus's value is the slaves' default";
  EXPECT_EQ(wd.master.slaves[1].watchdog_ms, 0u);
  const auto ok = ethercat::load_bus_settings(
      ini::IniFile::parse("[EMCMOT]\nSERVO_PERIOD = 250000\n[ETHERCAT]\nINTERFACE = raw:eth0\nSLAVE = 2\n"
                          "[ETHERCAT_SLAVE_2]\nNAME = z\nSDO = 0x6060:0:s8 8\nTXPDO = 0x6041:0:u16\n",
                          "machine.ini"),
      "ETHERCAT", "ethercat.0", [](const std::string& thread) { return thread == "servo-thread" ? 250'000 : 0; });
  EXPECT_EQ(ok.master.cycle_ns, 250'000) << "the period of the bus's thread, not [EMCMOT]SERVO_PERIOD";
  ASSERT_EQ(ok.master.slaves.size(), 1u);
  EXPECT_EQ(ok.master.slaves[0].sdos[0].origin, "machine.ini:8");
  EXPECT_EQ(ok.master.slaves[0].sdos[0].data, (std::vector<uint8_t>{8}));
  ASSERT_TRUE(ok.master.slaves[0].tx_pdo);
  EXPECT_EQ((*ok.master.slaves[0].tx_pdo)[0].bits, 16);
  EXPECT_FALSE(ok.master.slaves[0].rx_pdo);
}

TEST(EthercatComponent, CycleThatDiffersFromItsThreadStopsStartUp) {
  const std::string seg = cnc::testing::unique_name("ecatcycle");
  const auto ini = ini::IniFile::parse("[ETHERCAT]\nINTERFACE = sim:" + seg + "\nCYCLE_US = 2000\nSLAVE = 1\n",
                                       "machine.ini");
  hal::Hal hal;
  hal::ComponentRegistry registry;
  hal::register_core_components(registry);
  ethercat::register_components(registry);
  sim::register_components(registry);
  hal::CommandInterpreter halcmd(hal, registry, &ini, nullptr);
  halcmd.run_text(
      "loadrt threads name1=servo-thread period1=1000000\n"
      "loadrt ethercat_sim name=" + seg + " drives=1\n"
      "loadrt ethercat\n"
      "addf ethercat.0.read servo-thread\n"
      "addf ethercat.0.write servo-thread\n",
      "test.hal");
  try {
    for (hal::Component* c : hal.components()) c->on_ready();
    FAIL() << "started with a frame every 1 ms planned as 2 ms";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("machine.ini:3: [ETHERCAT]CYCLE_US = 2000 us, but ethercat.0.write runs in "
                                    "servo-thread with a period of 1000 us"));
  }
  hal.clear();
}
