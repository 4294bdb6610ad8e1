// The drive-parameter restore (commission/restore.hpp) and the EtherCAT
// backup: backup -> a parameter changed in the drive -> restore -> the
// drive's values equal the backup's again, on simulated CANopen drives
// (in-process CAN bus, the simulator host's own thread, real-time clock)
// and on simulated EtherCAT CoE drives (an in-process segment, "sim:").
// Identity checks and bad input write nothing.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "commission/backup.hpp"
#include "commission/restore.hpp"
#include "core/ipc/server.hpp"
#include "core/util/atomic_file.hpp"
#include "fieldbus/ethercat/master.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_host.hpp"
#include "sim/ethercat/segment.hpp"
#include "tests/commission/sim_bus_scan.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

using CanBus = e2e::SimulatedCanDrives;

// Axes on joints 0, 1, ... driven by the given CANopen nodes or, with
// `ethercat`, EtherCAT slave positions.
State state_with_axes(const std::vector<std::pair<char, int>>& axes, bool ethercat) {
  State s;
  int joint = 0;
  for (const auto& [letter, drive] : axes) {
    Axis a;
    a.letter = letter;
    a.joint = joint++;
    (ethercat ? a.slave : a.node) = drive;
    s.axes.push_back(a);
  }
  return s;
}

State canopen_state(const std::vector<std::pair<char, int>>& axes) {
  State s = state_with_axes(axes, false);
  s.interface = "virtual:restore";
  return s;
}

constexpr int64_t kTimeout = 1'000'000'000;  // a loaded test host may stall the simulator's thread

std::vector<uint8_t> u32(uint32_t v) { return {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)}; }
uint32_t as_u32(const std::vector<uint8_t>& d) {
  uint32_t v = 0;
  for (std::size_t i = 0; i < d.size() && i < 4; ++i) v |= uint32_t{d[i]} << (8 * i);
  return v;
}

// Backs up the state's drives into `dir` (CANopen over `bus`).
std::vector<BackupFile> canopen_backup(can::Transport& bus, State& s, const std::filesystem::path& dir) {
  BackupOptions o;
  o.timeout_ns = kTimeout;
  BackupResult r = backup_drives(bus, s, o);
  EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
  write_backup(s, r, dir);
  return load_backup_dir(dir);
}

TEST(CommissionRestore, CanopenBackupThenAChangedParameterIsWrittenBackAndReadsBackEqual) {
  CanBus b;
  b.add(1);
  b.add(2);
  b.start();
  State s = canopen_state({{'X', 1}, {'Y', 2}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[0].node, 1);
  EXPECT_EQ(files[0].axis, 'X');
  const uint32_t window = as_u32(files[0].find(0x6065, 0)->data);

  // Someone changes node 1's following-error window and node 2's home offset.
  auto x = canopen_channel(*b.client, 1, kTimeout);
  auto y = canopen_channel(*b.client, 2, kTimeout);
  ASSERT_TRUE(x->download({0x6065, 0}, u32(window + 777)).ok);
  ASSERT_TRUE(y->download({0x607C, 0}, u32(static_cast<uint32_t>(-500))).ok);
  // And node 2's loop gains (step 7 writes the velocity loop's).
  const BackupEntry* kv = files[1].find(0x60F9, 1);
  const BackupEntry* kp = files[1].find(0x60FB, 1);
  ASSERT_TRUE(kv && kp) << "the loop gains are not backed up";
  ASSERT_TRUE(y->download({0x60F9, 1}, u32(as_u32(kv->data) * 2)).ok);
  ASSERT_TRUE(y->download({0x60FB, 1}, u32(as_u32(kp->data) + 100)).ok);

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  // The dry run lists them and writes nothing.
  const RestoreResult dry = restore_drives(files, buses, true);
  ASSERT_TRUE(dry.ok()) << describe(dry);
  ASSERT_EQ(dry.drives.size(), 2u);
  ASSERT_EQ(dry.drives[0].changes.size(), 1u) << describe(dry);
  EXPECT_EQ(dry.drives[0].changes[0].entry.addr, (canopen::ObjectAddress{0x6065, 0}));
  EXPECT_NE(describe(dry).find("node 1 (axis X, node-01-x.dcf): 1 parameter(s) differ"), std::string::npos) << describe(dry);
  EXPECT_NE(describe(dry).find("would write 0x607C:00 Home offset: -500 -> 0"), std::string::npos) << describe(dry);
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window + 777);

  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  EXPECT_TRUE(r.drives[0].changes[0].written);
  EXPECT_NE(describe(r).find("wrote 0x6065:00 Following error window = " + backup_value_text(canopen::DataType::Unsigned32, u32(window))),
            std::string::npos) << describe(r);
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window);
  EXPECT_EQ(y->upload({0x607C, 0}).data, u32(0));
  EXPECT_EQ(y->upload({0x60F9, 1}).data, kv->data);
  EXPECT_EQ(y->upload({0x60FB, 1}).data, kp->data);
  // Read back: every restorable parameter as in the backup.
  const RestoreResult again = restore_drives(files, buses, true);
  ASSERT_TRUE(again.ok());
  for (const auto& d : again.drives) EXPECT_TRUE(d.changes.empty()) << describe(again);
}

// TPDO1 as a master configures it (the simulated drive starts with none
// mapped): statusword and position actual, valid on 0x181.
template <typename Drive>
void map_tpdo1(Drive& drive) {
  drive.od().template set<uint32_t>({0x1A00, 1}, 0x60410010);
  drive.od().template set<uint32_t>({0x1A00, 2}, 0x60640020);
  drive.od().template set<uint8_t>({0x1A00, 0}, 2);
  drive.od().template set<uint32_t>({0x1800, 1}, 0x181);
}

