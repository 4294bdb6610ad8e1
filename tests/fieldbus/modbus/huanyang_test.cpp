#include <gtest/gtest.h>

#include <vector>

#include "fieldbus/modbus/crc.hpp"
#include "fieldbus/modbus/huanyang.hpp"

using namespace cnc::modbus;

namespace {
std::vector<uint8_t> bytes(const hy::Frame& f) { return {f.bytes.begin(), f.bytes.begin() + static_cast<long>(f.size)}; }
}  // namespace

// Modbus over Serial Line's own example: read 3 registers from 0x006B of
// slave 0x11 is 11 03 00 6B 00 03, CRC 76 87 (low byte first).
TEST(ModbusCrc, MatchesTheSpecificationsExample) {
  const uint8_t frame[] = {0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87};
  EXPECT_EQ(crc16(frame, 6), 0x8776);
  EXPECT_TRUE(crc_ok(frame, sizeof frame));
  uint8_t bad[sizeof frame];
  std::copy(std::begin(frame), std::end(frame), bad);
  bad[3] ^= 0x01;
  EXPECT_FALSE(crc_ok(bad, sizeof bad));
}

// The Huanyang manual's control examples: run forward 01 03 01 01 31 88,
// stop 01 03 01 08 F1 8E.
TEST(Huanyang, ControlFramesMatchTheManualByteForByte) {
  EXPECT_EQ(bytes(hy::control(1, hy::kControlRunForward)), (std::vector<uint8_t>{0x01, 0x03, 0x01, 0x01, 0x31, 0x88}));
  EXPECT_EQ(bytes(hy::control(1, hy::kControlStop)), (std::vector<uint8_t>{0x01, 0x03, 0x01, 0x08, 0xF1, 0x8E}));
  const auto rev = bytes(hy::control(1, hy::kControlRunReverse));
  ASSERT_EQ(rev.size(), 6u);
  EXPECT_EQ(rev[3], 0x11);
  EXPECT_TRUE(crc_ok(rev.data(), rev.size()));
}

// Write frequency (function 0x05) carries 0.01 Hz, high byte first:
// 100.00 Hz = 0x2710.
TEST(Huanyang, FrequencyFrameCarriesCentiHertzHighByteFirst) {
  const auto f = bytes(hy::set_frequency(1, 10000));
  ASSERT_EQ(f.size(), 7u);
  EXPECT_EQ(f[0], 0x01);
  EXPECT_EQ(f[1], 0x05);
  EXPECT_EQ(f[2], 0x02);
  EXPECT_EQ(f[3], 0x27);
  EXPECT_EQ(f[4], 0x10);
  EXPECT_TRUE(crc_ok(f.data(), f.size()));
}

TEST(Huanyang, StatusRequestNamesTheMonitorValue) {
  const auto f = bytes(hy::read_status(2, hy::kOutputFrequency));
  ASSERT_EQ(f.size(), 8u);
  EXPECT_EQ((std::vector<uint8_t>(f.begin(), f.begin() + 6)), (std::vector<uint8_t>{0x02, 0x04, 0x03, 0x01, 0x00, 0x00}));
  EXPECT_TRUE(crc_ok(f.data(), f.size()));
}

TEST(Huanyang, ReplyParserChecksCrcSlaveFunctionAndLength) {
  // A monitor reply: output frequency 60.00 Hz (0x1770).
  std::vector<uint8_t> r = {0x01, 0x04, 0x03, 0x01, 0x17, 0x70};
  const uint16_t c = crc16(r.data(), r.size());
  r.push_back(c & 0xFF);
  r.push_back(c >> 8);
  const hy::Reply ok = hy::parse_reply(r.data(), r.size(), 1, hy::kReadControlStatus);
  EXPECT_EQ(ok.error, hy::ParseError::None);
  EXPECT_EQ(hy::monitor_value(ok, hy::kOutputFrequency), 6000);
  EXPECT_FALSE(hy::monitor_value(ok, hy::kOutputCurrent).has_value());
  EXPECT_EQ(hy::parse_reply(r.data(), r.size(), 2, hy::kReadControlStatus).error, hy::ParseError::WrongSlave);
  EXPECT_EQ(hy::parse_reply(r.data(), r.size(), 1, hy::kWriteFrequency).error, hy::ParseError::WrongFunction);
  EXPECT_EQ(hy::parse_reply(r.data(), r.size() - 1, 1, hy::kReadControlStatus).error, hy::ParseError::BadLength);
  r[4] ^= 0x40;
  EXPECT_EQ(hy::parse_reply(r.data(), r.size(), 1, hy::kReadControlStatus).error, hy::ParseError::BadCrc);
}
