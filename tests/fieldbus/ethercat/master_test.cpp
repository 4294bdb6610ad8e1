// The master against simulated CiA 402 drives on an in-process segment:
// bring-up to OP, CiA 402 drives enabled and moving over CoE, the cycle
// without allocation, DC lock, and every injected fault ending in a safe
// stop (or a stopped start-up) with a message naming slave and reason.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "cia402/drive_group.hpp"
#include "fieldbus/ethercat/cia402_binding.hpp"
#include "tests/fieldbus/ethercat/bus.hpp"

namespace cnc::ethercat {
namespace {

using test::Bus;
using ::testing::HasSubstr;

TEST(EthercatMaster, BringsThreeDrivesToOp) {
  Bus bus(3);
  ASSERT_EQ(bus.master->slave_count(), 3u);
  EXPECT_EQ(bus.master->slaves()[0].sii.name, "drive-1");
  EXPECT_EQ(bus.master->slaves()[0].sii.order, "CNC-SIM-402");
  EXPECT_EQ(bus.master->slaves()[2].sii.serial, 3u);
  EXPECT_EQ(bus.master->expected_wkc(), 9);
  EXPECT_TRUE(bus.master->uses_dc());
  EXPECT_EQ(bus.master->phase(), BusPhase::SafeOp);
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages() << bus.master->fault_text();
  for (unsigned p = 1; p <= 3; ++p) {
    EXPECT_EQ(bus.segment->slave(p - 1).state(), AlState::Op);
    EXPECT_EQ(bus.master->slave_al_state(p), 8);
  }
  bus.run_until([] { return false; }, 50);
  EXPECT_EQ(bus.master->counters().last_wkc.load(), 9);
  EXPECT_TRUE(bus.master->counters().inputs_fresh.load());
  EXPECT_FALSE(bus.master->has_fault());
  EXPECT_THAT(bus.drain_messages(), HasSubstr("3 slaves in OP"));
}

TEST(EthercatMaster, PdoConfigurationByCompleteAccess) {
  MasterConfig cfg;
  for (unsigned p : {1u, 2u}) {
    SlaveConfig s;
    s.position = p;
    s.complete_access = true;
    s.rx_pdo = std::vector<PdoEntryConfig>{{0x6040, 0, 16}, {0x607A, 0, 32}};
    cfg.slaves.push_back(s);
  }
  Bus bus(2, cfg, false);
  const uint64_t before = bus.segment->drive(0)->sdo_requests();
  bus.start_up();
  // Three transfers (and their read-backs) per direction instead of one per entry.
  EXPECT_LT(bus.segment->drive(0)->sdo_requests() - before, 20u);
  EXPECT_EQ(bus.segment->drive(0)->od().get<uint8_t>({0x1600, 0}), 2);
  EXPECT_EQ(bus.master->output_bytes(), 12u);
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
}

TEST(EthercatMaster, ProcessImageFollowsTheMapping) {
  Bus bus(2);
  // Default mapping: outputs 6040 u16, 607A s32, 6060 s8 (7 B); inputs 6041, 6064, 6061, 603F (9 B).
  EXPECT_EQ(bus.master->output_bytes(), 14u);
  EXPECT_EQ(bus.master->input_bytes(), 18u);
  const ProcessSlot t2 = bus.master->output(2, 0x607A, 0);
  ASSERT_TRUE(t2);
  EXPECT_EQ(t2.bit_offset, (7 + 2) * 8);
  EXPECT_EQ(t2.bit_length, 32);
  EXPECT_FALSE(bus.master->output(2, 0x60FF, 0));
  EXPECT_EQ(bus.master->input(1, 0x6064, 0).bit_offset, 16);
}

TEST(EthercatMaster, Cia402DrivesEnableAndMoveOverCoe) {
  Bus bus(3);
  auto link = make_cia402_link(*bus.master);
  cia402::GroupConfig gc;
  gc.name = "cia402.0";
  gc.bus = bus.master->name();
  for (int i = 0; i < 3; ++i) {
    cia402::DriveEntry e;
    e.number = i;
    e.config.name = "axis-" + std::to_string(i);
    e.config.source = "cia402.0.drive.0" + std::to_string(i);
    e.config.address = i + 1;
    e.config.scaling.counts_per_unit = 1000;
    gc.drives.push_back(e);
  }
  cia402::DriveGroup group(gc, *link, &bus.messages);
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
  std::thread cfg([&] { group.configure(); });  // blocking SDOs while the servo cycle runs
  bus.run_until([] { return false; }, 300);
  cfg.join();
  double cmd = 0;
  int cycle = 0;
  auto app = [&] {
    const int64_t t = bus.time.load();
    group.read(t);
    for (std::size_t i = 0; i < group.size(); ++i) {
      group.command(i).enable = true;
      group.command(i).pos_cmd = cmd * static_cast<double>(i + 1);
    }
    group.write(t);
  };
  ASSERT_TRUE(bus.run_until([&] { return group.feedback(0).enabled && group.feedback(1).enabled && group.feedback(2).enabled; },
                            5000, app))
      << bus.drain_messages();
  // A 10 mm move at 20 mm/s.
  for (cycle = 0; cycle < 700; ++cycle) {
    cmd = std::min(10.0, cycle * 0.02);
    bus.cycle(app);
  }
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(group.feedback(i).pos_fb, 10.0 * static_cast<double>(i + 1), 0.05) << "drive " << i;
    EXPECT_NEAR(static_cast<double>(bus.segment->drive(i)->model().position()), 10000.0 * static_cast<double>(i + 1), 50);
  }
  EXPECT_FALSE(bus.master->has_fault()) << bus.master->fault_text();
}

TEST(EthercatMaster, CycleDoesNotAllocate) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  if (!cnc::testing::AllocationCounter::available()) GTEST_SKIP() << "no allocation counter in this build";
  uint64_t allocations = 0;
  {
    cnc::testing::ScopedAllocationCheck check;
    for (int i = 0; i < 2000; ++i) bus.cycle({}, false);
    allocations = check.allocations();
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_FALSE(bus.master->has_fault());
}

TEST(EthercatMaster, LostFramesStopTheBusSafely) {
  MasterConfig cfg;
  cfg.miss_limit = 3;
  Bus bus(3, cfg);
  ASSERT_TRUE(bus.reach_op());
  bus.segment->drop_frames(2);  // two lost cycles: tolerated
  bus.run_until([] { return false; }, 20);
  EXPECT_FALSE(bus.master->has_fault());
  EXPECT_EQ(bus.master->counters().frames_lost.load(), 2u);
  bus.segment->drop_frames(1000);
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  EXPECT_TRUE(bus.master->has_fault());
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("safe stop: 3 consecutive cycles without valid process data"));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("no frame comes back"));
}