// A TPDO's mapping and transmission type changed in the drive (as CiA 301
// allows it: the PDO disabled, sub-index 0 to 0, the entry, sub-index 0,
// enabled) are restored in that order; the simulated drive refuses a
// mapping written out of order (sub-index 0 not 0, or the PDO valid).
TEST(CommissionRestore, CanopenChangedPdoMappingIsRestoredInTheCia301Order) {
  CanBus b;
  auto& drive = b.add(1);
  map_tpdo1(drive);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 1u);
  const BackupEntry* count = files[0].find(0x1A00, 0);
  const BackupEntry* cob = files[0].find(0x1800, 1);
  ASSERT_TRUE(count && cob);
  ASSERT_GE(count->data.at(0), 2) << "TPDO1 maps two objects or more in the simulated drive";
  ASSERT_EQ(cob->data.at(3) & 0x80, 0) << "TPDO1 is valid in the simulated drive";

  auto x = canopen_channel(*b.client, 1, kTimeout);
  EXPECT_FALSE(x->download({0x1A00, 1}, u32(0x60640020)).ok) << "the drive takes a mapping of a valid PDO";
  ASSERT_TRUE(x->download({0x1800, 1}, u32(as_u32(cob->data) | 0x80000000u)).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {0}).ok);
  ASSERT_TRUE(x->download({0x1A00, 1}, u32(0x60640020)).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {1}).ok);
  ASSERT_TRUE(x->download({0x1800, 2}, {1}).ok);
  ASSERT_TRUE(x->download({0x1800, 1}, cob->data).ok);

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult dry = restore_drives(files, buses, true);
  ASSERT_TRUE(dry.ok()) << describe(dry);
  EXPECT_TRUE(dry.drives[0].changes.empty()) << describe(dry);
  EXPECT_GE(dry.drives[0].pdo_changes.size(), 3u) << describe(dry);  // 0x1A00:0, 0x1A00:1, 0x1800:2
  EXPECT_NE(describe(dry).find("would write 0x1A00:00"), std::string::npos) << describe(dry);
  EXPECT_EQ(x->upload({0x1A00, 0}).data, (std::vector<uint8_t>{1})) << "a dry run wrote";

  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  const std::string text = describe(r);
  const auto at = [&text](const std::string& s) { return text.find("pdo write " + s); };
  ASSERT_NE(at("0x1800:01 = 0x8"), std::string::npos) << text;
  EXPECT_LT(at("0x1800:01 = 0x8"), at("0x1A00:00 = 0x00 (mapping off)")) << text;
  EXPECT_LT(at("0x1A00:00 = 0x00 (mapping off)"), at("0x1A00:01")) << text;
  EXPECT_LT(at("0x1A00:01"), at("0x1A00:00 = 0x0" + std::to_string(count->data[0]) + " (mapping on)")) << text;
  EXPECT_LT(at("0x1A00:00 = 0x0" + std::to_string(count->data[0]) + " (mapping on)"), at("0x1800:01 = 0x0")) << text;
  for (uint8_t k = 0; k <= count->data[0]; ++k)
    EXPECT_EQ(x->upload({0x1A00, k}).data, files[0].find(0x1A00, k)->data) << "0x1A00:" << int(k);
  EXPECT_EQ(x->upload({0x1800, 2}).data, files[0].find(0x1800, 2)->data);
  EXPECT_EQ(x->upload({0x1800, 1}).data, cob->data);
  const RestoreResult again = restore_drives(files, buses, true);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again.drives[0].pdo_changes.empty()) << describe(again);
}

// The simulated drive has 8 RPDOs and 8 TPDOs: each is backed up (found
// by reading 0x1400.../0x1800... until "object does not exist", which is
// not a missing object), and a changed TPDO6 mapping is restored.
TEST(CommissionRestore, CanopenPdosBeyondTheFourthAreBackedUpAndRestored) {
  CanBus b;
  auto& drive = b.add(1);
  drive.od().set<uint32_t>({0x1A05, 1}, 0x60410010);
  drive.od().set<uint32_t>({0x1A05, 2}, 0x60640020);
  drive.od().set<uint8_t>({0x1A05, 0}, 2);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 1u);
  for (const auto& [index, sub] : std::vector<std::pair<uint16_t, uint8_t>>{
           {0x1400, 1}, {0x1407, 1}, {0x1407, 2}, {0x1607, 0}, {0x1805, 1}, {0x1805, 5}, {0x1807, 1}, {0x1A05, 0},
           {0x1A05, 1}, {0x1A05, 2}, {0x1A07, 0}})
    EXPECT_TRUE(files[0].find(index, sub)) << std::hex << index << ":" << int(sub) << " not backed up";
  EXPECT_FALSE(files[0].find(0x1408, 1));
  ASSERT_TRUE(files[0].find(0x1A05, 2));
  const std::string text = read_file(files[0].path);
  EXPECT_NE(text.find("[1A05sub1]\nParameterName=TPDO6 mapping entry 1\n"), std::string::npos) << text;
  EXPECT_EQ(text.find("1408"), std::string::npos) << "the end of the search is not a missing object\n" << text;
  EXPECT_EQ(text.find("1808"), std::string::npos) << text;

  auto x = canopen_channel(*b.client, 1, kTimeout);
  const std::vector<uint8_t> cob = x->upload({0x1805, 1}).data;
  ASSERT_EQ(cob.size(), 4u);
  ASSERT_TRUE(x->download({0x1805, 1}, u32(as_u32(cob) | 0x80000000u)).ok);
  ASSERT_TRUE(x->download({0x1A05, 0}, {0}).ok);
  ASSERT_TRUE(x->download({0x1A05, 1}, u32(0x60640020)).ok);
  ASSERT_TRUE(x->download({0x1A05, 0}, {1}).ok);
  ASSERT_TRUE(x->download({0x1805, 1}, cob).ok);

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  EXPECT_NE(describe(r).find("pdo write 0x1A05:00 = 0x00 (mapping off)"), std::string::npos) << describe(r);
  for (uint8_t k = 0; k <= 2; ++k)
    EXPECT_EQ(x->upload({0x1A05, k}).data, files[0].find(0x1A05, k)->data) << "0x1A05:" << int(k);
  const RestoreResult again = restore_drives(files, buses, true);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again.drives[0].pdo_changes.empty()) << describe(again);
}

// The NMT state byte of node `node`'s next heartbeat on `port` (-1: none
// within 2 s); boot-up messages (0) are skipped.
int next_heartbeat(can::Transport& port, uint8_t node) {
  can::Frame f;
  while (port.receive(f)) {
  }
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (std::chrono::steady_clock::now() < end) {
    while (port.receive(f))
      if (f.id == 0x700u + node && f.len == 1 && f.data[0] != 0) return f.data[0];
    port.wait(10'000'000);
  }
  return -1;
}

