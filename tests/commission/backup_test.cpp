// The drive-parameter backup on simulated CiA 402 drives over the
// in-process CAN bus on the real-time clock (the drives in the simulator
// host's own thread), as it runs over SocketCAN.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "commission/backup.hpp"
#include "commission/config_writer.hpp"
#include "core/util/atomic_file.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_host.hpp"
#include "tests/commission/sim_bus_scan.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

using Bus = e2e::SimulatedCanDrives;

// The state after scan and assignment: nodes found, axes on them.
State state_of(const std::vector<std::pair<char, int>>& axes) {
  State s;
  s.interface = "virtual:backup";
  int joint = 0;
  for (const auto& [letter, node] : axes) {
    ScannedNode n;
    n.node_id = node;
    n.cia402 = true;
    n.encoder_increments = 10000;
    s.nodes.push_back(n);
    Axis a;
    a.letter = letter;
    a.joint = joint++;
    a.node = node;
    a.scaling.encoder_counts = 10000;
    a.scaling.screw_lead = 5;
    s.axes.push_back(a);
  }
  return s;
}

// A loaded test host may leave the simulator's thread waiting for a while.
BackupOptions options() {
  BackupOptions o;
  o.timeout_ns = 1'000'000'000;
  return o;
}

const BackedUpValue* value(const NodeBackup& b, uint16_t index, uint8_t sub) {
  for (const auto& v : b.values)
    if (v.object.addr.index == index && v.object.addr.sub == sub) return &v;
  return nullptr;
}

TEST(CommissionBackup, ReadsTheParametersOfEveryDriveAndListsTheObjectsADriveLacks) {
  Bus b;
  auto& x_drive = b.add(1);
  x_drive.od().set<int32_t>({0x607D, 1}, -123456);
  // TPDO1 as a master maps it (the simulated drive starts with none mapped).
  x_drive.od().set<uint32_t>({0x1A00, 1}, 0x60410010);
  x_drive.od().set<uint32_t>({0x1A00, 2}, 0x60640020);
  x_drive.od().set<uint8_t>({0x1A00, 0}, 2);
  b.add(2).od().set<int8_t>({0x6098, 0}, 35);
  b.start();
  State s = state_of({{'X', 1}, {'Y', 2}});
  BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_EQ(r.nodes.size(), 2u);
  const NodeBackup& x = r.nodes[0];
  EXPECT_EQ(x.node, 1);
  EXPECT_EQ(x.axis, 'X');
  ASSERT_TRUE(value(x, 0x1018, 1));
  EXPECT_EQ(value(x, 0x1018, 1)->data, (std::vector<uint8_t>{0xC1, 0x0C, 0, 0}));
  for (auto [index, sub] : std::vector<std::pair<uint16_t, uint8_t>>{
           {0x6060, 0}, {0x607D, 2}, {0x608F, 1}, {0x6091, 1}, {0x6092, 1}, {0x6065, 0}, {0x6066, 0}, {0x6098, 0},
           {0x6099, 1}, {0x609A, 0}, {0x607C, 0}, {0x1400, 1}, {0x1600, 0}, {0x1800, 1}, {0x1A00, 0}})
    EXPECT_TRUE(value(x, index, sub)) << std::hex << index << ":" << int(sub);
  // The mapping entries sub-index 0 announced, each read.
  EXPECT_EQ(value(x, 0x1A00, 0)->data.at(0), 2);
  ASSERT_TRUE(value(x, 0x1A00, 2));
  EXPECT_EQ(value(x, 0x1A00, 2)->data, (std::vector<uint8_t>{0x20, 0x00, 0x64, 0x60}));
  EXPECT_FALSE(value(x, 0x1A00, 3));
  // The simulated drive has no hardware version (0x1009): listed, not fatal.
  ASSERT_FALSE(x.missing.empty());
  EXPECT_NE(x.missing[0].find("1009sub0 Manufacturer hardware version: 0x06020000"), std::string::npos) << x.missing[0];

  testing::TempDir dir;
  const auto files = write_backup(s, r, dir / "backup");
  ASSERT_EQ(files.size(), 2u);
  const std::string text = read_file(dir / "backup" / "node-01-x.dcf");
  EXPECT_NE(text.find("[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007\nParameterValue=0x00000CC1\n"),
            std::string::npos) << text;
  EXPECT_NE(text.find("[607Dsub1]\nParameterName=Min position limit\nDataType=0x0004\nParameterValue=-123456\n"),
            std::string::npos) << text;
  EXPECT_NE(text.find("[1008]\nParameterName=Manufacturer device name\nDataType=0x0009\nParameterValue=cnc simulated servo drive\n"),
            std::string::npos) << text;
  EXPECT_NE(text.find("[1A00sub2]\nParameterName=TPDO1 mapping entry 2\nDataType=0x0007\nParameterValue=0x60640020\n"),
            std::string::npos) << text;
  EXPECT_NE(text.find("[Missing]"), std::string::npos);
  EXPECT_NE(read_file(dir / "backup" / "node-02-y.dcf").find("[6098]\nParameterName=Homing method\nDataType=0x0002\nParameterValue=35\n"),
            std::string::npos);
  ASSERT_TRUE(s.backup);
  EXPECT_EQ(s.backup->files, (std::vector<std::string>{"node-01-x.dcf", "node-02-y.dcf"}));

  // The written configuration carries the backup in its folder.
  const auto config = generate_config(s, dir / "config", "machine");
  bool found = false;
  for (const auto& f : config)
    if (f.path == dir / "config" / "drive-backup" / "node-01-x.dcf") found = f.content == text;
  EXPECT_TRUE(found);
  write_config(config);
  EXPECT_EQ(read_file(dir / "config" / "drive-backup" / "node-02-y.dcf"), read_file(dir / "backup" / "node-02-y.dcf"));
}