TEST(EthercatMaster, WrongWorkingCounterStopsTheBus) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  bus.segment->corrupt_wkc(5, -2);
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("last working counter 7, expected 9"));
  EXPECT_GE(bus.master->counters().wkc_errors.load(), 3u);
}

TEST(EthercatMaster, CableBreakNamesTheLastSlaveReached) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  bus.segment->break_after(2);
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("only 2 of 3 slaves answer: link lost after slave 2 (drive-2)"));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("expected 9"));
  // The drive behind the break loses its outputs: its watchdog takes it to SAFEOP.
  bus.run_until([] { return false; }, 150);
  bus.segment->poll();
  EXPECT_EQ(bus.segment->slave(2).state(), AlState::SafeOp);
  EXPECT_EQ(bus.segment->slave(2).al_status_code(), al::kSmWatchdog);
}

TEST(EthercatMaster, RestartsAfterTheCableIsMended) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  const ProcessSlot slot = bus.master->input(3, 0x6064, 0);
  bus.segment->break_after(2);
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  bus.master->request_restart();  // still broken: the restart names why it failed
  ASSERT_TRUE(bus.run_until([&] { return bus.master->fault_text().find("restart") != std::string::npos; }, 5000))
      << bus.master->fault_text();
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("restart: 2 slaves answer, 3 were configured before"));
  bus.segment->break_after(0);
  bus.master->request_restart();
  ASSERT_TRUE(bus.run_until([&] { return bus.master->is_operational(); }, 20000)) << bus.master->fault_text();
  EXPECT_TRUE(bus.master->fault_text().empty());
  EXPECT_EQ(bus.master->input(3, 0x6064, 0).bytes, slot.bytes);  // the drives' slots still hold
  bus.run_until([] { return false; }, 50);
  EXPECT_EQ(bus.master->counters().last_wkc.load(), 9);
  EXPECT_THAT(bus.drain_messages(), HasSubstr("restarted after the fault"));
}