// A node some master left OPERATIONAL: the simulated drive (as many real
// ones) refuses PDO mapping writes there (SDO abort 0x08000022); the
// restore puts it into PRE-OPERATIONAL first and leaves it there.
TEST(CommissionRestore, AnOperationalNodeIsPutIntoPreOperationalBeforeItsPdoMappingIsRestoredAndLeftThere) {
  CanBus b;
  auto& drive = b.add(1);
  map_tpdo1(drive);
  auto observer = b.bus->open_port("observer");
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 1u);
  const BackupEntry* cob = files[0].find(0x1800, 1);
  ASSERT_TRUE(cob);

  // Changed in PRE-OPERATIONAL (one entry), then the node started, with a
  // heartbeat to tell its state.
  auto x = canopen_channel(*b.client, 1, kTimeout);
  ASSERT_TRUE(x->download({0x1800, 1}, u32(as_u32(cob->data) | 0x80000000u)).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {0}).ok);
  ASSERT_TRUE(x->download({0x1A00, 1}, u32(0x60640020)).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {1}).ok);
  ASSERT_TRUE(x->download({0x1800, 1}, cob->data).ok);
  ASSERT_TRUE(x->download({0x1017, 0}, {20, 0}).ok);
  ASSERT_EQ(b.client->send(can::Frame::make(0x000, {0x01, 1})), can::SendStatus::Ok);  // NMT start node 1
  ASSERT_EQ(next_heartbeat(*observer, 1), 0x05) << "node 1 is OPERATIONAL";
  ASSERT_TRUE(x->download({0x1800, 1}, u32(as_u32(cob->data) | 0x80000000u)).ok);
  const DriveChannel::Result refused = x->download({0x1A00, 0}, {0});
  EXPECT_EQ(refused.abort_code, 0x08000022u) << "the drive takes a mapping in OPERATIONAL: " << refused.error;

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult dry = restore_drives(files, buses, true);
  ASSERT_TRUE(dry.ok()) << describe(dry);
  EXPECT_EQ(next_heartbeat(*observer, 1), 0x05) << "a dry run changed the NMT state";

  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  for (uint8_t k = 0; k <= 2; ++k)
    EXPECT_EQ(x->upload({0x1A00, k}).data, files[0].find(0x1A00, k)->data) << "0x1A00:" << int(k);
  EXPECT_EQ(x->upload({0x1800, 1}).data, cob->data);
  EXPECT_EQ(next_heartbeat(*observer, 1), 0x7F) << "node 1 is left PRE-OPERATIONAL";
  EXPECT_NE(describe(r).find("node 1 (axis X, node-01-x.dcf)"), std::string::npos);
  EXPECT_NE(describe(r).find("NMT Enter Pre-Operational sent before writing, and the node reported PRE-OPERATIONAL "
                             "(heartbeat 0x701)"),
            std::string::npos) << describe(r);
  EXPECT_NE(describe(r).find("it is left in PRE-OPERATIONAL"), std::string::npos) << describe(r);
  EXPECT_NE(describe(r).find("after the writes it reports PRE-OPERATIONAL (heartbeat 0x701)"), std::string::npos)
      << describe(r);
}

// NMT is unconfirmed on the wire: the restore waits for the node to say
// it is PRE-OPERATIONAL. Here the command is lost (the virtual bus drops
// it), node 1 goes on reporting OPERATIONAL in its heartbeat: it is named
// with what it reported, nothing is written to it, nor to node 2 after it.
TEST(CommissionRestore, ANodeThatDoesNotReportPreOperationalIsNamedWithWhatItReportedAndNothingIsWritten) {
  CanBus b;
  b.add(1);
  b.add(2);
  auto observer = b.bus->open_port("observer");
  b.start();
  State s = canopen_state({{'X', 1}, {'Y', 2}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 2u);
  const uint32_t window = as_u32(files[0].find(0x6065, 0)->data);
  auto x = canopen_channel(*b.client, 1, kTimeout);
  auto y = canopen_channel(*b.client, 2, kTimeout);
  ASSERT_TRUE(x->download({0x6065, 0}, u32(window + 777)).ok);
  ASSERT_TRUE(y->download({0x6065, 0}, u32(window + 555)).ok);
  ASSERT_TRUE(x->download({0x1017, 0}, {20, 0}).ok);
  ASSERT_EQ(b.client->send(can::Frame::make(0x000, {0x01, 1})), can::SendStatus::Ok);  // NMT start node 1
  ASSERT_EQ(next_heartbeat(*observer, 1), 0x05) << "node 1 is OPERATIONAL";

  b.bus->drop_next(can::Filter::exact(0x000), 1);  // the restore's NMT Enter Pre-Operational is lost
  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  buses.listen_ns = 0;  // (the heartbeat is not another master's traffic anyway)
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_EQ(r.problems.size(), 1u) << describe(r);
  EXPECT_NE(r.problems[0].find("node 1 (axis X, node-01-x.dcf): NMT Enter Pre-Operational sent, but it reported "
                               "OPERATIONAL (0x05) (heartbeat 0x701), not PRE-OPERATIONAL, within 500 ms"),
            std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("nothing was written to it"), std::string::npos) << r.problems[0];
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window + 777);
  EXPECT_EQ(as_u32(y->upload({0x6065, 0}).data), window + 555) << "node 2 was written after node 1's problem";
  EXPECT_TRUE(r.drives[1].not_reached);
  EXPECT_NE(describe(r).find("nothing written: the restore stopped at an earlier drive"), std::string::npos) << describe(r);
  EXPECT_EQ(next_heartbeat(*observer, 1), 0x05) << "node 1 is still OPERATIONAL";

  // With the command not lost, the restore goes ahead and node 1 says so.
  const RestoreResult after = restore_drives(files, buses, false);
  ASSERT_TRUE(after.ok()) << describe(after);
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window);
  EXPECT_EQ(as_u32(y->upload({0x6065, 0}).data), window);
  EXPECT_EQ(next_heartbeat(*observer, 1), 0x7F);
}