TEST(CommissionBackup, ASilentNodeIsAnErrorNamingItAndNothingIsWritten) {
  Bus b;
  b.add(1);
  b.start();
  State s = state_of({{'X', 1}, {'Z', 5}});
  BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_FALSE(r.ok());
  ASSERT_EQ(r.problems.size(), 1u);
  EXPECT_NE(r.problems[0].find("node 5 (axis Z) does not answer"), std::string::npos) << r.problems[0];
  testing::TempDir dir;
  EXPECT_THROW(write_backup(s, r, dir / "backup"), std::runtime_error);
  EXPECT_FALSE(std::filesystem::exists(dir / "backup"));
  EXPECT_FALSE(s.backup);
  // A disabled axis's drive is left out, and said so.
  s.axes[1].enabled = false;
  r = backup_drives(*b.client, s, options());
  EXPECT_TRUE(r.ok());
  ASSERT_EQ(r.skipped.size(), 1u);
  EXPECT_NE(r.skipped[0].find("axis Z"), std::string::npos);
}

TEST(CommissionBackup, TheManufacturerObjectsTheEdsListsAreBackedUpToo) {
  testing::TempDir dir;
  std::string eds = read_file(testing::source_dir() / "configs/canopen-mill/drives/servo.eds");
  const std::string none = "[ManufacturerObjects]\nSupportedObjects=0\n";
  ASSERT_NE(eds.find(none), std::string::npos);
  eds.replace(eds.find(none), none.size(), "[ManufacturerObjects]\nSupportedObjects=2\n1=0x2000\n2=0x2002\n");
  eds += "\n[2000]\nParameterName=Drive temperature\nObjectType=0x7\nDataType=0x0003\nAccessType=ro\nDefaultValue=0\nPDOMapping=1\n"
         "\n[2002]\nParameterName=Current loop gain\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\nPDOMapping=0\n";
  std::filesystem::create_directories(dir / "eds");
  write_file_atomically(dir / "eds" / "servo.eds", eds);
  Bus b;
  b.add(3);
  b.start();
  State s = state_of({{'X', 3}});
  s.eds_dir = (dir / "eds").string();
  s.nodes[0].eds = "servo.eds";
  const BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_TRUE(r.ok()) << r.problems[0];
  EXPECT_TRUE(value(r.nodes[0], 0x2000, 0));
  bool missing = false;
  for (const auto& m : r.nodes[0].missing) missing = missing || m.find("2002sub0 Current loop gain") == 0;
  EXPECT_TRUE(missing);
  // Not in the EDS, not read (the simulator's 0x2001 exists on the drive).
  EXPECT_FALSE(value(r.nodes[0], 0x2001, 0));
}

// A gantry pair's second drive is backed up with the first (issue 21):
// one file per drive, both named after the axis.
TEST(CommissionBackup, ReadsBothDrivesOfAGantryPair) {
  Bus b;
  b.add(1).od().set<int8_t>({0x6098, 0}, 19);
  b.add(2).od().set<int8_t>({0x6098, 0}, 21);
  b.start();
  State s = state_of({{'Y', 1}});
  ScannedNode second;
  second.node_id = 2;
  second.cia402 = true;
  s.nodes.push_back(second);
  s.axes[0].gantry = GantryDrive{2, 0, 1, true};
  BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_EQ(r.nodes.size(), 2u);
  EXPECT_EQ(r.nodes[1].node, 2);
  EXPECT_EQ(r.nodes[1].axis, 'Y');
  ASSERT_TRUE(value(r.nodes[1], 0x6098, 0));
  EXPECT_EQ(value(r.nodes[1], 0x6098, 0)->data, (std::vector<uint8_t>{21}));
  testing::TempDir dir;
  const auto files = write_backup(s, r, dir / "backup");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[1].filename(), "node-02-y.dcf");
}

