#include <gtest/gtest.h>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "fieldbus/canopen/config.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {

std::string error_of(const std::string& ini_text) {
  try {
    const auto ini = ini::IniFile::parse(ini_text, "machine.ini");
    load_bus_config(ini, "CANOPEN", "canopen.0");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

const char* kTwoAxes = R"([EMCMOT]
SERVO_PERIOD = 2000000
[CANOPEN]
INTERFACE = socketcan:can0
BITRATE = 500000
SYNC_COUNTER_OVERFLOW = 16
MASTER_NODE_ID = 100
NODE = 1 2
[CANOPEN_NODE_1]
NAME = x-axis
VENDOR_ID = 0x0000009A
PRODUCT_CODE = 0x00030924
HEARTBEAT_MS = 50
MASTER_HEARTBEAT_TIMEOUT_MS = 150
RPDO1 = 0x6040:0:u16 0x607A:0:s32
TPDO1 = 0x6041:0:u16 0x6064:0:s32
TPDO2 = 0x606C:0:s32 pad8 0x6061:0:s8 pad16
TPDO2_TRANSMISSION = 4
SDO = 0x6060:0:s8 8
SDO = 0x1008:0:str x drive
[CANOPEN_NODE_2]
NAME = y-axis
MANDATORY = NO
RPDO1 = 0x60400010 0x607A0020
TPDO1 = 0x60410010 0x60640020
EXPORT_PINS = YES
)";

}  // namespace

TEST(CanopenConfig, LoadsTheBusAndItsNodes) {
  const auto ini = ini::IniFile::parse(kTwoAxes, "machine.ini");
  const BusConfig c = load_bus_config(ini, "CANOPEN", "canopen.0", 2'000'000);
  EXPECT_EQ(c.interface, "socketcan:can0");
  EXPECT_EQ(c.bitrate, 500000u);
  EXPECT_EQ(c.cycle_ns, 2'000'000) << "the thread's period, not [EMCMOT]SERVO_PERIOD";
  EXPECT_TRUE(c.cycle_key.empty());
  EXPECT_EQ(c.sync_overflow, 16);
  EXPECT_EQ(c.master_node_id, 100);
  ASSERT_EQ(c.nodes.size(), 2u);
  const NodeConfig& x = c.nodes[0];
  EXPECT_EQ(x.label(), "node 1 (x-axis)");
  EXPECT_EQ(x.vendor_id, 0x9Au);
  EXPECT_EQ(x.product_code, 0x30924u);
  EXPECT_FALSE(x.revision);
  EXPECT_EQ(x.heartbeat_ms, 50);
  EXPECT_EQ(x.consumer_timeout_ms(), 120);
  EXPECT_EQ(x.master_heartbeat_timeout_ms, 150);
  ASSERT_EQ(x.rpdos.size(), 1u);
  EXPECT_EQ(x.rpdos[0].map, (std::vector<PdoMapEntry>{{0x6040, 0, 16}, {0x607A, 0, 32}}));
  EXPECT_EQ(x.rpdos[0].transmission, 1);
  ASSERT_EQ(x.tpdos.size(), 2u);
  EXPECT_EQ(x.tpdos[1].map, (std::vector<PdoMapEntry>{{0x606C, 0, 32}, {0x0005, 0, 8}, {0x6061, 0, 8}, {0x0006, 0, 16}}));
  EXPECT_EQ(x.tpdos[1].transmission, 4);
  EXPECT_EQ(x.tpdo_kinds[0], (std::vector<ValueKind>{ValueKind::Unsigned, ValueKind::Signed}));
  ASSERT_EQ(x.sdo.size(), 2u);
  EXPECT_EQ(x.sdo[0].addr, (ObjectAddress{0x6060, 0}));
  EXPECT_EQ(x.sdo[0].data, (std::vector<uint8_t>{8}));
  EXPECT_EQ(x.sdo[0].origin, "machine.ini:19");
  EXPECT_EQ(std::string(x.sdo[1].data.begin(), x.sdo[1].data.end()), "x drive");
  const NodeConfig& y = c.nodes[1];
  EXPECT_FALSE(y.mandatory);
  EXPECT_TRUE(y.export_pins);
  EXPECT_EQ(y.rpdos[0].map[1], (PdoMapEntry{0x607A, 0, 32}));
  // Per 2 ms SYNC period at 500 kbit/s (1000 bit times): SYNC with counter
  // (65 worst case), 2 x RPDO1 and TPDO1 (6 bytes, 115), TPDO2 (8 bytes,
  // 135) every 4th SYNC, heartbeats of node 1 (50 ms) and 2 and the master
  // (100 ms, 65 bits each).
  const can::BusLoad l = c.load();
  EXPECT_NEAR(l.worst_bits_per_cycle, 65 + 4 * 115 + 135 / 4.0 + 65 * (2 / 50.0 + 2 * 2 / 100.0), 1e-9);
  EXPECT_NEAR(l.worst_case(), l.worst_bits_per_cycle / 1000.0, 1e-12);
}