// A node without heartbeat (0x1017 = 0) is asked by node guarding (RTR on
// 0x700+id); one that answers neither is named, and nothing is written.
TEST(CommissionRestore, WithoutHeartbeatNodeGuardingConfirmsPreOperationalAndANodeThatAnswersNeitherIsRefused) {
  CanBus b;
  b.add(1);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  const uint32_t window = as_u32(files[0].find(0x6065, 0)->data);
  auto x = canopen_channel(*b.client, 1, kTimeout);
  ASSERT_EQ(x->upload({0x1017, 0}).data, (std::vector<uint8_t>{0, 0})) << "the simulated drive has no heartbeat";
  ASSERT_EQ(b.client->send(can::Frame::make(0x000, {0x01, 1})), can::SendStatus::Ok);  // NMT start node 1
  ASSERT_TRUE(x->download({0x6065, 0}, u32(window + 777)).ok);

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  buses.nmt_timeout_ns = 300'000'000;
  // Its node guarding never gets through: an RTR every 100 ms, at most 3
  // within the 300 ms (the filter takes the requests and the answers).
  b.bus->drop_next(can::Filter::exact(0x701), 3);
  const RestoreResult silent = restore_drives(files, buses, false);
  ASSERT_EQ(silent.problems.size(), 1u) << describe(silent);
  EXPECT_NE(silent.problems[0].find("node 1 (axis X, node-01-x.dcf): NMT Enter Pre-Operational sent, but no heartbeat "
                                    "(its 0x1017 is 0) and no answer to node guarding (RTR on 0x701) within 300 ms"),
            std::string::npos) << silent.problems[0];
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window + 777);

  buses.nmt_timeout_ns = kTimeout;  // room for a request still dropped (a loaded host sent fewer than 3)
  ASSERT_EQ(b.client->send(can::Frame::make(0x000, {0x01, 1})), can::SendStatus::Ok);  // OPERATIONAL again
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  EXPECT_NE(describe(r).find("the node reported PRE-OPERATIONAL (node guarding answer 0x701)"), std::string::npos)
      << describe(r);
  EXPECT_NE(describe(r).find("after the writes it reports PRE-OPERATIONAL (node guarding answer 0x701)"),
            std::string::npos) << describe(r);
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window);
}

// A backup whose mapping counts an entry it does not have is found out
// before anything is written (not half-way through the PDO).
TEST(CommissionRestore, ABackupMappingWithoutAnEntryItCountsIsAProblemBeforeAnythingIsWritten) {
  CanBus b;
  auto& drive = b.add(1);
  map_tpdo1(drive);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  auto files = canopen_backup(*b.client, s, dir / "backup");
  std::string text = read_file(files[0].path);
  const auto sec = text.find("[1A00sub2]");
  ASSERT_NE(sec, std::string::npos) << text;
  text.erase(sec, text.find('[', sec + 1) - sec);
  write_file_atomically(files[0].path, text);
  files = load_backup_dir(dir / "backup");
  auto x = canopen_channel(*b.client, 1, kTimeout);
  ASSERT_TRUE(x->download({0x1800, 1}, u32(0x80000181)).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {0}).ok);
  ASSERT_TRUE(x->download({0x1A00, 0}, {1}).ok);
  ASSERT_TRUE(x->download({0x1800, 1}, u32(0x181)).ok);

  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_EQ(r.problems.size(), 1u) << describe(r);
  EXPECT_NE(r.problems[0].find("node 1 (axis X, node-01-x.dcf): the backup's 0x1A00:00 (line "), std::string::npos)
      << r.problems[0];
  EXPECT_NE(r.problems[0].find(") counts 2 entries but has no 0x1A00:02; nothing was written"), std::string::npos)
      << r.problems[0];
  EXPECT_TRUE(r.drives[0].pdo_steps.empty()) << describe(r);
  EXPECT_EQ(as_u32(x->upload({0x1800, 1}).data), 0x181u) << "the PDO was disabled";
  EXPECT_EQ(x->upload({0x1A00, 0}).data, (std::vector<uint8_t>{1}));
}

// A channel that records the writes it passes on (the order the drive
// sees them in).
class RecordingChannel final : public DriveChannel {
 public:
  RecordingChannel(std::unique_ptr<DriveChannel> inner, std::vector<std::string>& log) : inner_(std::move(inner)), log_(log) {}
  Result upload(canopen::ObjectAddress a) override { return inner_->upload(a); }
  Result download(canopen::ObjectAddress a, const std::vector<uint8_t>& data) override {
    char b[16];
    std::snprintf(b, sizeof b, "%04X:%02X", a.index, a.sub);
    log_.push_back(b);
    return inner_->download(a, data);
  }
  Result prepare_for_writes(std::string& done) override {
    log_.push_back("prepare");
    return inner_->prepare_for_writes(done);
  }
  Result report_state(std::string& state) override { return inner_->report_state(state); }

 private:
  std::unique_ptr<DriveChannel> inner_;
  std::vector<std::string>& log_;
};

// A mapping entry the drive refuses half-way through a PDO (the backup
// maps an object this drive does not have): the restore stops there,
// naming the object and the abort code; what was written before is
// listed, the state the drive is left in is read from it and said (the
// PDO disabled, nothing mapped, PRE-OPERATIONAL, not stored), and node 2,
// which also differs from its backup, is not written.
TEST(CommissionRestore, AWriteRefusedHalfWayStopsTheRestoreNamingObjectAndAbortAndSaysWhereTheDriveIsLeft) {
  CanBus b;
  auto& drive = b.add(1);
  map_tpdo1(drive);
  b.add(2);
  b.start();
  State s = canopen_state({{'X', 1}, {'Y', 2}});
  testing::TempDir dir;
  auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 2u);
  // The backup's second TPDO1 entry is an object this drive lacks (a
  // backup of other firmware).
  std::string text = read_file(files[0].path);
  const auto sec = text.find("[1A00sub2]");
  ASSERT_NE(sec, std::string::npos) << text;
  const auto val = text.find("ParameterValue=0x60640020", sec);
  ASSERT_NE(val, std::string::npos) << text.substr(sec, 200);
  text.replace(val, 25, "ParameterValue=0x5FFE0020");
  write_file_atomically(files[0].path, text);
  files = load_backup_dir(dir / "backup");
  const uint32_t window = as_u32(files[0].find(0x6065, 0)->data);
  auto x = canopen_channel(*b.client, 1, kTimeout);
  auto y = canopen_channel(*b.client, 2, kTimeout);
  ASSERT_TRUE(x->download({0x6065, 0}, u32(window + 777)).ok);
  ASSERT_TRUE(y->download({0x6065, 0}, u32(window + 555)).ok);

  std::vector<std::string> log1, log2;
  const auto open = [&](const BackupFile& f, std::string&) -> std::unique_ptr<DriveChannel> {
    return std::make_unique<RecordingChannel>(canopen_channel(*b.client, f.node, kTimeout), f.node == 1 ? log1 : log2);
  };
  const RestoreResult r = restore_drives(files, open, false);
  const std::string text_r = describe(r);
  ASSERT_EQ(r.problems.size(), 1u) << text_r;
  const std::string& p = r.problems[0];
  EXPECT_NE(p.find("node 1 (axis X, node-01-x.dcf): restoring the PDO configuration, writing 0x1A00:02 (mapping entry) "
                   "failed: 0x06020000"),
            std::string::npos) << p;
  EXPECT_NE(p.find("the restore stopped there: 4 object(s) of this drive were written before it, it is not stored"),
            std::string::npos) << p;
  EXPECT_NE(p.find("not written at all: node 2 (axis Y, node-02-y.dcf)"), std::string::npos) << p;
  // The writes node 1 saw, in order: the parameter, then TPDO1 disabled,
  // its mapping emptied, the first entry, the refused one; nothing after.
  EXPECT_EQ(log1, (std::vector<std::string>{"prepare", "6065:00", "1800:01", "1A00:00", "1A00:01", "1A00:02"}));
  EXPECT_TRUE(log2.empty()) << "node 2 was written after node 1 stopped";
  // Where node 1 is left, as the restore said and as the drive reads.
  const DriveRestore& d = r.drives[0];
  EXPECT_NE(d.stopped.find("writing 0x1A00:02 = 0x5FFE0020 (mapping entry): 0x06020000"), std::string::npos) << d.stopped;
  const auto left = [&d](const std::string& line) { return std::find(d.left.begin(), d.left.end(), line) != d.left.end(); };
  EXPECT_TRUE(left("NMT state: PRE-OPERATIONAL (node guarding answer 0x701)")) << text_r;
  EXPECT_TRUE(left("0x1800:01 = 0x80000181 (the PDO is disabled)")) << text_r;
  EXPECT_TRUE(left("0x1A00:00 = 0x00 (nothing mapped)")) << text_r;
  EXPECT_TRUE(left("0x6065:00 = " + backup_value_text(canopen::DataType::Unsigned32, u32(window)))) << text_r;
  EXPECT_NE(text_r.find("STOPPED at writing 0x1A00:02"), std::string::npos) << text_r;
  EXPECT_NE(text_r.find("not stored: \"store parameters\" (0x1010:01) was not sent"), std::string::npos) << text_r;
  EXPECT_EQ(as_u32(x->upload({0x1800, 1}).data), 0x80000181u);
  EXPECT_EQ(x->upload({0x1A00, 0}).data, (std::vector<uint8_t>{0}));
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window);
  EXPECT_EQ(as_u32(y->upload({0x6065, 0}).data), window + 555);
}

