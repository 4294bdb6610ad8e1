// The slave information interface (SII) EEPROM image (ETG.2010): parsing
// what a master needs (identity, mailbox, general, FMMU, SM, PDO categories,
// strings) and building an image (simulated slaves, tests). Non-realtime.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace cnc::ethercat {

namespace sii_category {
inline constexpr uint16_t kStrings = 10;
inline constexpr uint16_t kGeneral = 30;
inline constexpr uint16_t kFmmu = 40;
inline constexpr uint16_t kSyncManager = 41;
inline constexpr uint16_t kTxPdo = 50;
inline constexpr uint16_t kRxPdo = 51;
inline constexpr uint16_t kDc = 60;
inline constexpr uint16_t kEnd = 0xFFFF;
}  // namespace sii_category

struct SiiPdoEntry {
  uint16_t index = 0;
  uint8_t sub = 0;
  uint8_t bits = 0;
  uint8_t data_type = 0;
  std::string name;
};
struct SiiPdo {
  uint16_t index = 0;
  uint8_t sm = 0;
  std::string name;
  std::vector<SiiPdoEntry> entries;
  unsigned bits() const noexcept {
    unsigned b = 0;
    for (const auto& e : entries) b += e.bits;
    return b;
  }
};
struct SiiSm {
  uint16_t start = 0, length = 0;
  uint8_t control = 0, enable = 0;
  uint8_t type = 0;  // 1 mailbox out, 2 mailbox in, 3 outputs, 4 inputs
};

struct SiiInfo {
  uint16_t alias = 0;
  uint32_t vendor_id = 0, product_code = 0, revision = 0, serial = 0;
  uint16_t mailbox_rx_offset = 0, mailbox_rx_size = 0, mailbox_tx_offset = 0, mailbox_tx_size = 0;
  uint16_t mailbox_protocols = 0;  // bit 2 CoE
  bool checksum_ok = false;
  std::vector<std::string> strings;  // SII string index i is strings[i - 1]
  std::string name, order, group;
  uint8_t coe_details = 0;           // bit 0 SDO, 1 SDO info, 2 PDO assign, 3 PDO config, 5 complete access
  std::vector<uint8_t> fmmus;        // 1 outputs, 2 inputs, 3 mailbox status
  std::vector<SiiSm> sms;
  std::vector<SiiPdo> tx_pdos, rx_pdos;
  bool has_dc_category = false;

  bool has_coe() const noexcept { return (mailbox_protocols & 0x04) != 0; }
  std::string string(uint8_t index) const { return index == 0 || index > strings.size() ? "" : strings[index - 1]; }
};

// Parses an image (bytes, little-endian words). Throws std::runtime_error
// naming the word address of a malformed category.
SiiInfo parse_sii(const std::vector<uint8_t>& image);
// Byte length of the image up to and including the end marker, from the
// bytes read so far; 0 while more are needed to know.
std::size_t sii_length_known(const std::vector<uint8_t>& partial);

// Builds an image from `info` (strings are collected from the names).
std::vector<uint8_t> build_sii(const SiiInfo& info);

}  // namespace cnc::ethercat
