// Frame and datagram codec: layout on the wire, parsing, working-counter rules.
#include <gtest/gtest.h>

#include <array>

#include "fieldbus/ethercat/frame.hpp"

namespace cnc::ethercat {
namespace {

const Mac kMac = {0x02, 0, 0, 0, 0, 1};

TEST(EthercatFrame, LayoutOfTwoDatagrams) {
  std::array<uint8_t, kMaxFrame> buf{};
  FrameBuilder fb;
  fb.begin(buf.data(), kMac);
  const uint8_t data[4] = {1, 2, 3, 4};
  ASSERT_TRUE(fb.add(Command::FPWR, 0x42, physical_address(0x1001, 0x0120), 4, data));
  ASSERT_TRUE(fb.add(Command::LRW, 0x43, 0x00010000, 6));
  const std::size_t n = fb.finish();
  EXPECT_EQ(n, kMinFrame);  // 14 + 2 + 16 + 18 = 50, padded
  EXPECT_EQ(buf[0], 0xFF);  // broadcast
  EXPECT_EQ(buf[6], 0x02);
  EXPECT_EQ(buf[12], 0x88);
  EXPECT_EQ(buf[13], 0xA4);
  EXPECT_EQ(get16(buf.data() + 14), (34u) | (1u << 12));  // length 34, type 1
  const uint8_t* d = buf.data() + 16;
  EXPECT_EQ(d[0], 5);     // FPWR
  EXPECT_EQ(d[1], 0x42);  // index
  EXPECT_EQ(get16(d + 2), 0x1001);
  EXPECT_EQ(get16(d + 4), 0x0120);
  EXPECT_EQ(get16(d + 6), 4 | 0x8000);  // length 4, more follows
  EXPECT_EQ(d[10], 1);
  EXPECT_EQ(get16(d + 14), 0);  // WKC
  const uint8_t* e = d + 16;
  EXPECT_EQ(e[0], 12);
  EXPECT_EQ(get32(e + 2), 0x00010000u);
  EXPECT_EQ(get16(e + 6), 6);  // last: no "more" bit

  FrameView v;
  ASSERT_EQ(parse_frame(buf.data(), n, v), ParseResult::Ok);
  ASSERT_EQ(v.count, 2u);
  EXPECT_EQ(v.datagrams[0].command(), Command::FPWR);
  EXPECT_EQ(v.datagrams[0].adp(), 0x1001);
  EXPECT_EQ(v.datagrams[0].ado(), 0x0120);
  EXPECT_TRUE(v.datagrams[0].more());
  EXPECT_EQ(v.datagrams[1].length(), 6);
  EXPECT_FALSE(v.datagrams[1].more());
  v.datagrams[1].add_wkc(3);
  EXPECT_EQ(v.datagrams[1].wkc(), 3);
}

TEST(EthercatFrame, RejectsForeignAndTruncatedFrames) {
  std::array<uint8_t, kMaxFrame> buf{};
  FrameBuilder fb;
  fb.begin(buf.data(), kMac);
  fb.add(Command::BRD, 0, 0, 2);
  const std::size_t n = fb.finish();
  FrameView v;
  EXPECT_EQ(parse_frame(buf.data(), 10, v), ParseResult::TooShort);
  auto copy = buf;
  copy[13] = 0x00;
  EXPECT_EQ(parse_frame(copy.data(), n, v), ParseResult::NotEthercat);
  copy = buf;
  copy[15] = 0x20;  // type 2
  EXPECT_EQ(parse_frame(copy.data(), n, v), ParseResult::BadType);
  copy = buf;
  put16(copy.data() + 16 + 6, 200);  // datagram longer than the frame says
  EXPECT_EQ(parse_frame(copy.data(), n, v), ParseResult::BadLength);
  EXPECT_STREQ(parse_result_text(ParseResult::NotEthercat), "not an EtherCAT frame (EtherType is not 0x88A4)");
}

TEST(EthercatFrame, FullFrameRefusesMoreData) {
  std::array<uint8_t, kMaxFrame> buf{};
  FrameBuilder fb;
  fb.begin(buf.data(), kMac);
  EXPECT_TRUE(fb.add(Command::LRW, 0, 0, 1400));
  EXPECT_FALSE(fb.add(Command::LRW, 0, 0, 200));
  EXPECT_TRUE(fb.add(Command::BRD, 0, 0, 2));
  EXPECT_EQ(fb.datagram_count(), 2u);
  EXPECT_FALSE(fb.add(Command::LRW, 0, 0, 0x800));
}

TEST(EthercatFrame, WorkingCounterRules) {
  EXPECT_EQ(expected_wkc(Command::BRD, 5, 0), 5);
  EXPECT_EQ(expected_wkc(Command::FPWR, 0, 1), 1);
  EXPECT_EQ(expected_wkc(Command::FPRW, 1, 1), 3);
  EXPECT_EQ(expected_wkc(Command::LRW, 3, 3), 9);  // three drives with inputs and outputs
  EXPECT_EQ(expected_wkc(Command::LRD, 3, 0), 3);
  EXPECT_EQ(expected_wkc(Command::FRMW, 1, 2), 3);
  EXPECT_EQ(auto_increment_address(0), 0);
  EXPECT_EQ(auto_increment_address(2), 0xFFFE);
  EXPECT_STREQ(command_name(Command::ARMW), "ARMW");
}

TEST(EthercatProtocol, AlStatusCodesAsText) {
  EXPECT_STREQ(al_status_text(0x001B), "sync manager watchdog");
  EXPECT_STREQ(al_status_text(0x0016), "invalid mailbox configuration (PREOP)");
  EXPECT_STREQ(al_status_text(0x8001), "vendor-specific error");
  EXPECT_STREQ(al_status_text(0x00AB), "unknown AL status code");
  EXPECT_STREQ(al_state_name(0x14), "SAFEOP");
  EXPECT_STREQ(mailbox_error_text(2), "unsupported protocol");
}

TEST(EthercatProtocol, SmAndFmmuEntriesRoundTrip) {
  uint8_t b[16];
  SmEntry{0x1000, 128, 0x26, 0x08, 1, 0}.encode(b);
  const SmEntry s = SmEntry::decode(b);
  EXPECT_EQ(s.start, 0x1000);
  EXPECT_TRUE(s.is_mailbox());
  EXPECT_TRUE(s.master_writes());
  EXPECT_TRUE(s.enabled());
  FmmuEntry f;
  f.logical_start = 0x12345;
  f.length = 9;
  f.physical_start = 0x1180;
  f.type = 1;
  f.activate = 1;
  f.encode(b);
  EXPECT_EQ(get32(b), 0x12345u);
  EXPECT_EQ(b[7], 7);
  const FmmuEntry g = FmmuEntry::decode(b);
  EXPECT_EQ(g.physical_start, 0x1180);
  EXPECT_EQ(g.type, 1);
}

}  // namespace
}  // namespace cnc::ethercat
