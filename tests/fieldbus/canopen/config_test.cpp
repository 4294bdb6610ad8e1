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
MAX_CYCLE_LOAD = 95
SDO_FRAMES_PER_CYCLE = 1
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
TPDO2_SYNC_START = 3
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
  EXPECT_EQ(x.sdo[0].origin, "machine.ini:22");
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
  // Per slot: the SYNC counter (16, a multiple of 4) and SYNC start 3 put
  // TPDO2 in the third of four slots; EMCY allowance (135) interferes, one
  // SDO frame (135) blocks.
  EXPECT_DOUBLE_EQ(c.max_cycle_load, 0.95);
  EXPECT_EQ(c.plan_sdo_frames, 1u);
  EXPECT_EQ(c.plan_emcy_frames, 1u);
  ASSERT_EQ(l.slots.size(), 4u);
  EXPECT_DOUBLE_EQ(l.slots[2].synchronous_bits, 65 + 4 * 115 + 135);
  EXPECT_DOUBLE_EQ(l.slots[0].synchronous_bits, 65 + 4 * 115);
  EXPECT_EQ(l.worst_slot, 2u);
  EXPECT_DOUBLE_EQ(l.slots[2].total(), 65 + 4 * 115 + 135 + 135 + 135);
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

namespace {
std::string csp_axes(int n, const std::string& bus_extra = "") {
  std::string text = "[CANOPEN]\nINTERFACE = virtual:x\nSYNC_PERIOD_US = 1000\nNODE =";
  for (int i = 1; i <= n; ++i) text += " " + std::to_string(i);
  text += "\n" + bus_extra;
  for (int i = 1; i <= n; ++i) {
    text += "[CANOPEN_NODE_" + std::to_string(i) + "]\nRPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n";
  }
  return text;
}
}  // namespace

