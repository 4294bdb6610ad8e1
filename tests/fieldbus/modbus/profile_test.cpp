#include <gtest/gtest.h>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "fieldbus/modbus/config.hpp"
#include "fieldbus/modbus/profile.hpp"

using namespace cnc;
using namespace cnc::modbus;

TEST(VfdProfile, EveryBuiltinFamilyHasRunStopSpeedAndFeedback) {
  for (const std::string& name : builtin_profile_names()) {
    const VfdProfile* p = builtin_profile(name);
    ASSERT_NE(p, nullptr) << name;
    EXPECT_TRUE(p->output_frequency.present) << name;
    EXPECT_GT(p->speed_per_hz, 0) << name;
    if (p->protocol == Protocol::Standard) {
      EXPECT_FALSE(p->run_forward.empty()) << name;
      EXPECT_FALSE(p->run_reverse.empty()) << name;
      EXPECT_FALSE(p->stop.empty()) << name;
    }
  }
  EXPECT_EQ(builtin_profile("nonsense"), nullptr);
}

TEST(VfdProfile, FaultTextsDecodeKnownCodesAndNameUnknownOnes) {
  const VfdProfile* delta = builtin_profile("delta");
  ASSERT_NE(delta, nullptr);
  EXPECT_EQ(delta->fault_text(1), "over-current during acceleration (ocA)");
  EXPECT_EQ(delta->fault_text(200), "fault code 200");
}

TEST(VfdProfile, GenericProfileComesEntirelyFromTheIni) {
  const auto ini = ini::IniFile::parse(
      "[MODBUS_VFD_3]\nPROFILE = generic\nRUN_FORWARD = 0x2000:0x12\nRUN_REVERSE = 0x2000:0x22\n"
      "STOP = 0x2000:1\nFAULT_RESET = 0x2002:2\nSPEED_REGISTER = 0x2001\nSPEED_PER_HZ = 100\n"
      "FREQUENCY_REGISTER = 0x2103 INPUT\nFREQUENCY_PER_HZ = 100\nCURRENT_REGISTER = 0x2104\nCURRENT_PER_A = 100\n"
      "FAULT_REGISTER = 0x2100\nFAULT_MASK = 0xFF\nFAULT_TEXT = 1: over-current\nFAULT_TEXT = 7:over-voltage\n",
      "m.ini");
  const VfdProfile p = load_generic_profile(ini, "MODBUS_VFD_3");
  ASSERT_EQ(p.run_forward.size(), 1u);
  EXPECT_EQ(p.run_forward[0].address, 0x2000);
  EXPECT_EQ(p.run_forward[0].value, 0x12);
  EXPECT_EQ(p.speed_address, 0x2001);
  EXPECT_EQ(p.output_frequency.space, Space::Input);
  EXPECT_DOUBLE_EQ(p.current.per_unit, 100);
  EXPECT_EQ(p.fault_mask, 0xFF);
  EXPECT_EQ(p.fault_text(1), "over-current");
  EXPECT_EQ(p.fault_text(7), "over-voltage");
}

TEST(ModbusConfig, ErrorsNameTheFileLineAndKey) {
  const auto ini = ini::IniFile::parse("[MODBUS]\nTRANSPORT = TCP\nHOST = 127.0.0.1\nVFD = 1\n"
                                       "[MODBUS_VFD_1]\nPROFILE = acme\n",
                                       "m.ini");
  try {
    load_link_config(ini, "MODBUS", "modbus.0");
    FAIL() << "an unknown profile was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("m.ini:6"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("acme"), std::string::npos) << e.what();
  }
  const auto hy_tcp = ini::IniFile::parse("[MODBUS]\nTRANSPORT = TCP\nHOST = 127.0.0.1\nVFD = 1\n"
                                          "[MODBUS_VFD_1]\nPROFILE = huanyang\n",
                                          "m.ini");
  EXPECT_THROW(load_link_config(hy_tcp, "MODBUS", "modbus.0"), ConfigError);
}

TEST(ModbusConfig, IoMapsBecomePollingGroupsWithTheirOwnRates) {
  const auto ini = ini::IniFile::parse("[MODBUS_1]\nTRANSPORT = RTU\nDEVICE = /dev/ttyUSB1\nBAUD = 9600\nPARITY = E\nIO = 4\n"
                                       "[MODBUS_1_IO_4]\nPOLL_MS = 40\nCOIL = 0 4\nDISCRETE_INPUT = 8 2 poll_ms=10\n"
                                       "INPUT_REGISTER = 3 2 float signed scale=0.1 offset=-5\nHOLDING_REGISTER = 10 1 s32\n",
                                       "m.ini");
  const LinkConfig c = load_link_config(ini, "MODBUS_1", "modbus.1");
  ASSERT_EQ(c.ios.size(), 1u);
  const IoConfig& io = c.ios[0];
  ASSERT_EQ(io.maps.size(), 4u);
  EXPECT_EQ(io.values, 9u);
  EXPECT_EQ(io.maps[0].poll_ns, 40'000'000);
  EXPECT_EQ(io.maps[1].poll_ns, 10'000'000);
  EXPECT_EQ(io.maps[1].first_value, 4u);
  EXPECT_TRUE(io.maps[2].is_signed);
  EXPECT_DOUBLE_EQ(io.maps[2].scale, 0.1);
  EXPECT_EQ(io.maps[3].type, IoType::S32);
  EXPECT_EQ(c.describe(), "rtu /dev/ttyUSB1 9600 8E1");
}
