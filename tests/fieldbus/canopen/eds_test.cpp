#include <gtest/gtest.h>

#include "core/util/error.hpp"
#include "fieldbus/canopen/eds.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {
std::filesystem::path data(const std::string& name) {
  return cnc::testing::source_dir() / "tests/fieldbus/canopen/data" / name;
}

std::string error_of(const std::string& text) {
  try {
    parse_eds(text, "bad.eds");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(Eds, ParsesDeviceInfoAndObjects) {
  const DeviceDescription d = load_eds(data("echo_device.eds"));
  EXPECT_FALSE(d.is_dcf);
  EXPECT_EQ(d.vendor_name, "cnc project");
  EXPECT_EQ(d.vendor_number, 0xCC1u);
  EXPECT_EQ(d.product_number, 0x402u);
  EXPECT_EQ(d.revision_number, 0x00010002u);
  EXPECT_EQ(d.baud_rates_kbit, (std::vector<uint32_t>{125, 250, 500, 1000}));
  const EdsEntry* cw = d.find({0x6040, 0});
  ASSERT_NE(cw, nullptr);
  EXPECT_EQ(cw->type, DataType::Unsigned16);
  EXPECT_EQ(cw->access, Access::ReadWrite) << "rww reads as rw";
  EXPECT_TRUE(cw->pdo_mapping);
  EXPECT_EQ(d.find({0x1018, 4})->default_value, "$NODEID+0x1000");
  EXPECT_TRUE(d.has_index(0x1018));
  EXPECT_EQ(d.find({0x1018, 5}), nullptr);
  // CompactSubObj: sub 0 = count, subs 1..4 from the object's type
  ASSERT_NE(d.find({0x2000, 4}), nullptr);
  EXPECT_EQ(d.find({0x2000, 4})->type, DataType::Integer32);
  EXPECT_EQ(d.find({0x2000, 0})->default_value, "4");
}

TEST(Eds, BuildsADictionaryWithNodeIdValuesAndLimits) {
  const DeviceDescription d = load_eds(data("echo_device.eds"));
  ObjectDictionary od;
  d.build_dictionary(od, 9);
  EXPECT_EQ(od.get<uint32_t>({0x1018, 4}), 0x1009u);
  EXPECT_EQ(od.get<uint32_t>({0x1400, 1}), 0x209u);
  EXPECT_EQ(od.get<uint16_t>({0x6041, 0}), 0x0250);
  EXPECT_EQ(od.get<int8_t>({0x6060, 0}), 8);
  const int8_t eleven = 11;
  EXPECT_EQ(od.write({0x6060, 0}, reinterpret_cast<const uint8_t*>(&eleven), 1, true), 0x06090031u);
  const OdEntry* name = od.find({0x1008, 0});
  ASSERT_NE(name, nullptr);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(od.data(*name)), name->size), "Echo device");
}

TEST(Eds, NumbersInCSyntaxWithNodeId) {
  EXPECT_EQ(eval_eds_number("0x180", 0), 0x180);
  EXPECT_EQ(eval_eds_number("$NODEID+0x180", 5), 0x185);
  EXPECT_EQ(eval_eds_number("0x200 + $NODEID", 5), 0x205);
  EXPECT_EQ(eval_eds_number("$nodeid", 7), 7);
  EXPECT_EQ(eval_eds_number("010", 0), 8) << "octal";
  EXPECT_EQ(eval_eds_number("-5", 0), -5);
  EXPECT_FALSE(eval_eds_number("12a", 0));
  EXPECT_FALSE(eval_eds_number("", 0));
  EXPECT_FALSE(eval_eds_number("0x10+", 0));
}

TEST(Eds, DcfParameterValuesAndCommissioning) {
  const std::string text =
      "[DeviceComissioning]\nNodeID=0x0A\nNodeName=x-axis\nBaudrate=1000\n"
      "[1017]\nParameterName=Producer heartbeat time\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\n"
      "DefaultValue=0\nParameterValue=100\n";
  const DeviceDescription d = parse_eds(text, "x.dcf");
  EXPECT_TRUE(d.is_dcf);
  EXPECT_EQ(d.node_id, 10);
  EXPECT_EQ(d.node_name, "x-axis");
  EXPECT_EQ(d.baudrate_kbit, 1000u);
  const EdsEntry* hb = d.find({0x1017, 0});
  EXPECT_EQ(d.value_bytes(*hb, 10, true), (std::vector<uint8_t>{100, 0}));
  EXPECT_EQ(d.value_bytes(*hb, 10, false), (std::vector<uint8_t>{0, 0}));
}

TEST(Eds, ErrorsNameTheFileAndLine) {
  EXPECT_EQ(error_of("[1000]\nObjectType=0x7\nDataType=0x0007\nAccessType=xx\n"),
            "bad.eds:4: AccessType=xx: expected ro, wo, rw, rwr, rww or const");
  EXPECT_EQ(error_of("[1000]\nObjectType=0x7\nDataType=0x0099\nAccessType=ro\n"),
            "bad.eds:3: DataType=0x0099: not a CiA 301 basic data type this stack supports");
  EXPECT_EQ(error_of("[1000]\nObjectType=0x7\nAccessType=ro\n"), "bad.eds:1: [1000]: DataType missing");
  EXPECT_EQ(error_of("[1001]\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=300\n"),
            "bad.eds:5: [0x1001:00] DefaultValue=300: out of range for UNSIGNED8");
  EXPECT_EQ(error_of("[1001]\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=zz\n"),
            "bad.eds:5: [0x1001:00] DefaultValue=zz: expected a number in C syntax (0x.., decimal, $NODEID+..)");
  EXPECT_EQ(error_of("[1018sub1]\nDataType=0x0007\nAccessType=ro\n"), "bad.eds:1: [1018sub1] without its object section [1018]");
  EXPECT_EQ(error_of("[1018]\nObjectType=0x9\nSubNumber=2\n[1018sub0]\nDataType=0x0005\nAccessType=ro\n"),
            "bad.eds:1: [1018]: SubNumber=2 but 1 sub-index sections follow");
  EXPECT_EQ(error_of("[1000]\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nAccessType=rw\n"),
            "bad.eds:5: key AccessType given twice in [1000]");
  EXPECT_EQ(error_of("[FileInfo]\nno equals sign\n"), "bad.eds:2: expected key=value or [section]");
  EXPECT_EQ(error_of("[FileInfo\n"), "bad.eds:1: section header without closing ']'");
  EXPECT_EQ(error_of("[MandatoryObjects]\nSupportedObjects=1\n1=0x1000\n"),
            "bad.eds:3: [MandatoryObjects] 1=0x1000: no such object section");
  EXPECT_EQ(error_of("[DeviceComissioning]\nNodeID=200\n"), "bad.eds:2: NodeID=200: expected 1..127");
  EXPECT_EQ(error_of("[1000]\nObjectType=0x3\n"),
            "bad.eds:2: ObjectType=0x3: expected 0x7 VAR, 0x8 ARRAY, 0x9 RECORD (or 0x2, 0x5, 0x6)");
}

TEST(Eds, MissingFile) {
  try {
    load_eds("/nonexistent/x.eds");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/x.eds: cannot read the device description: cannot open: No such file or directory");
  }
}