TEST(EthercatMaster, ProcessDataWatchdogDropsSlaveToSafeOp) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  bus.time.fetch_add(150'000'000);  // the servo thread stalls for 150 ms
  bus.segment->poll();
  EXPECT_EQ(bus.segment->slave(0).state(), AlState::SafeOp);
  EXPECT_TRUE(bus.segment->slave(0).error_indicated());
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("a slave left OP"));
  EXPECT_THAT(bus.master->fault_text(),
              HasSubstr("slave 1 (drive-1) is in SAFEOP with AL status code 0x001B sync manager watchdog"));
}

// ---------------------------------------------------------------- SM watchdog

namespace {
MasterConfig watchdogs(std::initializer_list<uint32_t> ms) {
  MasterConfig cfg;
  unsigned p = 0;
  for (uint32_t m : ms) {
    SlaveConfig s;
    s.position = ++p;
    s.watchdog_ms = m;
    cfg.slaves.push_back(s);
  }
  return cfg;
}
}  // namespace

TEST(EthercatMaster, TheSmWatchdogIsConfiguredAsTheIniSays) {
  Bus bus(3, watchdogs({100, 20, 0}));
  EXPECT_TRUE(bus.segment->slave(0).watchdog_enabled());
  EXPECT_EQ(bus.segment->slave(0).watchdog_time_ns(), 100'000'000);
  EXPECT_TRUE(bus.segment->slave(1).watchdog_enabled());
  EXPECT_EQ(bus.segment->slave(1).watchdog_time_ns(), 20'000'000);
  EXPECT_FALSE(bus.segment->slave(2).watchdog_enabled()) << "WATCHDOG_MS = 0 switches it off";
  EXPECT_FALSE(bus.segment->slave(2).sm(2).control & sm::kWatchdogTrigger);
}

// A device description whose output SM lacks the watchdog trigger bit
// (control 0x24) would leave the slave unwatched: the master sets it.
TEST(EthercatMaster, TheWatchdogIsOnEvenWhenTheSiiLeavesItsBitOff) {
  sim::CoeDriveConfig d;
  d.sm2_control = 0x24;
  Bus bus(2, {}, true, d);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(bus.segment->slave(i).sm(2).control, 0x64) << "slave " << i + 1;
    EXPECT_TRUE(bus.segment->slave(i).watchdog_enabled());
    EXPECT_EQ(bus.segment->slave(i).watchdog_time_ns(), 100'000'000) << "the default";
  }
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
  bus.time.fetch_add(150'000'000);  // the servo thread stalls
  bus.segment->poll();
  EXPECT_EQ(bus.segment->slave(0).state(), AlState::SafeOp);
  EXPECT_EQ(bus.segment->slave(0).al_status_code(), al::kSmWatchdog);
}