// The loops' parameter sets 0x60F9/0x60FB have manufacturer-specific
// sub-indices: without an EDS the backup reads each record's sub-index 0
// and then every sub-index it counts, in the size the drive gives. Here
// one drive has a sixth position-loop parameter (UNSIGNED8) and the other
// a velocity set of one entry: each is backed up as the drive has it.
TEST(CommissionBackup, TheLoopGainsSubIndicesAreThoseTheDrivesSubIndexZeroCounts) {
  Bus b;
  auto& x_drive = b.add(1);
  x_drive.od().add({0x60FB, 6}, canopen::DataType::Unsigned8, canopen::Access::ReadWrite, 42, false, "vendor filter");
  x_drive.od().set<uint8_t>({0x60FB, 0}, 6);
  b.add(2).od().set<uint8_t>({0x60F9, 0}, 1);
  b.start();
  const State s = state_of({{'X', 1}, {'Y', 2}});
  const BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_EQ(r.nodes.size(), 2u);
  const NodeBackup& x = r.nodes[0];
  const NodeBackup& y = r.nodes[1];
  ASSERT_TRUE(value(x, 0x60FB, 0));
  EXPECT_EQ(value(x, 0x60FB, 0)->object.access, "ro") << "a record's size is not restored";
  const BackedUpValue* sixth = value(x, 0x60FB, 6);
  ASSERT_TRUE(sixth) << "the sub-index beyond the five step 7 knows was not read";
  EXPECT_EQ(sixth->data, (std::vector<uint8_t>{42}));
  EXPECT_EQ(sixth->object.type, canopen::DataType::Unsigned8);
  EXPECT_EQ(sixth->object.name, "Position control parameter 6");
  ASSERT_TRUE(value(x, 0x60FB, 1));
  EXPECT_EQ(value(x, 0x60FB, 1)->object.name, "Position loop gain");
  ASSERT_TRUE(value(x, 0x60F9, 2));
  ASSERT_TRUE(value(y, 0x60F9, 1));
  EXPECT_FALSE(value(y, 0x60F9, 2)) << "node 2's velocity set counts one entry";
  for (const std::string& m : y.missing) EXPECT_EQ(m.find("60F9sub2"), std::string::npos) << m;
}

// Without an EDS the PDOs are searched for number by number: a drive
// whose TPDOs are numbered with a gap (TPDO1-8, then TPDO11) has TPDO11
// backed up too, as long as the gap is shorter than pdo_search_gap; with a
// gap limit of 1 (stop at the first missing number) it is lost.
TEST(CommissionBackup, PdosAfterAGapInTheirNumbersAreFoundWithoutAnEds) {
  namespace co = canopen;
  Bus b;
  auto& drive = b.add(1);
  auto& od = drive.od();
  od.add({0x180A, 0}, co::DataType::Unsigned8, co::Access::Const, 2, false, "TPDO11 communication parameter");
  od.add({0x180A, 1}, co::DataType::Unsigned32, co::Access::ReadWrite, 0x8000028A, false, "COB-ID");
  od.add({0x180A, 2}, co::DataType::Unsigned8, co::Access::ReadWrite, 254, false, "Transmission type");
  od.add({0x1A0A, 0}, co::DataType::Unsigned8, co::Access::ReadWrite, 1, false, "TPDO11 mapping");
  od.add({0x1A0A, 1}, co::DataType::Unsigned32, co::Access::ReadWrite, 0x60410010, false, "Mapping entry 1");
  b.start();
  const State s = state_of({{'X', 1}});
  BackupResult r = backup_drives(*b.client, s, options());
  ASSERT_TRUE(r.ok()) << r.problems[0];
  ASSERT_TRUE(value(r.nodes[0], 0x1807, 1)) << "TPDO8";
  EXPECT_FALSE(value(r.nodes[0], 0x1808, 1));
  ASSERT_TRUE(value(r.nodes[0], 0x180A, 1)) << "TPDO11, after the gap, was not found";
  EXPECT_EQ(value(r.nodes[0], 0x180A, 1)->data, (std::vector<uint8_t>{0x8A, 0x02, 0x00, 0x80}));
  ASSERT_TRUE(value(r.nodes[0], 0x1A0A, 1));
  EXPECT_EQ(value(r.nodes[0], 0x1A0A, 1)->data, (std::vector<uint8_t>{0x10, 0x00, 0x41, 0x60}));
  for (const std::string& m : r.nodes[0].missing) EXPECT_EQ(m.find("1808"), std::string::npos) << "a gap is no loss: " << m;

  BackupOptions first_missing_ends = options();
  first_missing_ends.pdo_search_gap = 1;
  r = backup_drives(*b.client, s, first_missing_ends);
  ASSERT_TRUE(r.ok()) << r.problems[0];
  EXPECT_TRUE(value(r.nodes[0], 0x1807, 1));
  EXPECT_FALSE(value(r.nodes[0], 0x180A, 1));
}

}  // namespace
}  // namespace cnc::commission