// Another master on the bus (here a SYNC every 5 ms and an RPDO to node 1
// from a port of its own, as another instance or host would send them):
// the restore refuses naming what it saw, and writes nothing; the dry run
// (which writes nothing) does not listen.
TEST(CommissionRestore, AnotherMasterOnTheCanBusIsRefusedNamingWhatWasSeen) {
  CanBus b;
  b.add(1);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  auto x = canopen_channel(*b.client, 1, kTimeout);
  const uint32_t window = as_u32(files[0].find(0x6065, 0)->data);
  ASSERT_TRUE(x->download({0x6065, 0}, u32(window + 777)).ok);

  auto other = b.bus->open_port("other-master");
  std::atomic<bool> stop{false};
  std::thread master([&] {
    while (!stop.load()) {
      other->send(can::Frame::make(0x080, {}));
      other->send(can::Frame::make(0x201, {0x06, 0x00}));
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult dry = restore_drives(files, buses, true);
  const RestoreResult r = restore_drives(files, buses, false);
  stop = true;
  master.join();
  EXPECT_TRUE(dry.ok()) << describe(dry);
  ASSERT_EQ(r.problems.size(), 1u) << describe(r);
  EXPECT_NE(r.problems[0].find("another CANopen master is active on " + b.client->name() + ": SYNC (0x080) x"),
            std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("RPDO 0x201 x"), std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("within 300 ms"), std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("nothing was written"), std::string::npos) << r.problems[0];
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window + 777);
  // Once it is gone the restore goes ahead.
  const RestoreResult after = restore_drives(files, buses, false);
  ASSERT_TRUE(after.ok()) << describe(after);
  EXPECT_EQ(as_u32(x->upload({0x6065, 0}).data), window);
}

TEST(CommissionRestore, AnotherDriveInTheBackedUpPlaceIsRefusedNamingItAndNothingIsWritten) {
  CanBus b;
  b.add(1);
  b.add(2, 0x999);
  b.start();
  State s = canopen_state({{'X', 1}});
  testing::TempDir dir;
  auto files = canopen_backup(*b.client, s, dir / "backup");
  ASSERT_EQ(files.size(), 1u);
  // The backup of node 1, restored to node 2 (another product).
  std::string text = read_file(files[0].path);
  text.replace(text.find("NodeID=1\n"), 9, "NodeID=2\n");
  write_file_atomically(dir / "node-02.dcf", text);
  const BackupFile other = load_backup_file(dir / "node-02.dcf");
  auto y = canopen_channel(*b.client, 2, kTimeout);
  ASSERT_TRUE(y->download({0x6098, 0}, {35}).ok);
  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = kTimeout;
  const RestoreResult r = restore_drives(std::vector<BackupFile>{other}, buses, false);
  ASSERT_EQ(r.problems.size(), 1u) << describe(r);
  EXPECT_NE(r.problems[0].find("node 2 (axis X, node-02.dcf) is another drive: vendor 0x00000CC1 product 0x00000999"),
            std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("the backup's vendor 0x00000CC1 product 0x00000402"), std::string::npos) << r.problems[0];
  EXPECT_EQ(y->upload({0x6098, 0}).data, (std::vector<uint8_t>{35}));
}

TEST(CommissionRestore, ASilentNodeIsAProblemNamingItAndTheOtherDrivesAreNotWritten) {
  CanBus b;
  b.add(1);
  b.add(2);
  b.start();
  State s = canopen_state({{'X', 1}, {'Y', 2}});
  testing::TempDir dir;
  const auto files = canopen_backup(*b.client, s, dir / "backup");
  std::string text = read_file(files[1].path);
  text.replace(text.find("NodeID=2\n"), 9, "NodeID=9\n");
  write_file_atomically(files[1].path, text);
  const auto changed = load_backup_dir(dir / "backup");
  auto x = canopen_channel(*b.client, 1, kTimeout);
  ASSERT_TRUE(x->download({0x6098, 0}, {35}).ok);
  RestoreBuses buses;
  buses.can = b.client.get();
  buses.sdo_timeout_ns = 200'000'000;
  const RestoreResult r = restore_drives(changed, buses, false);
  ASSERT_EQ(r.problems.size(), 1u) << describe(r);
  EXPECT_NE(r.problems[0].find("node 9 (axis Y, node-02-y.dcf) does not answer"), std::string::npos) << r.problems[0];
  // Node 1 was fine, but a restore is all or nothing.
  EXPECT_EQ(x->upload({0x6098, 0}).data, (std::vector<uint8_t>{35}));
}

TEST(CommissionRestore, BadBackupFilesAreErrorsNamingFileAndLine) {
  testing::TempDir dir;
  const std::string good =
      "; a backup\n[DeviceComissioning]\nNodeID=3\nNodeName=z-axis\n"
      "[1018sub1]\nDataType=0x0007\nParameterValue=0x00000CC1\n"
      "[1018sub2]\nDataType=0x0007\nParameterValue=0x00000402\n"
      "[1018sub3]\nDataType=0x0007\nParameterValue=0x00010000\n"
      "[6065]\nParameterName=Following error window\nDataType=0x0007\nParameterValue=0x00002710\n"
      "[2000]\nParameterName=Drive temperature\nDataType=0x0003\nParameterValue=-5\nAccessType=ro\n"
      "[Missing]\n1=1009sub0 Manufacturer hardware version: 0x06020000\n";
  write_file_atomically(dir / "good.dcf", good);
  const BackupFile f = load_backup_file(dir / "good.dcf");
  EXPECT_EQ(f.node, 3);
  EXPECT_EQ(f.axis, 'Z');
  ASSERT_EQ(f.entries.size(), 5u);
  EXPECT_EQ(f.find(0x6065, 0)->data, u32(10000));
  EXPECT_TRUE(restorable(*f.find(0x6065, 0)));
  EXPECT_FALSE(restorable(*f.find(0x2000, 0)));  // read-only
  EXPECT_FALSE(restorable(*f.find(0x1018, 1)));  // identity: checked, never written

  auto error_of = [&](const std::string& text) {
    write_file_atomically(dir / "bad.dcf", text);
    try {
      load_backup_file(dir / "bad.dcf");
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string file = (dir / "bad.dcf").string();
  std::string bad = good;
  bad.insert(bad.find("[6065]"), "garbage\n");
  EXPECT_EQ(error_of(bad), file + ":14: \"garbage\": expected KEY=VALUE or a [section]");
  bad = good;
  bad.replace(bad.find("0x00002710"), 10, "ten");
  EXPECT_EQ(error_of(bad), file + ":14: ParameterValue \"ten\" of 0x6065:00 is not a value of type UNSIGNED32");
  bad = good;
  const std::string id2 = "[1018sub2]\nDataType=0x0007\nParameterValue=0x00000402\n";
  bad.replace(bad.find(id2), id2.size(), "");
  EXPECT_NE(error_of(bad).find("no identity 0x1018:02"), std::string::npos) << error_of(bad);
  bad = good;
  bad.replace(bad.find("NodeID=3"), 8, "NodeID=300");
  EXPECT_EQ(error_of(bad), file + ":3: nodeid \"300\": expected a node-ID 1-127 (NodeID) or a slave position (EtherCATSlave)");
  EXPECT_NE(error_of("[6065]\nDataType=0x0007\n").find(":1: section of 0x6065:00 has no ParameterValue"), std::string::npos);
  EXPECT_THROW(load_backup_file(dir / "none.dcf"), std::runtime_error);
  EXPECT_THROW(load_backup_dir(dir / "empty"), std::runtime_error);
}

// --- EtherCAT: simulated CoE drives on an in-process segment ---
struct EcatSegment {
  std::shared_ptr<ethercat::sim::Segment> segment = std::make_shared<ethercat::sim::Segment>();
  std::string name = testing::unique_name("restore");
  explicit EcatSegment(unsigned drives, const ethercat::sim::CoeDriveConfig& config = {}) {
    segment->add_drives(drives, config);
    ethercat::sim::register_sim_link_kind();
    ethercat::sim::register_segment(name, segment);
  }
  ~EcatSegment() { ethercat::sim::unregister_segment(name); }
  std::string interface() const { return "sim:" + name; }
};

State ethercat_state(const std::string& interface, const std::vector<std::pair<char, int>>& axes) {
  State s = state_with_axes(axes, true);
  s.ethercat_interface = interface;
  return s;
}

TEST(CommissionRestore, EthercatBackupOverCoeHasTheFactorGroupIdentityAndManufacturerObjects) {
  EcatSegment seg(2);
  State s = ethercat_state(seg.interface(), {{'X', 1}, {'Y', 2}});
  BackupResult r = backup_ethercat_drives(seg.interface(), s);
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_EQ(r.nodes.size(), 2u);
  EXPECT_EQ(r.nodes[0].slave, 1u);
  EXPECT_EQ(r.nodes[0].file, "slave-01-x.dcf");
  testing::TempDir dir;
  write_backup(s, r, dir / "b");
  const std::string text = read_file(dir / "b" / "slave-02-y.dcf");
  const uint32_t counts = static_cast<uint32_t>(seg.segment->drive(1)->model().config().plant.encoder_counts);
  EXPECT_NE(text.find("[DeviceComissioning]\nEtherCATSlave=2\nNodeName=y-axis\n"), std::string::npos) << text;
  EXPECT_NE(text.find("[608Fsub1]\nParameterName=Encoder increments\nDataType=0x0007\nParameterValue=" +
                      backup_value_text(canopen::DataType::Unsigned32, u32(counts))),
            std::string::npos) << text;
  for (const char* sec : {"[6091sub1]", "[6092sub1]", "[607E]", "[6065]", "[6098]", "[1018sub3]", "[1C12sub1]", "[1A00sub1]"})
    EXPECT_NE(text.find(sec), std::string::npos) << sec << "\n" << text;
  // A manufacturer object from the drive's SDO information, read-only.
  const auto t = text.find("[2000]\nParameterName=Drive temperature (0.1 C)\nDataType=0x0003\nParameterValue=");
  ASSERT_NE(t, std::string::npos) << text;
  EXPECT_EQ(text.substr(text.find('\n', text.find("ParameterValue=", t)) + 1, 14), "AccessType=ro\n") << text;
  // No CANopen PDO communication objects on EtherCAT.
  EXPECT_EQ(text.find("[1400sub1]"), std::string::npos);
}

TEST(CommissionRestore, EthercatChangedParameterIsWrittenBackOverCoeAndReadsBackEqual) {
  EcatSegment seg(2);
  State s = ethercat_state(seg.interface(), {{'X', 1}, {'Y', 2}});
  BackupResult br = backup_ethercat_drives(seg.interface(), s);
  ASSERT_TRUE(br.ok()) << br.problems[0];
  testing::TempDir dir;
  write_backup(s, br, dir / "b");
  const auto files = load_backup_dir(dir / "b");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[1].slave, 2u);

  ethercat::MasterConfig cfg;
  cfg.interface = seg.interface();
  ethercat::Master m(cfg, nullptr);
  m.to_preop();
  ASSERT_TRUE(m.sdo_download(2, 0x6065, 0, u32(4321)).ok);
  ASSERT_TRUE(m.sdo_download(2, 0x607C, 0, u32(static_cast<uint32_t>(-500))).ok);
  const BackupEntry* kv = files[1].find(0x60F9, 1);
  ASSERT_TRUE(kv) << "the velocity loop's gain is not backed up";
  ASSERT_TRUE(m.sdo_download(2, 0x60F9, 1, u32(as_u32(kv->data) + 1)).ok);
  RestoreBuses buses;
  buses.ethercat = &m;
  const RestoreResult dry = restore_drives(files, buses, true);
  ASSERT_TRUE(dry.ok()) << describe(dry);
  EXPECT_TRUE(dry.drives[0].changes.empty()) << describe(dry);
  ASSERT_EQ(dry.drives[1].changes.size(), 3u) << describe(dry);
  EXPECT_NE(describe(dry).find("would write 0x607C:00 Home offset: -500 -> 0"), std::string::npos) << describe(dry);
  EXPECT_EQ(as_u32(m.sdo_upload(2, 0x6065, 0).data), 4321u);

  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  EXPECT_EQ(m.sdo_upload(2, 0x6065, 0).data, files[1].find(0x6065, 0)->data);
  EXPECT_EQ(m.sdo_upload(2, 0x607C, 0).data, u32(0));
  EXPECT_EQ(m.sdo_upload(2, 0x60F9, 1).data, kv->data);
  EXPECT_NE(describe(r).find("not stored: the drive has no \"store parameters\""), std::string::npos) << describe(r);
  const RestoreResult again = restore_drives(files, buses, true);
  for (const auto& d : again.drives) EXPECT_TRUE(d.changes.empty()) << describe(again);

  // A slave position the segment does not have: refused, nothing written.
  ASSERT_TRUE(m.sdo_download(1, 0x6065, 0, u32(99)).ok);
  std::string text = read_file(files[1].path);
  text.replace(text.find("EtherCATSlave=2"), 15, "EtherCATSlave=5");
  write_file_atomically(dir / "slave-05.dcf", text);
  const RestoreResult missing = restore_drives(std::vector<BackupFile>{files[0], load_backup_file(dir / "slave-05.dcf")}, buses, false);
  ASSERT_EQ(missing.problems.size(), 1u) << describe(missing);
  EXPECT_NE(missing.problems[0].find("EtherCAT slave 5 (axis Y, slave-05.dcf) does not answer"), std::string::npos)
      << missing.problems[0];
  EXPECT_EQ(as_u32(m.sdo_upload(1, 0x6065, 0).data), 99u);
  m.release();
}

// EtherCAT in PREOP: a TxPDO mapping and its assignment changed are
// restored with 0x1C12/0x1C13 emptied first, the mapping rewritten, then
// the assignments (the simulated drive checks each against the mapping).
TEST(CommissionRestore, EthercatChangedPdoMappingAndAssignmentAreRestored) {
  EcatSegment seg(1);
  State s = ethercat_state(seg.interface(), {{'X', 1}});
  BackupResult br = backup_ethercat_drives(seg.interface(), s);
  ASSERT_TRUE(br.ok()) << br.problems[0];
  testing::TempDir dir;
  write_backup(s, br, dir / "b");
  const auto files = load_backup_dir(dir / "b");
  ASSERT_TRUE(files[0].find(0x1C13, 1) && files[0].find(0x1A00, 0) && files[0].find(0x1A01, 0)) << "not backed up";

  ethercat::MasterConfig cfg;
  cfg.interface = seg.interface();
  ethercat::Master m(cfg, nullptr);
  m.to_preop();
  // TxPDO 0x1A01 mapping the statusword assigned instead of 0x1A00, whose
  // mapping loses its last entry.
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {0}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A01, 0, {0}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A01, 1, u32(0x60410010)).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A01, 0, {1}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A00, 0, {2}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 1, {0x01, 0x1A}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {1}).ok);
  RestoreBuses buses;
  buses.ethercat = &m;
  const RestoreResult dry = restore_drives(files, buses, true);
  ASSERT_TRUE(dry.ok()) << describe(dry);
  EXPECT_GE(dry.drives[0].pdo_changes.size(), 3u) << describe(dry);  // 0x1A00:0, 0x1A01:0, 0x1C13:1
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  const std::string text = describe(r);
  EXPECT_LT(text.find("pdo write 0x1C13:00 = 0x00 (assignment off)"), text.find("pdo write 0x1A00:00 = 0x00")) << text;
  EXPECT_LT(text.find("pdo write 0x1A01:00"), text.find("pdo write 0x1C13:01")) << text;
  for (const auto& [index, sub] : std::vector<std::pair<uint16_t, uint8_t>>{{0x1C13, 0}, {0x1C13, 1}, {0x1A00, 0}, {0x1A00, 4}, {0x1A01, 0}})
    EXPECT_EQ(m.sdo_upload(1, index, sub).data, files[0].find(index, sub)->data) << std::hex << index << ":" << int(sub);
  const RestoreResult again = restore_drives(files, buses, true);
  EXPECT_TRUE(again.drives[0].pdo_changes.empty()) << describe(again);
}