// The busiest cycle of 3 CSP axes at 1 kHz: SYNC 55 + 6 x 115 (RPDO1,
// TPDO1) = 745 synchronous bits, the EMCY allowance (135, it wins
// arbitration against the PDOs), one 8-byte SDO frame on the wire (135):
// 1015 bit times, more than the 1 ms cycle. Two axes: 785 (78.5 %).
TEST(CanopenConfig, ABusWhoseBusiestCycleDoesNotFitIsRefused) {
  EXPECT_EQ(error_of(csp_axes(3)),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: bus load: cycle slot 0 of 1 needs 1015 bit times (745 "
            "synchronous + 135 higher-priority events and allowances + 135 blocking), 101.5 % of the SYNC period, above "
            "the budget of 90 % (MAX_CYCLE_LOAD) (SYNC period 1000 us, 1000 kbit/s): use fewer or shorter PDOs, "
            "inhibit times on event PDOs, SYNC_START phases, a longer period or a second bus; LOAD_OVERRIDE = YES runs "
            "it anyway, with a warning");
  EXPECT_EQ(error_of(csp_axes(2)), "(no error)");
  const auto ini = cnc::ini::IniFile::parse(csp_axes(2), "machine.ini");
  const BusConfig two = load_bus_config(ini, "CANOPEN", "canopen.0");
  EXPECT_NEAR(two.load().worst_cycle(), 0.785, 1e-12);
  // Average: SYNC + 4 x 115 + 3 heartbeats (65 bits every 100 ms).
  EXPECT_NEAR(two.load().worst_bits_per_cycle, 55 + 4 * 115 + 3 * 65 / 100.0, 1e-9);
}

TEST(CanopenConfig, TheAverageLoadOfEventPdosAtTheirInhibitTimeIsChecked) {
  // Two axes, each with three 8-byte event TPDOs at a 1 ms inhibit time:
  // 135 bits per cycle each on average, 515 + 6 x 135 + 2 = 1327 bits,
  // refused (their busiest cycle still fits: they only block once).
  std::string text = csp_axes(2);
  for (int i = 1; i <= 2; ++i) {
    const std::string sec = "[CANOPEN_NODE_" + std::to_string(i) + "]\n";
    std::string add;
    for (int p = 2; p <= 4; ++p) {
      const std::string k = "TPDO" + std::to_string(p);
      add += k + " = 0x606C:0:s32 0x60FD:0:u32\n" + k + "_TRANSMISSION = 255\n" + k + "_INHIBIT_100US = 10\n";
    }
    text.insert(text.find(sec) + sec.size(), add);
  }
  const std::string e = error_of(text);
  EXPECT_NE(e.find("bus load: average load 132.7 % in the worst case"), std::string::npos) << e;
  EXPECT_NE(e.find("(MAX_BUS_LOAD)"), std::string::npos) << e;
  // At a 10 ms inhibit time: 515 + 6 x 13.5 + 2 = 598 bits, accepted.
  std::string slow = text;
  for (std::size_t at; (at = slow.find("_INHIBIT_100US = 10\n")) != std::string::npos;) {
    slow.replace(at, 20, "_INHIBIT_100US = 100\n");
  }
  EXPECT_EQ(error_of(slow), "(no error)");
}

TEST(CanopenConfig, AnEventPdoWithNothingBoundingItsRateIsRefused) {
  std::string text = csp_axes(1) + "TPDO2 = 0x60FD:0:u32\nTPDO2_TRANSMISSION = 255\nTPDO2_EVENT_MS = 100\n";
  EXPECT_EQ(error_of(text),
            "machine.ini:2: [CANOPEN]INTERFACE: canopen.0: node 1 TPDO2: event-driven (transmission 255) with nothing "
            "bounding its rate, the bus load cannot be planned: give TPDO2_INHIBIT_100US (the device enforces it) or "
            "TPDO2_MIN_INTERVAL_US (what the application guarantees)");
  // A declared interval plans it.
  const auto ini = cnc::ini::IniFile::parse(text + "TPDO2_MIN_INTERVAL_US = 5000\n", "machine.ini");
  const BusConfig c = load_bus_config(ini, "CANOPEN", "canopen.0");
  EXPECT_EQ(c.nodes[0].tpdos[1].plan_interval_us, 5000u);
  EXPECT_NEAR(c.load().worst_bits_per_cycle, 55 + 2 * 115 + 95 / 5.0 + 2 * 65 / 100.0, 1e-9);
}

// Synchronous PDOs sent every n-th SYNC coincide in one cycle unless the
// SYNC counter and SYNC_START fix their phases.
TEST(CanopenConfig, SyncStartPhasesSpreadDividedPdosOverTheSlots) {
  std::string text = csp_axes(2, "SYNC_COUNTER_OVERFLOW = 20\nLOAD_OVERRIDE = YES\n");
  for (int i = 1; i <= 2; ++i) {
    const std::string sec = "[CANOPEN_NODE_" + std::to_string(i) + "]\n";
    text.insert(text.find(sec) + sec.size(), "TPDO4 = 0x606C:0:s32 0x6077:0:s16 0x603F:0:u16\nTPDO4_TRANSMISSION = 20\n");
  }
  auto ini = cnc::ini::IniFile::parse(text, "machine.ini");
  BusConfig c = load_bus_config(ini, "CANOPEN", "canopen.0", 1'000'000);
  ASSERT_EQ(c.load().slots.size(), 1u);  // no phase known: both in the one planned slot
  const double together = c.load().worst_cycle();
  c.nodes[0].tpdos[1].sync_start = 1;
  c.nodes[1].tpdos[1].sync_start = 11;
  const can::BusLoad spread = c.load();
  ASSERT_EQ(spread.slots.size(), 20u);
  EXPECT_EQ(spread.slots[0].synchronous_bits, 65 + 4 * 115 + 135);
  EXPECT_EQ(spread.slots[10].synchronous_bits, 65 + 4 * 115 + 135);
  EXPECT_EQ(spread.slots[1].synchronous_bits, 65 + 4 * 115);
  EXPECT_LT(spread.worst_cycle(), together);
}

TEST(CanopenConfig, LoadOverrideRunsAPlanAboveItsBudgetAndSaysSo) {
  const auto ini = cnc::ini::IniFile::parse(csp_axes(3, "LOAD_OVERRIDE = YES\n"), "machine.ini");
  const BusConfig c = load_bus_config(ini, "CANOPEN", "canopen.0");
  EXPECT_TRUE(c.load_override);
  EXPECT_NE(c.load_problem().find("101.5 % of the SYNC period"), std::string::npos) << c.load_problem();
}

// configs/sim's drives send by priority (the simulated drives' TX_QUEUE);
// had they one FIFO queue each, the event PDOs queued before a TPDO1 would
// make the busiest cycle far longer than the SYNC period, and the plan
// says so.
TEST(CanopenConfig, TheSimulatedMillDoesNotFitItsBusIfItsDrivesSentInQueueOrder) {
  auto ini = cnc::ini::IniFile::load(cnc::testing::source_dir() / "configs/sim/sim.ini");
  const double priority = load_bus_config(ini, "CANOPEN", "canopen.0", 1'000'000).load().worst_cycle();
  ini.set("CANOPEN_NODE_1", "TX_QUEUE", "FIFO");
  ini.set("CANOPEN_NODE_2", "TX_QUEUE", "FIFO");
  EXPECT_LT(priority, 0.80);
  // Refused at start-up: SYNC, RPDO1 and TPDO1 of both (515 bits), each
  // node's TPDO2-4 and heartbeat queued ahead (2 x 460), and what outranks
  // the heartbeat 0x702: the EMCY and SDO allowances (405).
  try {
    load_bus_config(ini, "CANOPEN", "canopen.0", 1'000'000);
    ADD_FAILURE() << "FIFO drives accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("needs 1905 bit times (515 synchronous + 1325 higher-priority events and "
                                         "allowances + 65 blocking), 190.5 % of the SYNC period"),
              std::string::npos)
        << e.what();
  }
  ini.set("CANOPEN", "LOAD_OVERRIDE", "YES");
  const BusConfig fifo = load_bus_config(ini, "CANOPEN", "canopen.0", 1'000'000);
  EXPECT_TRUE(fifo.nodes[0].tx_fifo);
  EXPECT_NE(fifo.load_problem().find("(MAX_CYCLE_LOAD)"), std::string::npos) << fifo.load_problem();
  ini.set("CANOPEN_NODE_1", "TX_QUEUE", "MAILBOX");
  try {
    load_bus_config(ini, "CANOPEN", "canopen.0", 1'000'000);
    ADD_FAILURE() << "TX_QUEUE = MAILBOX accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("TX_QUEUE"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("expected PRIORITY or FIFO"), std::string::npos) << e.what();
  }
}

// configs/sim at 1 kHz: both buses within their budgets with margin.
TEST(CanopenConfig, TheSimulatedMillFitsItsBusesAtOneKilohertz) {
  const auto ini = cnc::ini::IniFile::load(cnc::testing::source_dir() / "configs/sim/sim.ini");
  for (const char* section : {"CANOPEN", "CANOPEN_1"}) {
    const BusConfig c = load_bus_config(ini, section, section, 1'000'000);
    const can::BusLoad l = c.load();
    EXPECT_LT(l.worst_case(), 0.70) << section;
    EXPECT_LT(l.worst_cycle(), 0.80) << section;
    EXPECT_EQ(c.load_problem(), "") << section;
    EXPECT_FALSE(c.load_override) << section;
  }
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