TEST(CanopenConfig, ErrorsNameTheFileLineAndKey) {
  const std::string base = "[CANOPEN]\nINTERFACE = virtual:x\nNODE = 3\n[CANOPEN_NODE_3]\n";
  EXPECT_EQ(error_of(base + "RPDO1 = 0x6040:0:u17\n"),
            "machine.ini:5: [CANOPEN_NODE_3]RPDO1: \"0x6040:0:u17\": type \"u17\" is not one of u8 u16 u32 u64 s8 s16 s32 s64 f32 f64 bool");
  EXPECT_EQ(error_of(base + "RPDO1 = 0x6040:0\n"),
            "machine.ini:5: [CANOPEN_NODE_3]RPDO1: \"0x6040:0\": give the type (index:sub:type); no device description says it");
  EXPECT_EQ(error_of(base + "TPDO1_TRANSMISSION = 1\n"),
            "machine.ini:5: [CANOPEN_NODE_3]TPDO1_TRANSMISSION: TPDO1 is not configured");
  EXPECT_EQ(error_of(base + "SDO = 0x6060:0:s8 300\n"),
            "machine.ini:5: [CANOPEN_NODE_3]SDO: \"300\": out of range for INTEGER8");
  EXPECT_EQ(error_of("[CANOPEN]\nINTERFACE = virtual:x\nNODE = 3\n"),
            "machine.ini:3: [CANOPEN]NODE: node 3 has no [CANOPEN_NODE_3] section");
  EXPECT_EQ(error_of("[CANOPEN]\nINTERFACE = virtual:x\nNODE = 200\n"),
            "machine.ini:3: [CANOPEN]NODE: \"200\": expected node-IDs 1..127");
  EXPECT_EQ(error_of("[CANOPEN]\nINTERFACE = virtual:x\n"), "machine.ini:2: [CANOPEN]INTERFACE: no NODE = <id> lines in [CANOPEN]");
  EXPECT_EQ(error_of(base + "RPDO1 = 0x6040:0:u64 0x607A:0:s32\n"),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: node 3 RPDO1: 96 bits mapped, a classic CAN PDO holds 64");
  EXPECT_EQ(error_of("[CANOPEN]\nINTERFACE = virtual:x\nNODE = 3 127\n[CANOPEN_NODE_3]\n[CANOPEN_NODE_127]\n"),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: node 127 has the master's node-ID 127");
  EXPECT_EQ(error_of(base + "RPDO1 = 0x6040:0:u16\nRPDO1_COB_ID = 0x183\nTPDO1 = 0x6041:0:u16\n"),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: COB-ID 0x183 used by both node 3 RPDO1 and node 3 TPDO1");
}

TEST(CanopenConfig, BusLoadAboveTheBudgetIsRefused) {
  std::string text = "[CANOPEN]\nINTERFACE = virtual:x\nSYNC_PERIOD_US = 1000\nNODE = 1 2 3 4 5\n";
  for (int i = 1; i <= 5; ++i) {
    text += "[CANOPEN_NODE_" + std::to_string(i) + "]\nRPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n";
  }
  EXPECT_EQ(error_of(text),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: bus load 120.9 % in the worst case (100.0 % nominal) exceeds "
            "the budget of 80 % (SYNC period 1000 us, 1000 kbit/s): use fewer or shorter PDOs, a longer period or a "
            "second bus");
  // Three such axes fit (the reference: 3 CSP axes at 1 kHz with margin).
  std::string three = "[CANOPEN]\nINTERFACE = virtual:x\nSYNC_PERIOD_US = 1000\nNODE = 1 2 3\n";
  for (int i = 1; i <= 3; ++i) {
    three += "[CANOPEN_NODE_" + std::to_string(i) + "]\nRPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n";
  }
  EXPECT_EQ(error_of(three), "(no error)");
}

TEST(CanopenConfig, DcfSuppliesMappingValuesAndIdentity) {
  cnc::testing::TempDir dir;
  dir.write("x.dcf", R"([DeviceInfo]
VendorNumber=0x0000009A
ProductNumber=0x00030924
[DeviceComissioning]
NodeID=5
[1017]
ParameterName=Producer heartbeat time
DataType=0x0006
AccessType=rw
DefaultValue=0
ParameterValue=25
[1400]
ObjectType=0x9
SubNumber=2
[1400sub1]
DataType=0x0007
AccessType=rw
DefaultValue=$NODEID+0x200
[1400sub2]
DataType=0x0005
AccessType=rw
DefaultValue=255
ParameterValue=1
[1600]
ObjectType=0x9
SubNumber=3
[1600sub0]
DataType=0x0005
AccessType=rw
ParameterValue=2
[1600sub1]
DataType=0x0007
AccessType=rw
ParameterValue=0x60400010
[1600sub2]
DataType=0x0007
AccessType=rw
ParameterValue=0x607A0020
[6040]
DataType=0x0006
AccessType=rw
PDOMapping=1
[607A]
DataType=0x0004
AccessType=rw
PDOMapping=1
[6060]
DataType=0x0002
AccessType=rw
DefaultValue=0
ParameterValue=8
[6061]
DataType=0x0002
AccessType=ro
ParameterValue=8
)");
  const std::string ini_text = "[CANOPEN]\nINTERFACE = virtual:x\nNODE = 5\n[CANOPEN_NODE_5]\nDCF = x.dcf\n";
  auto ini = ini::IniFile::parse(ini_text, (dir.path() / "machine.ini").string());
  const BusConfig c = load_bus_config(ini, "CANOPEN", "canopen.0");
  const NodeConfig& n = c.nodes.at(0);
  EXPECT_EQ(n.vendor_id, 0x9Au);
  EXPECT_EQ(n.product_code, 0x30924u);
  EXPECT_EQ(n.heartbeat_ms, 25);
  ASSERT_EQ(n.rpdos.size(), 1u);
  EXPECT_EQ(n.rpdos[0].cob_id, 0x205u);
  EXPECT_EQ(n.rpdos[0].transmission, 1);
  EXPECT_EQ(n.rpdos[0].map, (std::vector<PdoMapEntry>{{0x6040, 0, 16}, {0x607A, 0, 32}}));
  EXPECT_EQ(n.rpdo_kinds[0], (std::vector<ValueKind>{ValueKind::Unsigned, ValueKind::Signed}));
  ASSERT_EQ(n.sdo.size(), 1u) << "0x6061 is read-only, the PDO and heartbeat objects are configured apart";
  EXPECT_EQ(n.sdo[0].addr, (ObjectAddress{0x6060, 0}));
  EXPECT_EQ(n.sdo[0].data, (std::vector<uint8_t>{8}));
  EXPECT_EQ(n.sdo[0].origin, (dir.path() / "x.dcf").string() + ":51") << "the ParameterValue line";

  // A mapping the description refuses is caught before anything is sent.
  const std::string bad = ini_text + "TPDO1 = 0x6060:0\n";
  auto ini2 = ini::IniFile::parse(bad, (dir.path() / "machine.ini").string());
  try {
    load_bus_config(ini2, "CANOPEN", "canopen.0");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), (dir.path() / "machine.ini").string() +
                                         ":2: [CANOPEN]INTERFACE: canopen.0: node 5 TPDO1: 0x6060:00 is not "
                                         "PDO-mappable according to " + (dir.path() / "x.dcf").string());
  }
  const std::string other = "[CANOPEN]\nINTERFACE = virtual:x\nNODE = 6\n[CANOPEN_NODE_6]\nDCF = x.dcf\n";
  auto ini3 = ini::IniFile::parse(other, (dir.path() / "machine.ini").string());
  try {
    load_bus_config(ini3, "CANOPEN", "canopen.0");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("is for node-ID 5"), std::string::npos) << e.what();
  }
}