// Over CoE the same stop: a mapping entry the slave refuses after the
// assignments were emptied leaves them empty, and the restore says so.
TEST(CommissionRestore, EthercatAMappingEntryRefusedHalfWayStopsTheRestoreAndSaysTheAssignmentsAreEmpty) {
  EcatSegment seg(1);
  State s = ethercat_state(seg.interface(), {{'X', 1}});
  BackupResult br = backup_ethercat_drives(seg.interface(), s);
  ASSERT_TRUE(br.ok()) << br.problems[0];
  testing::TempDir dir;
  write_backup(s, br, dir / "b");
  auto files = load_backup_dir(dir / "b");
  ASSERT_TRUE(files[0].find(0x1A00, 4)) << "0x1A00 maps four objects or more in the simulated slave";
  std::string text = read_file(files[0].path);
  const auto sec = text.find("[1A00sub4]");
  ASSERT_NE(sec, std::string::npos);
  const auto val = text.find("ParameterValue=", sec);
  text.replace(val, text.find('\n', val) - val, "ParameterValue=0x5FFE0020");
  write_file_atomically(files[0].path, text);
  files = load_backup_dir(dir / "b");

  ethercat::MasterConfig cfg;
  cfg.interface = seg.interface();
  ethercat::Master m(cfg, nullptr);
  m.to_preop();
  RestoreBuses buses;
  buses.ethercat = &m;
  const RestoreResult r = restore_drives(files, buses, false);
  const std::string out = describe(r);
  ASSERT_EQ(r.problems.size(), 1u) << out;
  EXPECT_NE(r.problems[0].find("EtherCAT slave 1 (axis X, slave-01-x.dcf): restoring the PDO configuration, writing "
                               "0x1A00:04 (mapping entry) failed: aborted by the slave: 0x06020000"),
            std::string::npos) << r.problems[0];
  EXPECT_NE(r.problems[0].find("the restore stopped there"), std::string::npos) << r.problems[0];
  const DriveRestore& d = r.drives[0];
  const auto left = [&d](const std::string& line) { return std::find(d.left.begin(), d.left.end(), line) != d.left.end(); };
  EXPECT_TRUE(left("0x1C12:00 = 0x00 (no PDO assigned)")) << out;
  EXPECT_TRUE(left("0x1C13:00 = 0x00 (no PDO assigned)")) << out;
  EXPECT_TRUE(left("0x1A00:00 = 0x00 (nothing mapped)")) << out;
  EXPECT_EQ(m.sdo_upload(1, 0x1C13, 0).data, (std::vector<uint8_t>{0}));
  EXPECT_EQ(m.sdo_upload(1, 0x1A00, 0).data, (std::vector<uint8_t>{0}));
  EXPECT_EQ(out.find("stored in the drive"), std::string::npos) << out;
}

