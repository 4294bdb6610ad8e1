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
#include "sim/ethercat/segment.hpp"
#include "sim/register.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using ::testing::HasSubstr;

namespace {

std::string machine_ini(const std::string& seg, const std::string& bus_keys = "MISS_LIMIT = 0\n",
                        const std::string& cia402_keys = "") {
  return "[EMCMOT]\nSERVO_PERIOD = 1000000\n"
         "[ETHERCAT]\nINTERFACE = sim:" + seg + "\nSLAVE = 1 2\n" + bus_keys +
         "[ETHERCAT_SLAVE_1]\nNAME = x-axis\nVENDOR_ID = 0x00000CC1\n"
         "[ETHERCAT_SLAVE_2]\nNAME = y-axis\nSDO = 0x6065:0:u32 20000\n"
         "RXPDO = 0x6040:0:u16 0x607A:0:s32 0x6060:0:s8\nTXPDO = 0x6041:0:u16 0x6064:0:s32 0x6061:0:s8 0x606C:0:s32\n"
         "[CIA402]\nBUS = ethercat.0\nDRIVE = 0 1\n" + cia402_keys +
         "[CIA402_DRIVE_0]\nADDRESS = 1\nNAME = x-axis\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n"
         "[CIA402_DRIVE_1]\nADDRESS = 2\nNAME = y-axis\nENCODER_COUNTS = 10000\nSCREW_LEAD = 5\n";
}

// ethercat_sim, ethercat and cia402 in one HAL with a servo thread run by
// hand on the real clock (the simulated segment answers in-process).
struct SimMachine {
  explicit SimMachine(const std::string& seg_name, const std::string& ini_text)
      : seg(seg_name), ini(ini::IniFile::parse(ini_text, "machine.ini")) {
    hal::register_core_components(registry);
    canopen::register_components(registry);
    ethercat::register_components(registry);
    cia402::register_components(registry);
    sim::register_components(registry);
    halcmd = std::make_unique<hal::CommandInterpreter>(hal, registry, &ini, &messages);
    halcmd->run_text(
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
    servo = hal.find_thread("servo-thread");
    info.period_ns = 1'000'000;
  }
  ~SimMachine() { hal.clear(); }
  // Runs up to n cycles, 0.5 ms apart, until `until` holds.
  bool cycles(int n, const std::function<bool()>& until) {
    for (int i = 0; i < n; ++i) {
      info.now_ns = monotonic_ns();
      servo->run_cycle(info);
      ++info.cycle;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
      if (until && until()) return true;
    }
    return false;
  }
  bool enable_both() {
    if (!cycles(5000, [&] { return hal.get_value("ethercat.0.ready") == "TRUE"; })) return false;
    hal.set_value("cia402.0.drive.00.enable", "TRUE");
    hal.set_value("cia402.0.drive.01.enable", "TRUE");
    return cycles(5000, [&] {
      return hal.get_value("cia402.0.drive.00.enabled") == "TRUE" && hal.get_value("cia402.0.drive.01.enabled") == "TRUE";
    });
  }
  bool has_message(const std::string& part) {
    Message m;
    while (messages.pop(m)) log += std::string(m.text.c_str()) + "\n";
    return log.find(part) != std::string::npos;
  }

  std::string seg;
  ini::IniFile ini;
  hal::Hal hal;
  hal::ComponentRegistry registry;
  MessageQueue messages;
  std::unique_ptr<hal::CommandInterpreter> halcmd;
  hal::Thread* servo = nullptr;
  rt::CycleInfo info;
  std::string log;
};

}  // namespace

TEST(EthercatComponent, LoadrtRunsCia402DrivesOverTheSimulatedBus) {
  const std::string seg = cnc::testing::unique_name("ecathal");
  SimMachine sm(seg, machine_ini(seg));
  auto& hal = sm.hal;
  ethercat::Master* m = ethercat::find_master(hal, "ethercat.0");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->slave_count(), 2u);
  EXPECT_TRUE(m->output(2, 0x607A, 0));
  EXPECT_TRUE(m->input(2, 0x606C, 0));   // the configured mapping
  EXPECT_FALSE(m->input(1, 0x606C, 0));  // SII default
  EXPECT_EQ(m->sdo_upload(2, 0x6065, 0).data, (std::vector<uint8_t>{0x20, 0x4E, 0, 0}));

