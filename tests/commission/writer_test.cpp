#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "commission/config_writer.hpp"
#include "commission/steps.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission {
namespace {

State machine() {
  State s;
  s.interface = "virtual:w";
  for (int id : {1, 2}) {
    ScannedNode n;
    n.node_id = id;
    n.cia402 = true;
    n.encoder_increments = 10000;
    s.nodes.push_back(n);
  }
  assign_axis(s, 'X', 0, 1);
  assign_axis(s, 'Z', 1, 2);
  set_scaling(s, 'X', 5);
  set_scaling(s, 'Z', 4);
  apply_direction_test(s, 'Z', 5, 5, -2.5, true);  // reversed, half the counts
  return s;
}

std::string read(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(CommissionWriter, GeneratesDrivesWithTheMeasuredScalingAndDirection) {
  testing::TempDir dir;
  const auto files = generate_config(machine(), dir.path(), "m");
  ASSERT_GE(files.size(), 2u);
  const std::string& ini = files[0].content;
  EXPECT_NE(ini.find("COORDINATES = X Z"), std::string::npos);
  EXPECT_NE(ini.find("NODE = 1 2"), std::string::npos);
  // Z: 10000 counts per rev on a 4 mm lead; the table moved half as far as
  // the encoder said: twice the counts per mm, written as a 2 mm lead.
  EXPECT_NE(ini.find("[CIA402_DRIVE_1]"), std::string::npos);
  EXPECT_NE(ini.find("SCREW_LEAD = 2\nREVERSE = YES"), std::string::npos) << ini;
  EXPECT_NE(ini.find("SCREW_LEAD = 5\nREVERSE = NO"), std::string::npos) << ini;
  EXPECT_NE(files[1].content.find("net z-pos-fb cia402.0.drive.01.pos-fb => joint.1.motor-pos-fb"), std::string::npos);
}

State ethercat_machine() {
  State s;
  s.ethercat_interface = "raw:eth1";
  s.esi_dir = "/home/cnc/esi";
  for (unsigned pos : {1u, 2u, 3u}) {
    ScannedSlave sl;
    sl.position = pos;
    sl.vendor_id = 0xCC1;
    sl.product_code = pos == 3 ? 0x999 : 0x402;
    sl.name = "servo " + std::to_string(pos);
    sl.coe = pos != 3;  // slave 3: an I/O coupler without CoE
    sl.esi = pos != 3 ? "servo.xml" : "";
    s.slaves.push_back(sl);
  }
  assign_axis_ethercat(s, 'X', 0, 2);
  assign_axis_ethercat(s, 'Y', 1, 1);
  set_scaling(s, 'X', 5, 131072);
  set_scaling(s, 'Y', 10, 8192, 2, 1);
  return s;
}

// Drives on EtherCAT: the segment, each slave with its identity and ESI,
// the CiA 402 drives addressed by slave position, the EtherCAT master's
// functions in the servo thread.
TEST(CommissionWriter, WritesEthercatDrivesBySlavePosition) {
  testing::TempDir dir;
  const auto files = generate_config(ethercat_machine(), dir.path(), "m");
  const std::string& ini = files[0].content;
  EXPECT_NE(ini.find("[ETHERCAT]\nINTERFACE = raw:eth1\nSLAVE = 2 1\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("[ETHERCAT_SLAVE_2]\nNAME = x-axis\nESI = /home/cnc/esi/servo.xml\nVENDOR_ID = 0x00000CC1\n"
                     "PRODUCT_CODE = 0x00000402\n"),
            std::string::npos)
      << ini;
  EXPECT_NE(ini.find("[CIA402]\nBUS = ethercat.0\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("ADDRESS = 2\nNAME = x-axis\nJOINT = 0\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("ADDRESS = 1\nNAME = y-axis\nJOINT = 1\nENCODER_COUNTS = 8192\nGEAR_MOTOR_REVS = 2"),
            std::string::npos)
      << ini;
  EXPECT_EQ(ini.find("[CANOPEN"), std::string::npos) << ini;
  const std::string& hal = files[1].content;
  EXPECT_NE(hal.find("loadrt ethercat\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("addf ethercat.0.read servo-thread"), std::string::npos) << hal;
  EXPECT_NE(hal.find("addf ethercat.0.write servo-thread"), std::string::npos) << hal;
  EXPECT_NE(hal.find("cia402.0.watchdog-ok => ethercat.0.enable"), std::string::npos) << hal;
}

TEST(CommissionWriter, EthercatAssignmentRefusesUnknownSlavesSlavesWithoutCoeAndOneBusPerMachine) {
  State s = ethercat_machine();
  try {
    assign_axis_ethercat(s, 'Z', 2, 3);
    FAIL() << "a slave without CoE accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("EtherCAT slave 3 (servo 3) has no CoE mailbox"), std::string::npos) << e.what();
  }
  EXPECT_THROW(assign_axis_ethercat(s, 'Z', 2, 7), std::invalid_argument) << "not found by the scan";
  EXPECT_THROW(assign_axis_ethercat(s, 'Z', 2, 2), std::invalid_argument) << "slave 2 drives X";
  // A CANopen axis beside EtherCAT ones: refused by the writer, naming both.
  ScannedNode n;
  n.node_id = 4;
  n.cia402 = true;
  n.encoder_increments = 10000;
  s.nodes.push_back(n);
  s.interface = "socketcan:can0";
  assign_axis(s, 'Z', 2, 4);
  set_scaling(s, 'Z', 5);
  testing::TempDir dir;
  try {
    generate_config(s, dir.path(), "m");
    FAIL() << "two buses written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("the writer puts every axis on one bus"), std::string::npos) << e.what();
  }
}

TEST(CommissionWriter, WritesDisabledAxesAsDisabledOptionalDrivesAndRefusesGapsInTheJoints) {
  State s = machine();
  s.axis('Z')->enabled = false;
  testing::TempDir dir;
  const auto files = generate_config(s, dir.path(), "m");
  const std::string& ini = files[0].content;
  const auto z = ini.find("[CIA402_DRIVE_1]");
  ASSERT_NE(z, std::string::npos);
  EXPECT_NE(ini.find("DISABLED = YES", z), std::string::npos) << ini;
  EXPECT_EQ(ini.find("DISABLED = YES"), ini.find("DISABLED = YES", z)) << "X is not disabled";
  EXPECT_NE(ini.find("MANDATORY = NO", ini.find("[CANOPEN_NODE_2]")), std::string::npos);
  s.axes.erase(s.axes.begin());  // Z alone on joint 1: no joint 0
  EXPECT_THROW(generate_config(s, dir.path(), "m"), std::invalid_argument);
}

TEST(CommissionWriter, KeepsTheOldFilesAsBackupAndSkipsUnchangedOnes) {
  testing::TempDir dir;
  dir.write("m.ini", "old ini\n");
  const auto files = generate_config(machine(), dir.path(), "m");
  auto changed = write_config(files);
  EXPECT_EQ(changed.size(), files.size());
  EXPECT_EQ(read(dir / "m.ini.bak"), "old ini\n");
  EXPECT_EQ(read(dir / "m.ini"), files[0].content);
  changed = write_config(files);
  EXPECT_TRUE(changed.empty());
}

TEST(CommissionWriter, DiffShowsRemovedAndAddedLines) {
  const std::string d = diff_text("f.ini", "a\nb\nc\n", "a\nB\nc\nd\n");
  EXPECT_EQ(d, "--- f.ini\n+++ f.ini\n-b\n+B\n+d\n");
  EXPECT_EQ(diff_text("f.ini", "same\n", "same\n"), "");
}

TEST(CommissionWriter, TheWrittenConfigurationPassesTheStrictCheck) {
  const auto cncd = testing::binary_dir() / "bin/cncd";
  if (!std::filesystem::exists(cncd)) GTEST_SKIP() << "cncd not built";
  testing::TempDir dir;
  State s = machine();
  // The drives: simulated ones on the same in-process bus, as a site file.
  s.interface = "virtual:w";
  dir.write("drives.ini",
            "[CIA402_SIM]\nINTERFACE = virtual:w\nCLOCK = SERVO\nNODE = 1 2\n"
            "[CIA402_SIM_NODE_1]\nENCODER_COUNTS = 10000\n[CIA402_SIM_NODE_2]\nENCODER_COUNTS = 10000\n");
  dir.write("drives.hal", "loadrt cia402_sim sections=CIA402_SIM\n");
  dir.write("drives-run.hal", "addf cia402-sim.0.update servo-thread\n");
  s.ini_includes = {"drives.ini"};
  s.hal_before_bus = {"drives.hal"};
  s.hal_after_bus = {"drives-run.hal"};
  write_config(generate_config(s, dir.path(), "m"));
  std::string out;
  EXPECT_EQ(check_config(cncd, dir / "m.ini", out), 0) << out;
}

// A gantry router: X, Y on two drives (node 3 mounted mirrored), Z.
State gantry_machine() {
  State s;
  s.interface = "virtual:wg";
  for (int id : {1, 2, 3, 4}) {
    ScannedNode n;
    n.node_id = id;
    n.cia402 = true;
    n.encoder_increments = 10000;
    s.nodes.push_back(n);
  }
  assign_axis(s, 'X', 0, 1);
  assign_axis(s, 'Y', 1, 2, GantryDrive{3, 0, 2, true});
  assign_axis(s, 'Z', 3, 4);
  for (char l : {'X', 'Y', 'Z'}) set_scaling(s, l, 5);
  s.axis('Y')->min_limit = -2;
  s.axis('Y')->max_limit = 8;
  return s;
}

std::string section(const std::string& ini, const std::string& name) {
  const auto at = ini.find("[" + name + "]\n");
  if (at == std::string::npos) return {};
  const auto end = ini.find("\n[", at + 1);
  return ini.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

// Step 7's loop response is a writer option: on the response axis' drive
// only, the target velocity mapped (CANopen RPDO2, EtherCAT the RxPDO with
// 0x60FF), a virtual CAN bus shared, and the signal generator on the
// drive's vel-cmd; without the option none of it; an axis without a drive
// is refused.
TEST(CommissionWriter, TheResponseOptionMapsTheTargetVelocityAndAGeneratorOnTheAxisDriveOnly) {
  testing::TempDir dir;
  const State can = machine();
  const auto plain = generate_config(can, dir.path(), "m");
  const auto resp = generate_config(can, dir.path(), "m", {.response_axis = 'Z'});
  const std::string& ini = resp[0].content;
  EXPECT_EQ(section(ini, "CANOPEN_NODE_1").find("RPDO2"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CANOPEN_NODE_2").find("RPDO1 = 0x6040:0:u16 0x607A:0:s32\n"
                                                "# cnc-commission response: the target velocity for CSV\n"
                                                "RPDO2 = 0x60FF:0:s32\nTPDO1 = "),
            std::string::npos)
      << ini;
  EXPECT_NE(section(ini, "CANOPEN").find("INTERFACE = virtual:w,share\n"), std::string::npos) << ini;
  const std::string& hal = resp[1].content;
  EXPECT_NE(hal.find("loadrt siggen names=response,response-pos\nloadrt mux2 names=response-mux,response-pos-mux\n"),
            std::string::npos)
      << hal;
  EXPECT_NE(hal.find("net response-vel response-mux.out => cia402.0.drive.01.vel-cmd\n"), std::string::npos) << hal;
  for (const std::string& text : {plain[0].content, plain[1].content}) {
    EXPECT_EQ(text.find("RPDO2"), std::string::npos) << text;
    EXPECT_EQ(text.find(",share"), std::string::npos) << text;
    EXPECT_EQ(text.find("response"), std::string::npos) << text;
  }
  // Everything else is the machine's configuration as written.
  std::string stripped = ini;
  for (const std::string cut : {"# cnc-commission response: the target velocity for CSV\nRPDO2 = 0x60FF:0:s32\n", ",share"})
    stripped.erase(stripped.find(cut), cut.size());
  EXPECT_EQ(stripped, plain[0].content);
  // The position loop's generator: added to Z's position command alone,
  // its functions before the drives' write.
  const std::string pos_through = "net z-pos-cmd joint.1.motor-pos-cmd => response-pos-sum.in0\n"
                                  "net z-pos-cmd-response response-pos-sum.out => cia402.0.drive.01.pos-cmd\n";
  EXPECT_NE(hal.find(pos_through), std::string::npos) << hal;
  EXPECT_NE(hal.find("net x-pos-cmd joint.0.motor-pos-cmd => cia402.0.drive.00.pos-cmd\n"), std::string::npos) << hal;
  EXPECT_LT(hal.find("addf response-pos-sum servo-thread\n"), hal.find("addf cia402.0.write servo-thread\n")) << hal;
  std::string hal_stripped = hal;
  const std::size_t b = hal.find("# cnc-commission response: signal generators on the drive's velocity command\n");
  const std::string last = "net response-pos-offset response-pos-mux.out => response-pos-sum.in1\n";
  ASSERT_NE(b, std::string::npos);
  hal_stripped.erase(b, hal.find(last) + last.size() - b);
  hal_stripped.replace(hal_stripped.find(pos_through), pos_through.size(),
                       "net z-pos-cmd joint.1.motor-pos-cmd => cia402.0.drive.01.pos-cmd\n");
  EXPECT_EQ(hal_stripped.substr(0, plain[1].content.size()), plain[1].content);

  const State ecat = ethercat_machine();
  const std::string eini = generate_config(ecat, dir.path(), "m", {.response_axis = 'X'})[0].content;
  EXPECT_NE(section(eini, "ETHERCAT_SLAVE_2").find("\nRXPDO = " + std::string(kResponseEthercatRxPdo) + "\n"),
            std::string::npos)
      << eini;
  EXPECT_EQ(section(eini, "ETHERCAT_SLAVE_1").find("RXPDO"), std::string::npos) << eini;
  EXPECT_EQ(generate_config(ecat, dir.path(), "m")[0].content.find("RXPDO"), std::string::npos);
  EXPECT_NE(generate_config(ecat, dir.path(), "m", {.response_axis = 'X'})[1].content.find(
                "response-mux.out => cia402.0.drive.00.vel-cmd"),
            std::string::npos);
  try {
    generate_config(ecat, dir.path(), "m", {.response_axis = 'Z'});
    FAIL() << "a response on an axis without a drive was written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis Z has no drive yet"), std::string::npos) << e.what();
  }
}

// A gantry pair as LinuxCNC writes it: the letter twice in trivkins'
// coordinates with kinstype=BOTH, two joints with the axis' limits homed
// together (the same negative HOME_SEQUENCE), a drive and node each, the
// second drive's own REVERSE, and HAL nets for both.
TEST(CommissionWriter, WritesAGantryPairAsTwoJointsOfOneAxisHomedTogether) {
  testing::TempDir dir;
  const auto files = generate_config(gantry_machine(), dir.path(), "g");
  const std::string& ini = files[0].content;
  EXPECT_NE(ini.find("[KINS]\nKINEMATICS = trivkins coordinates=XYYZ kinstype=BOTH\nJOINTS = 4\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("COORDINATES = X Y Y Z\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("NODE = 1 2 3 4\n"), std::string::npos) << ini;
  EXPECT_NE(ini.find("DRIVE = 0 1 2 3\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "AXIS_Y").find("MIN_LIMIT = -2\nMAX_LIMIT = 8\n"), std::string::npos) << ini;
  EXPECT_EQ(section(ini, "AXIS_Y2"), "") << "one axis, not two";
  for (const char* j : {"JOINT_1", "JOINT_2"}) {
    const std::string sec = section(ini, j);
    EXPECT_NE(sec.find("MIN_LIMIT = -2\nMAX_LIMIT = 8\n"), std::string::npos) << j << ":\n" << sec;
    EXPECT_NE(sec.find("HOME_SEQUENCE = -1\n"), std::string::npos) << j << ":\n" << sec;
  }
  EXPECT_NE(section(ini, "JOINT_0").find("HOME_SEQUENCE = 0\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "JOINT_3").find("HOME_SEQUENCE = 0\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_1").find("ADDRESS = 2\nNAME = y-axis\nJOINT = 1\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_1").find("REVERSE = NO\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_2").find("ADDRESS = 3\nNAME = y2-axis\nJOINT = 2\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_2").find("SCREW_LEAD = 5\nREVERSE = YES\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_3").find("ADDRESS = 4\nNAME = z-axis\nJOINT = 3\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CANOPEN_NODE_3").find("NAME = y2-axis\n"), std::string::npos) << ini;
  const std::string& hal = files[1].content;
  EXPECT_NE(hal.find("net y-pos-cmd joint.1.motor-pos-cmd => cia402.0.drive.01.pos-cmd\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y2-pos-cmd joint.2.motor-pos-cmd => cia402.0.drive.02.pos-cmd\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y2-pos-fb cia402.0.drive.02.pos-fb => joint.2.motor-pos-fb\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y2-enable joint.2.amp-enable-out => cia402.0.drive.02.enable\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net z-pos-cmd joint.3.motor-pos-cmd => cia402.0.drive.03.pos-cmd\n"), std::string::npos) << hal;
}

// The switches found on the axis are netted for both drives of the pair,
// under their own net names (a name twice is a HAL error).
TEST(CommissionWriter, NetsTheSwitchesOfBothGantryDrivesUnderTheirOwnNames) {
  State s = gantry_machine();
  AxisSwitches w;
  w.neg_limit = {true, -5, 0, false, false, ""};  // active low: through a not
  w.home = {true, 1, 0, false, true, ""};
  s.axis('Y')->switches = w;
  testing::TempDir dir;
  const std::string hal = generate_config(s, dir.path(), "g")[1].content;
  EXPECT_NE(hal.find("loadrt not names=y-neg-lim-inv,y2-neg-lim-inv\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y-home-sw cia402.0.drive.01.home-sw => joint.1.home-sw-in\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y2-home-sw cia402.0.drive.02.home-sw => joint.2.home-sw-in\n"), std::string::npos) << hal;
  EXPECT_NE(hal.find("net y2-neg-lim y2-neg-lim-inv.out => joint.2.neg-lim-sw-in\n"), std::string::npos) << hal;
}

// Each drive of the pair with what steps 4-6 found on its own joint: its
// scale correction and direction, its home switch's HOME_OFFSET (with the
// squaring) and the first joint's HOME; the pair's joints apart (HOME_SEQUENCE
// 0) in the configuration the gantry's steps bring up.
TEST(CommissionWriter, WritesEachGantryDrivesOwnScaleDirectionAndHomeOffset) {
  State s = gantry_machine();
  Axis& y = *s.axis('Y');
  y.gantry->reverse = false;  // the second motor turned out to run the same way
  y.gantry->correction = 1.25;
  AxisHoming h;
  h.method = "controller";
  h.search_velocity = -5;
  h.latch_velocity = 0.5;
  h.home_offset = -1.5;
  h.home = 3.5;
  y.homing = h;
  h.home_offset = -1.2;  // its own switch 0.1 mm further, plus 0.2 mm squaring
  y.gantry->homing = h;
  y.gantry->squaring = 0.2;
  testing::TempDir dir;
  const std::string ini = generate_config(s, dir.path(), "g")[0].content;
  EXPECT_NE(section(ini, "CIA402_DRIVE_2").find("SCREW_LEAD = 4\nREVERSE = NO\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "JOINT_1").find("HOME_OFFSET = -1.5\nHOME = 3.5\nHOME_SEQUENCE = -1\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "JOINT_2").find("HOME_OFFSET = -1.2\nHOME = 3.5\nHOME_SEQUENCE = -1\n"), std::string::npos) << ini;
  const std::string apart = generate_config(s, dir.path(), "g", {.gantry_joints_apart = true})[0].content;
  EXPECT_NE(section(apart, "JOINT_2").find("HOME_SEQUENCE = 0\n"), std::string::npos) << apart;
  EXPECT_NE(apart.find("the pair's joints are not homed together"), std::string::npos) << apart;
}

// The drive's torque limit (0x6072) the scan read is written back with the
// drive ([CIA402_DRIVE_n]MAX_TORQUE, % of rated); none when not read.
TEST(CommissionWriter, WritesTheScannedTorqueLimitOfEachDrive) {
  State s = gantry_machine();
  s.nodes[1].max_torque = 2500;
  s.nodes[2].max_torque = 3000;
  testing::TempDir dir;
  const std::string ini = generate_config(s, dir.path(), "g")[0].content;
  EXPECT_NE(section(ini, "CIA402_DRIVE_1").find("MAX_TORQUE = 250\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_2").find("MAX_TORQUE = 300\n"), std::string::npos) << ini;
  EXPECT_EQ(section(ini, "CIA402_DRIVE_0").find("MAX_TORQUE"), std::string::npos) << ini;
}

TEST(CommissionWriter, GantryAssignmentRefusesADriveOrJointInUseAndAFaultyDrive) {
  State s = gantry_machine();
  EXPECT_THROW(assign_axis(s, 'A', 4, 5, GantryDrive{3, 0, 5, false}), std::invalid_argument) << "node 3 is Y's second drive";
  s.nodes.push_back(ScannedNode{});
  s.nodes.back().node_id = 5;
  s.nodes.back().cia402 = true;
  s.nodes.push_back(s.nodes.back());
  s.nodes.back().node_id = 6;
  s.nodes.back().fault = true;
  try {
    assign_axis(s, 'A', 4, 5, GantryDrive{6, 0, 5, false});
    FAIL() << "a drive in fault accepted as the gantry's second drive";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis A: the gantry's second drive, node 6"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("is in fault"), std::string::npos) << e.what();
  }
  EXPECT_THROW(assign_axis(s, 'A', 4, 5, GantryDrive{5, 0, 6, false}), std::invalid_argument) << "the first drive's node";
  EXPECT_THROW(assign_axis(s, 'A', 4, 5, GantryDrive{6, 0, 2, false}), std::invalid_argument) << "joint 2 is Y's";
  EXPECT_THROW(assign_axis(s, 'A', 2, 5), std::invalid_argument) << "joint 2 is Y's second joint";
  EXPECT_THROW(assign_axis(s, 'A', 4, 5, GantryDrive{6, 0, 4, false}), std::invalid_argument) << "the first drive's joint";
  // A gap in the joints (Z on 2, Y's second drive on joint 5): named.
  State g = gantry_machine();
  g.axis('Z')->joint = 2;
  g.axis('Y')->gantry->joint = 5;
  testing::TempDir dir;
  try {
    generate_config(g, dir.path(), "g");
    FAIL() << "a gap in the joints written";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis Y's gantry drive is on joint 5"), std::string::npos) << e.what();
  }
}

// Drive homing methods search in the drive's own direction: on a second
// drive that turns the other way the method would search the other side,
// so the writer refuses it, naming the way out; a pair turning the same
// way gets the method on both drives.
TEST(CommissionWriter, RefusesDriveHomingOnAGantryWhoseSecondDriveTurnsTheOtherWay) {
  State s = gantry_machine();
  AxisHoming h;
  h.method = "drive:21";
  h.search_velocity = -5;
  h.latch_velocity = -0.5;
  s.axis('Y')->homing = h;
  testing::TempDir dir;
  try {
    generate_config(s, dir.path(), "g");
    FAIL() << "drive homing written for a reversed second drive";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis Y: the gantry's second drive turns the other way"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("homing --method controller"), std::string::npos) << e.what();
  }
  s.axis('Y')->gantry->reverse = false;
  const std::string ini = generate_config(s, dir.path(), "g")[0].content;
  EXPECT_NE(section(ini, "CIA402_DRIVE_1").find("HOME_METHOD = 21\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "CIA402_DRIVE_2").find("HOME_METHOD = 21\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "JOINT_2").find("HOME_MODE = DRIVE\n"), std::string::npos) << ini;
  EXPECT_NE(section(ini, "JOINT_2").find("HOME_SEQUENCE = -1\n"), std::string::npos) << ini;
}

// The gantry configuration is one cncd accepts: loaded with its HAL by
// `cncd --check --strict`, with four simulated drives on the bus.
TEST(CommissionWriter, TheWrittenGantryConfigurationPassesTheStrictCheck) {
  const auto cncd = testing::binary_dir() / "bin/cncd";
  if (!std::filesystem::exists(cncd)) GTEST_SKIP() << "cncd not built";
  testing::TempDir dir;
  State s = gantry_machine();
  dir.write("drives.ini",
            "[CIA402_SIM]\nINTERFACE = virtual:wg\nCLOCK = SERVO\nNODE = 1 2 3 4\n"
            "[CIA402_SIM_NODE_1]\nENCODER_COUNTS = 10000\n[CIA402_SIM_NODE_2]\nENCODER_COUNTS = 10000\n"
            "[CIA402_SIM_NODE_3]\nENCODER_COUNTS = 10000\n[CIA402_SIM_NODE_4]\nENCODER_COUNTS = 10000\n");
  dir.write("drives.hal", "loadrt cia402_sim sections=CIA402_SIM\n");
  dir.write("drives-run.hal", "addf cia402-sim.0.update servo-thread\n");
  s.ini_includes = {"drives.ini"};
  s.hal_before_bus = {"drives.hal"};
  s.hal_after_bus = {"drives-run.hal"};
  write_config(generate_config(s, dir.path(), "g"));
  std::string out;
  EXPECT_EQ(check_config(cncd, dir / "g.ini", out), 0) << out;
}

}  // namespace
}  // namespace cnc::commission