// A drive with six TxPDO mappings, the sixth assigned as the second PDO
// of 0x1C13: backed up and restored over CoE.
TEST(CommissionRestore, EthercatMappingsBeyondTheFourthAreBackedUpAndRestored) {
  ethercat::sim::CoeDriveConfig six;
  six.pdo_mappings = 6;
  EcatSegment seg(1, six);
  {
    ethercat::MasterConfig cfg;
    cfg.interface = seg.interface();
    ethercat::Master m(cfg, nullptr);
    m.to_preop();
    ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {0}).ok);
    ASSERT_TRUE(m.sdo_download(1, 0x1A05, 1, u32(0x60770010)).ok);
    ASSERT_TRUE(m.sdo_download(1, 0x1A05, 0, {1}).ok);
    ASSERT_TRUE(m.sdo_download(1, 0x1C13, 2, {0x05, 0x1A}).ok);
    ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {2}).ok);
    m.release();
  }
  State s = ethercat_state(seg.interface(), {{'X', 1}});
  BackupResult br = backup_ethercat_drives(seg.interface(), s);
  ASSERT_TRUE(br.ok()) << br.problems[0];
  testing::TempDir dir;
  write_backup(s, br, dir / "b");
  const auto files = load_backup_dir(dir / "b");
  for (const auto& [index, sub] : std::vector<std::pair<uint16_t, uint8_t>>{
           {0x1600, 1}, {0x1605, 0}, {0x1A04, 0}, {0x1A05, 0}, {0x1A05, 1}, {0x1C13, 1}, {0x1C13, 2}})
    EXPECT_TRUE(files[0].find(index, sub)) << std::hex << index << ":" << int(sub) << " not backed up";
  EXPECT_FALSE(files[0].find(0x1A06, 0));
  ASSERT_TRUE(files[0].find(0x1A05, 1) && files[0].find(0x1C13, 2));

  ethercat::MasterConfig cfg;
  cfg.interface = seg.interface();
  ethercat::Master m(cfg, nullptr);
  m.to_preop();
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {0}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A05, 0, {0}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A05, 1, u32(0x603F0010)).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1A05, 0, {1}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 2, {0x04, 0x1A}).ok);
  ASSERT_TRUE(m.sdo_download(1, 0x1C13, 0, {2}).ok);
  RestoreBuses buses;
  buses.ethercat = &m;
  const RestoreResult r = restore_drives(files, buses, false);
  ASSERT_TRUE(r.ok()) << describe(r);
  for (const auto& [index, sub] : std::vector<std::pair<uint16_t, uint8_t>>{{0x1A05, 0}, {0x1A05, 1}, {0x1C13, 0}, {0x1C13, 2}})
    EXPECT_EQ(m.sdo_upload(1, index, sub).data, files[0].find(index, sub)->data) << std::hex << index << ":" << int(sub);
  m.release();
}