  ASSERT_NE(sm.servo, nullptr);
  ASSERT_TRUE(sm.cycles(5000, [&] { return hal.get_value("ethercat.0.ready") == "TRUE"; }));
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.al-state"), "8");
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.operational"), "TRUE");
  ASSERT_TRUE(sm.enable_both());
  hal.set_value("cia402.0.drive.01.pos-cmd", "0.5");  // a small step, within the drive's following window
  EXPECT_TRUE(sm.cycles(5000, [&] { return std::abs(std::stod(hal.get_value("cia402.0.drive.01.pos-fb")) - 0.5) < 0.001; }))
      << hal.get_value("cia402.0.drive.01.pos-fb");
  {
    // The servo thread's functions (bus read, drives, bus write) never allocate.
    uint64_t allocations = 0;
    for (int i = 0; i < 300; ++i) {
      sm.info.now_ns = monotonic_ns();
      cnc::testing::ScopedAllocationCheck check;
      sm.servo->run_cycle(sm.info);
      allocations += check.allocations();
      ++sm.info.cycle;
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    if (cnc::testing::AllocationCounter::available()) {
      EXPECT_EQ(allocations, 0u);
    }
  }
  EXPECT_EQ(hal.get_value("ethercat.0.fault"), "FALSE");
  EXPECT_EQ(hal.get_value("ethercat.0.working-counter"), "6");
  EXPECT_NE(hal.get_value("ethercat.0.cycles"), "0");
}

// The stale-feedback budget on EtherCAT: with the bus's own limit set high
// (MISS_LIMIT = 100, as a test host needs), lost frames stop the drives
// after [CIA402]STALE_LIMIT cycles, long before the bus's safe stop; a
// loss within the budget is ridden through.
TEST(EthercatComponent, LostFramesStopTheDrivesAfterStaleLimitCyclesNotMissLimit) {
  const std::string seg = cnc::testing::unique_name("ecatstale");
  SimMachine sm(seg, machine_ini(seg, "MISS_LIMIT = 100\n", "STALE_LIMIT = 5\n"));
  ASSERT_TRUE(sm.enable_both());
  auto segment = ethercat::sim::find_segment(seg);
  ASSERT_TRUE(segment);
  auto& hal = sm.hal;
  segment->drop_frames(4);  // within the budget
  sm.cycles(20, {});
  EXPECT_EQ(hal.get_value("cia402.0.drive.00.link-ok"), "TRUE");
  EXPECT_EQ(hal.get_value("cia402.0.drive.00.amp-fault"), "FALSE");
  EXPECT_FALSE(sm.has_message("no fresh feedback"));

  segment->drop_frames(1'000'000);
  int cycles = 0;
  ASSERT_TRUE(sm.cycles(200, [&] { return ++cycles, hal.get_value("cia402.0.drive.00.link-ok") == "FALSE"; }));
  EXPECT_LE(cycles, 5 + 2) << "stopped after STALE_LIMIT stale cycles (one more to see the first loss)";
  EXPECT_EQ(hal.get_value("ethercat.0.fault"), "FALSE") << "the bus's MISS_LIMIT (100) has not run out yet";
  EXPECT_EQ(hal.get_value("cia402.0.drive.00.amp-fault"), "TRUE");
  EXPECT_EQ(hal.get_value("cia402.0.drive.01.amp-fault"), "TRUE");
  EXPECT_TRUE(sm.has_message("no fresh feedback for 6 cycles on ethercat.0 (STALE_LIMIT = 5)"));
  segment->drop_frames(0);
}

// Without anyone asking, the master's worker reads the slaves' error
// counters every second on the real clock: what an injected corrupted
// frame leaves at a port shows on that port's HAL pins and in a message
// naming slave and port.
TEST(EthercatComponent, SlaveErrorCountersArePolledAndShownPerPort) {
  const std::string seg = cnc::testing::unique_name("ecatcounters");
  SimMachine sm(seg, machine_ini(seg));
  auto& hal = sm.hal;
  ASSERT_TRUE(sm.cycles(5000, [&] { return hal.get_value("ethercat.0.ready") == "TRUE"; }));
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.port-0.rx-errors"), "0");
  auto segment = ethercat::sim::find_segment(seg);
  ASSERT_TRUE(segment);
  segment->slave(1).inject_invalid_frames(0, 3);
  segment->slave(0).inject_lost_link(1);
  // The poll is due within a second; up to 3 s of cycles (0.5 ms sleeps).
  ASSERT_TRUE(sm.cycles(6000, [&] {
    return hal.get_value("ethercat.0.slave.02.port-0.rx-errors") == "3" &&
           hal.get_value("ethercat.0.slave.01.port-1.lost-links") == "1";
  })) << hal.get_value("ethercat.0.slave.02.port-0.rx-errors") << " " << sm.log;
  EXPECT_EQ(hal.get_value("ethercat.0.slave.02.port-1.rx-errors"), "0");
  EXPECT_EQ(hal.get_value("ethercat.0.slave.01.port-0.rx-errors"), "0");
  EXPECT_TRUE(sm.has_message("error counters slave 2 (y-axis): port 0: 3 invalid frames")) << sm.log;
  EXPECT_TRUE(sm.has_message("error counters slave 1 (x-axis): port 1: 1 lost link")) << sm.log;
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