TEST(CanopenConfig, MapEntriesAndWritesParse) {
  std::string err;
  auto e = parse_map_entry("0x6041:0:u16", nullptr, err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->entry.encode(), 0x60410010u);
  e = parse_map_entry("0x60FD:0x00:bool", nullptr, err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->entry.bits, 1);
  EXPECT_EQ(e->kind, ValueKind::Bit);
  e = parse_map_entry("pad16", nullptr, err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->entry.encode(), 0x00060010u);
  EXPECT_FALSE(parse_map_entry("0x60410000", nullptr, err)) << "zero bits";
  EXPECT_FALSE(parse_map_entry("0x10000:0:u8", nullptr, err));
  auto w = parse_sdo_write("0x6081:0:u32 100000", nullptr, err);
  ASSERT_TRUE(w);
  EXPECT_EQ(w->data, (std::vector<uint8_t>{0xA0, 0x86, 0x01, 0x00}));
  w = parse_sdo_write("0x607C:0:s32 -1", nullptr, err);
  ASSERT_TRUE(w);
  EXPECT_EQ(w->data, (std::vector<uint8_t>{0xFF, 0xFF, 0xFF, 0xFF}));
  w = parse_sdo_write("0x2000:0:hex 01 ab FF", nullptr, err);
  ASSERT_TRUE(w);
  EXPECT_EQ(w->data, (std::vector<uint8_t>{0x01, 0xAB, 0xFF}));
  w = parse_sdo_write("0x2001:0:f32 1.5", nullptr, err);
  ASSERT_TRUE(w);
  EXPECT_EQ(w->data, (std::vector<uint8_t>{0x00, 0x00, 0xC0, 0x3F}));
  EXPECT_FALSE(parse_sdo_write("0x6060:0:s8", nullptr, err));
  EXPECT_FALSE(parse_sdo_write("0x6060:0:u8 -1", nullptr, err));
}