// The master stops (servo thread stopped, `delf ethercat.0.write`,
// ethercat.0.enable FALSE): no frame arrives any more. Each drive stops by
// itself within its configured watchdog time plus its fault reaction.
TEST(EthercatMaster, WhenFramesStopTheDrivesStopWithinTheirWatchdogTime) {
  Bus bus(2, watchdogs({20, 50}));
  auto link = make_cia402_link(*bus.master);
  cia402::GroupConfig gc;
  gc.name = "cia402.0";
  gc.bus = bus.master->name();
  for (int i = 0; i < 2; ++i) {
    cia402::DriveEntry e;
    e.number = i;
    e.config.name = "axis-" + std::to_string(i);
    e.config.source = "cia402.0.drive.0" + std::to_string(i);
    e.config.address = i + 1;
    e.config.scaling.counts_per_unit = 1000;
    gc.drives.push_back(e);
  }
  cia402::DriveGroup group(gc, *link, &bus.messages);
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
  std::thread cfg([&] { group.configure(); });
  bus.run_until([] { return false; }, 300);
  cfg.join();
  double cmd = 0;
  auto app = [&] {
    const int64_t t = bus.time.load();
    group.read(t);
    for (std::size_t i = 0; i < group.size(); ++i) {
      group.command(i).enable = true;
      group.command(i).pos_cmd = cmd;
    }
    group.write(t);
  };
  ASSERT_TRUE(bus.run_until([&] { return group.feedback(0).enabled && group.feedback(1).enabled; }, 5000, app))
      << bus.drain_messages();
  for (int c = 0; c < 200; ++c) {
    cmd += 0.02;  // 20 mm/s
    bus.cycle(app);
  }
  bus.master->stop();  // nothing is sent any more, not even mailbox polls
  const int64_t last_frame = bus.time.load() - bus.master->config().cycle_ns;
  auto drive = [&](std::size_t i) { return bus.segment->drive(i)->model().state(); };
  auto advance_to = [&](int64_t since_last_frame) {
    while (bus.time.load() < last_frame + since_last_frame) {
      bus.time.fetch_add(100'000);
      bus.segment->poll();
    }
  };
  advance_to(19'000'000);
  EXPECT_EQ(bus.segment->slave(0).state(), AlState::Op) << "not before its 20 ms";
  EXPECT_EQ(drive(0), cia402::State::OperationEnabled);
  advance_to(20'200'000);
  EXPECT_EQ(bus.segment->slave(0).state(), AlState::SafeOp);
  EXPECT_EQ(bus.segment->slave(0).al_status_code(), al::kSmWatchdog);
  EXPECT_EQ(bus.segment->slave(1).state(), AlState::Op) << "its watchdog is 50 ms";
  advance_to(49'000'000);
  EXPECT_EQ(bus.segment->slave(1).state(), AlState::Op);
  EXPECT_EQ(drive(1), cia402::State::OperationEnabled);
  advance_to(50'200'000);
  EXPECT_EQ(bus.segment->slave(1).state(), AlState::SafeOp);
  advance_to(200'000'000);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(drive(i), cia402::State::Fault) << "drive " << i + 1;
    EXPECT_EQ(bus.segment->drive(i)->model().error_code(), cia402::err::kRpdoTimeout) << "the watchdog is the reason";
    EXPECT_EQ(bus.segment->drive(i)->model().plant().motor_velocity(), 0.0);
    EXPECT_EQ(bus.segment->slave(i).watchdog_expiries(), 1u);
  }
}

// A drive lost on EtherCAT is reported in EtherCAT's terms: there is no
// heartbeat on this bus, the loss is the master's safe stop.
TEST(EthercatMaster, ALostDriveIsReportedInEthercatTermsNotCanopenOnes) {
  Bus bus(1);
  auto link = make_cia402_link(*bus.master);
  cia402::GroupConfig gc;
  gc.name = "cia402.0";
  gc.bus = bus.master->name();
  cia402::DriveEntry e;
  e.config.name = "axis-0";
  e.config.source = "cia402.0.drive.00";
  e.config.address = 1;
  e.config.scaling.counts_per_unit = 1000;
  gc.drives.push_back(e);
  cia402::DriveGroup group(gc, *link, &bus.messages);
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
  std::thread cfg([&] { group.configure(); });
  bus.run_until([] { return false; }, 300);
  cfg.join();
  auto app = [&] {
    group.read(bus.time.load());
    group.command(0).enable = true;
    group.write(bus.time.load());
  };
  ASSERT_TRUE(bus.run_until([&] { return group.feedback(0).enabled; }, 5000, app)) << bus.drain_messages();
  bus.drain_messages();
  bus.segment->drop_frames(1'000'000);
  ASSERT_TRUE(bus.run_until([&] { return bus.master->has_fault(); }, 100, app));
  for (int i = 0; i < 3; ++i) bus.cycle(app);
  const std::string m = bus.drain_messages();
  EXPECT_THAT(m, HasSubstr("lost the drive on " + bus.master->name() +
                           " (process data lost (frames lost or working-counter errors) or a slave left OP)"));
  EXPECT_THAT(m, ::testing::Not(HasSubstr("heartbeat")));
}

