// SII EEPROM images: build, parse, checksum, categories, malformed images.
#include <gtest/gtest.h>

#include "fieldbus/ethercat/protocol.hpp"
#include "fieldbus/ethercat/sii.hpp"

namespace cnc::ethercat {
namespace {

SiiInfo sample() {
  SiiInfo s;
  s.alias = 7;
  s.vendor_id = 0x00000CC1;
  s.product_code = 0x402;
  s.revision = 3;
  s.serial = 99;
  s.mailbox_rx_offset = 0x1800;
  s.mailbox_rx_size = 256;
  s.mailbox_tx_offset = 0x1C00;
  s.mailbox_tx_size = 256;
  s.mailbox_protocols = 0x000C;  // CoE + FoE
  s.name = "Servo X";
  s.order = "SX-100";
  s.group = "Drives";
  s.coe_details = 0x2F;
  s.fmmus = {1, 2, 3};
  s.sms = {{0x1800, 256, 0x26, 1, 1}, {0x1C00, 256, 0x22, 1, 2}, {0x1100, 0, 0x64, 1, 3}, {0x1400, 0, 0x20, 1, 4}};
  SiiPdo rx;
  rx.index = 0x1600;
  rx.sm = 2;
  rx.name = "Outputs";
  rx.entries = {{0x6040, 0, 16, 6, "Controlword"}, {0x607A, 0, 32, 4, "Target position"}};
  s.rx_pdos = {rx};
  SiiPdo tx;
  tx.index = 0x1A00;
  tx.sm = 3;
  tx.entries = {{0x6041, 0, 16, 6, "Statusword"}};
  s.tx_pdos = {tx};
  return s;
}

TEST(EthercatSii, RoundTripKeepsEverythingAMasterNeeds) {
  const std::vector<uint8_t> img = build_sii(sample());
  EXPECT_EQ(sii_length_known(img), img.size());
  const SiiInfo p = parse_sii(img);
  EXPECT_TRUE(p.checksum_ok);
  EXPECT_EQ(p.alias, 7);
  EXPECT_EQ(p.vendor_id, 0x00000CC1u);
  EXPECT_EQ(p.product_code, 0x402u);
  EXPECT_EQ(p.serial, 99u);
  EXPECT_EQ(p.mailbox_rx_offset, 0x1800);
  EXPECT_EQ(p.mailbox_tx_size, 256);
  EXPECT_TRUE(p.has_coe());
  EXPECT_EQ(p.name, "Servo X");
  EXPECT_EQ(p.order, "SX-100");
  EXPECT_EQ(p.group, "Drives");
  EXPECT_EQ(p.coe_details, 0x2F);
  ASSERT_GE(p.fmmus.size(), 3u);  // padded to whole words
  EXPECT_EQ(std::vector<uint8_t>(p.fmmus.begin(), p.fmmus.begin() + 3), (std::vector<uint8_t>{1, 2, 3}));
  ASSERT_EQ(p.sms.size(), 4u);
  EXPECT_EQ(p.sms[2].type, 3);
  EXPECT_EQ(p.sms[2].control, 0x64);
  ASSERT_EQ(p.rx_pdos.size(), 1u);
  EXPECT_EQ(p.rx_pdos[0].index, 0x1600);
  EXPECT_EQ(p.rx_pdos[0].sm, 2);
  EXPECT_EQ(p.rx_pdos[0].name, "Outputs");
  ASSERT_EQ(p.rx_pdos[0].entries.size(), 2u);
  EXPECT_EQ(p.rx_pdos[0].entries[1].index, 0x607A);
  EXPECT_EQ(p.rx_pdos[0].entries[1].bits, 32);
  EXPECT_EQ(p.rx_pdos[0].entries[1].name, "Target position");
  EXPECT_EQ(p.rx_pdos[0].bits(), 48u);
  EXPECT_EQ(p.tx_pdos[0].entries[0].name, "Statusword");
  // Word addresses from the reference: vendor ID at word 8, mailbox at 0x18, categories at 0x40.
  EXPECT_EQ(get32(img.data() + 2 * 0x08), 0x00000CC1u);
  EXPECT_EQ(get16(img.data() + 2 * 0x18), 0x1800);
  EXPECT_EQ(get16(img.data() + 2 * 0x40), sii_category::kStrings);
}

TEST(EthercatSii, ChecksumCoversTheConfigurationArea) {
  std::vector<uint8_t> img = build_sii(sample());
  EXPECT_EQ(sii_crc8(img.data(), 14), img[14]);
  img[8] ^= 0x01;  // alias changed, checksum not
  EXPECT_FALSE(parse_sii(img).checksum_ok);
  // A known value: CRC-8 (poly 0x07, init 0xFF) of 14 zero bytes.
  const uint8_t zeros[14] = {};
  uint8_t crc = 0xFF;
  for (int i = 0; i < 14; ++i) {
    for (int b = 0; b < 8; ++b) crc = static_cast<uint8_t>((crc & 0x80) ? (crc << 1) ^ 0x07 : crc << 1);
  }
  EXPECT_EQ(sii_crc8(zeros, 14), crc);
}

TEST(EthercatSii, MalformedImagesNameTheWord) {
  std::vector<uint8_t> img = build_sii(sample());
  std::vector<uint8_t> cut(img.begin(), img.begin() + 0x80 + 6);
  EXPECT_EQ(sii_length_known(cut), 0u);
  try {
    parse_sii(cut);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("at word 0x0040"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_sii(std::vector<uint8_t>(20, 0)), std::runtime_error);
}

}  // namespace
}  // namespace cnc::ethercat