TEST(CommissionRestore, AnEthercatAxisOnASlaveTheSegmentLacksIsABackupProblem) {
  EcatSegment seg(1);
  State s = ethercat_state(seg.interface(), {{'X', 1}, {'Y', 3}});
  const BackupResult r = backup_ethercat_drives(seg.interface(), s);
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_NE(r.problems[0].find("EtherCAT slave 3 (axis Y) is not on " + seg.interface() + " (1 slave(s) answer)"),
            std::string::npos) << r.problems[0];
}

// `cnc-commission restore` refuses while a controller runs on its instance
// (a controller's segment, here this test's own ipc::Server), before
// reading any file or bus.
TEST(CommissionRestore, TheCommandRefusesWhileAControllerRunsTheMachine) {
  const std::string instance = testing::unique_name("restore-ctl");
  ipc::Server server(instance);
  testing::TempDir dir;
  const std::filesystem::path program = testing::binary_dir() / "bin" / "cnc-commission";
  ASSERT_TRUE(std::filesystem::exists(program)) << program;
  const std::string cmd = "CNC_INSTANCE=" + instance + " " + program.string() + " --state " +
                          (dir / "state.json").string() + " restore --dir " + (dir / "none").string() + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_TRUE(p);
  std::string out;
  char buf[256];
  while (std::fgets(buf, sizeof buf, p)) out += buf;
  const int status = ::pclose(p);
  EXPECT_EQ(WEXITSTATUS(status), 1) << out;
  EXPECT_NE(out.find("problem: a controller (cncd, pid " + std::to_string(::getpid()) + ", instance " + instance +
                     ") runs the machine: restore does not change drive parameters under it; stop it first"),
            std::string::npos) << out;
  EXPECT_NE(out.find("nothing was written"), std::string::npos) << out;
}

}  // namespace
}  // namespace cnc::commission