// The slaves' error counters (0x0300-0x0313) are cleared at start-up,
// read per port, and what grows is reported naming slave and port; a safe
// stop's message carries them.
TEST(EthercatMaster, SlaveErrorCountersAreReadAndReportedPerPort) {
  Bus bus(3, {}, false);
  bus.segment->slave(1).inject_invalid_frames(0, 9);  // before start-up: cleared by it
  bus.start_up();
  ASSERT_TRUE(bus.reach_op()) << bus.drain_messages();
  auto c = bus.master->read_error_counters();
  ASSERT_EQ(c.size(), 3u);
  EXPECT_FALSE(c[1].any()) << c[1].text();
  bus.drain_messages();
  bus.segment->slave(1).inject_invalid_frames(0, 3);
  bus.segment->slave(2).inject_lost_link(1);
  c = bus.master->read_error_counters();
  EXPECT_EQ(c[1].invalid_frames[0], 3);
  EXPECT_EQ(c[1].text(), "port 0: 3 invalid frames");
  EXPECT_EQ(c[2].text(), "port 1: 1 lost link");
  EXPECT_FALSE(c[0].any());
  const std::string m = bus.drain_messages();
  EXPECT_THAT(m, HasSubstr("error counters slave 2 (drive-2): port 0: 3 invalid frames (an invalid frame"));
  EXPECT_THAT(m, HasSubstr("error counters slave 3 (drive-3): port 1: 1 lost link"));
  // Only growth is reported again.
  bus.segment->slave(1).inject_invalid_frames(0, 1);
  bus.master->read_error_counters();
  EXPECT_THAT(bus.drain_messages(), HasSubstr("slave 2 (drive-2): port 0: 1 invalid frame ("));
  // The safe stop names them (of the slaves still reached).
  bus.segment->break_after(2);
  ASSERT_TRUE(bus.run_until([&] { return !bus.master->fault_text().empty(); }, 2000));
  EXPECT_THAT(bus.master->fault_text(), HasSubstr("slave 2 (drive-2) error counters: port 0: 4 invalid frames"));
}

TEST(EthercatMaster, SlaveRefusingSafeOpStopsStartUp) {
  Bus bus(3, {}, false);
  bus.segment->slave(1).refuse_state(AlState::SafeOp, al::kSyncError);
  try {
    bus.master->start_up();
    FAIL() << "start-up went through";
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("ethercat.0: start-up stopped: slave 2 (drive-2): PREOP -> SAFEOP refused: "
                                    "AL status code 0x001A synchronisation error (slave stays in PREOP)"));
  }
}

TEST(EthercatMaster, SdoAbortStopsStartUpWithObjectAndReason) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 2;
  s.name = "y-axis";
  s.sdos.push_back({0x6060, 0, {8}, "machine.ini:12"});
  cfg.slaves.push_back(s);
  Bus bus(3, cfg, false);
  bus.segment->drive(1)->abort_sdo(0x6060, 0x06090030);
  try {
    bus.master->start_up();
    FAIL() << "start-up went through";
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("slave 2 (y-axis): writing 0x6060:00 = 0x08 (value from machine.ini:12) refused: "
                                    "aborted by the slave: 0x06090030"));
  }
}

TEST(EthercatMaster, EveryWrittenValueIsReadBack) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 1;
  s.name = "x-axis";
  s.sdos.push_back({0x6065, 0, {0x10, 0x27, 0, 0}, "machine.ini:20"});
  cfg.slaves.push_back(s);
  Bus bus(1, cfg, false);
  // A slave that quietly keeps another value than the one written.
  canopen::ObjectDictionary& od = bus.segment->drive(0)->od();
  od.set_after_write({0x6065, 0}, [&od](const canopen::OdEntry&) { od.set<uint32_t>({0x6065, 0}, 5000); });
  try {
    bus.master->start_up();
    FAIL() << "start-up went through";
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("slave 1 (x-axis): verification of 0x6065:00 (value from machine.ini:20) failed: "
                                    "the slave has 0x00001388 after 0x00002710 was written"));
  }
}

TEST(EthercatMaster, UnmappableObjectStopsStartUp) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 1;
  s.rx_pdo = std::vector<PdoEntryConfig>{{0x6040, 0, 16}, {0x1018, 1, 32}};
  cfg.slaves.push_back(s);
  Bus bus(1, cfg, false);
  try {
    bus.master->start_up();
    FAIL() << "start-up went through";
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("slave 1 (drive-1): writing 0x1600:02 = 0x10180120 "
                                    "(RxPDO mapping entry 2: 0x1018:01, 32 bits) refused: aborted by the slave: 0x06040041"));
  }
}

TEST(EthercatMaster, WrongIdentityStopsStartUp) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 3;
  s.name = "z-axis";
  s.vendor_id = 0x00000002;
  cfg.slaves.push_back(s);
  Bus bus(3, cfg, false);
  EXPECT_THROW(
      {
        try {
          bus.master->start_up();
        } catch (const StartupError& e) {
          EXPECT_THAT(e.what(), HasSubstr("slave 3 (z-axis): identity: vendor ID is 0x00000CC1, expected 0x00000002"));
          throw;
        }
      },
      StartupError);
}

TEST(EthercatMaster, MissingSlaveStopsStartUp) {
  MasterConfig cfg;
  SlaveConfig s;
  s.position = 4;
  s.name = "a-axis";
  cfg.slaves.push_back(s);
  Bus bus(3, cfg, false);
  try {
    bus.master->start_up();
    FAIL();
  } catch (const StartupError& e) {
    EXPECT_THAT(e.what(), HasSubstr("configured slave 4 (a-axis) is missing: only 3 slaves answer"));
  }
}

TEST(EthercatMaster, EmergencyReachesTheMessageChannel) {
  Bus bus(2);
  ASSERT_TRUE(bus.reach_op());
  bus.segment->drive(1)->model().inject_overcurrent();
  bus.run_until([&] { return bus.master->slave_emcy_count(2) > 0; }, 3000);
  EXPECT_EQ(bus.master->slave_emcy_code(2), 0x2310);
  EXPECT_THAT(bus.drain_messages(), HasSubstr("slave 2 (drive-2): EMCY 0x2310"));
}

TEST(EthercatMaster, LockedFramesMeetEverySync0) {
  Bus bus(3);
  ASSERT_TRUE(bus.reach_op());
  bus.run_until([] { return false; }, 500);  // the lock settles
  uint64_t missed[3], pulses[3], overwritten[3];
  for (std::size_t i = 0; i < 3; ++i) {
    missed[i] = bus.segment->drive(i)->sync_events_missed();
    overwritten[i] = bus.segment->drive(i)->outputs_overwritten();
    pulses[i] = bus.segment->slave(i).sync0_pulses();
  }
  bus.run_until([] { return false; }, 2000);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(bus.segment->drive(i)->sync_events_missed(), missed[i]) << "drive " << i + 1;
    EXPECT_NEAR(static_cast<double>(bus.segment->slave(i).sync0_pulses() - pulses[i]), 2000.0, 2.0);
    EXPECT_EQ(bus.segment->drive(i)->outputs_overwritten(), overwritten[i]);
  }
  // One frame that never left: each drive's next SYNC0 finds no new set-point (0x1C32:0B).
  bus.master->cyclic_read(bus.time.load());
  bus.time.fetch_add(1'000'000 + bus.master->take_phase_adjust());
  bus.run_until([] { return false; }, 5);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(bus.segment->drive(i)->sync_events_missed(), missed[i] + 1);
    EXPECT_EQ(bus.segment->drive(i)->od().get<uint16_t>({0x1C32, 0x0B}), missed[i] + 1);
  }
}

TEST(EthercatMaster, ServoThreadLocksToTheDriftingReferenceClock) {
  for (const bool lock : {true, false}) {
    Bus bus(3);
    bus.lock = lock;
    ASSERT_TRUE(bus.reach_op());
    bus.run_until([] { return false; }, 10);
    const int64_t start = bus.master->phase_lock().offset_ns();
    bus.run_until([] { return false; }, 3000);
    const int64_t offset = bus.master->phase_lock().offset_ns();
    if (lock) {
      EXPECT_TRUE(bus.master->phase_lock().is_locked());
      EXPECT_LT(std::abs(offset), 2000) << "reference drifts 25 ppm; the lock must follow it";
      EXPECT_LT(bus.master->phase_lock().stats().max_abs, 20'000);
      EXPECT_GT(bus.master->phase_lock().stats().count, 1000u);
    } else {
      // Without the lock the phase walks away at 25 ns per cycle (the reference runs 25 ppm fast).
      // (The phase is taken modulo the cycle.)
      int64_t walked = ((offset - start) % 1'000'000 + 1'000'000) % 1'000'000;
      if (walked >= 500'000) walked -= 1'000'000;
      EXPECT_NEAR(static_cast<double>(walked), 75'000.0, 5'000.0);
    }
    // The slaves' drift loops hold their system times together.
    EXPECT_LT(bus.master->counters().dc_sync_diff_ns.load(), 1000u);
  }
}

}  // namespace
}  // namespace cnc::ethercat
