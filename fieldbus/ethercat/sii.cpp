#include "fieldbus/ethercat/sii.hpp"

#include <stdexcept>

#include "fieldbus/ethercat/protocol.hpp"

namespace cnc::ethercat {
namespace {

constexpr std::size_t kCategoriesStart = 0x40 * 2;

std::string hex_word(std::size_t byte) {
  char b[32];
  std::snprintf(b, sizeof b, "0x%04zx", byte / 2);
  return b;
}

void parse_pdos(const uint8_t* p, std::size_t n, std::vector<SiiPdo>& out, const SiiInfo& info, std::size_t at) {
  std::size_t i = 0;
  while (i + 8 <= n) {
    SiiPdo pdo;
    pdo.index = get16(p + i);
    const uint8_t count = p[i + 2];
    pdo.sm = p[i + 3];
    pdo.name = info.string(p[i + 5]);
    i += 8;
    if (i + 8u * count > n) throw std::runtime_error("SII PDO category at word " + hex_word(at) + ": entries overrun");
    for (uint8_t k = 0; k < count; ++k, i += 8) {
      SiiPdoEntry e;
      e.index = get16(p + i);
      e.sub = p[i + 2];
      e.name = info.string(p[i + 3]);
      e.data_type = p[i + 4];
      e.bits = p[i + 5];
      pdo.entries.push_back(e);
    }
    out.push_back(std::move(pdo));
  }
}

}  // namespace

std::size_t sii_length_known(const std::vector<uint8_t>& partial) {
  std::size_t pos = kCategoriesStart;
  while (pos + 2 <= partial.size()) {
    const uint16_t type = get16(partial.data() + pos);
    if (type == sii_category::kEnd) return pos + 2;
    if (pos + 4 > partial.size()) break;
    pos += 4 + 2 * std::size_t{get16(partial.data() + pos + 2)};
  }
  return 0;
}

SiiInfo parse_sii(const std::vector<uint8_t>& img) {
  if (img.size() < kCategoriesStart) throw std::runtime_error("SII image too short (" + std::to_string(img.size()) + " bytes)");
  SiiInfo info;
  const uint8_t* w = img.data();
  info.checksum_ok = sii_crc8(w, 14) == w[14];
  info.alias = get16(w + 8);
  info.vendor_id = get32(w + 0x10);
  info.product_code = get32(w + 0x14);
  info.revision = get32(w + 0x18);
  info.serial = get32(w + 0x1C);
  info.mailbox_rx_offset = get16(w + 0x30);
  info.mailbox_rx_size = get16(w + 0x32);
  info.mailbox_tx_offset = get16(w + 0x34);
  info.mailbox_tx_size = get16(w + 0x36);
  info.mailbox_protocols = get16(w + 0x38);
  // Strings first (other categories refer to them), then the rest.
  for (int pass = 0; pass < 2; ++pass) {
    std::size_t pos = kCategoriesStart;
    for (;;) {
      if (pos + 2 > img.size()) throw std::runtime_error("SII image ends at word " + hex_word(pos) + " without an end marker");
      const uint16_t type = get16(w + pos);
      if (type == sii_category::kEnd) break;
      if (pos + 4 > img.size()) throw std::runtime_error("SII category header at word " + hex_word(pos) + " truncated");
      const std::size_t size = 2 * std::size_t{get16(w + pos + 2)};
      const uint8_t* p = w + pos + 4;
      if (pos + 4 + size > img.size()) {
        throw std::runtime_error("SII category " + std::to_string(type) + " at word " + hex_word(pos) + " overruns the image");
      }
      if (pass == 0 && type == sii_category::kStrings && size >= 1) {
        std::size_t i = 1;
        for (uint8_t k = 0; k < p[0]; ++k) {
          if (i >= size || i + 1 + p[i] > size) throw std::runtime_error("SII strings at word " + hex_word(pos) + " overrun");
          info.strings.emplace_back(reinterpret_cast<const char*>(p + i + 1), p[i]);
          i += 1 + p[i];
        }
      } else if (pass == 1) {
        switch (type) {
          case sii_category::kGeneral:
            if (size >= 6) {
              info.group = info.string(p[0]);
              info.order = info.string(p[2]);
              info.name = info.string(p[3]);
              info.coe_details = p[5];
            }
            break;
          case sii_category::kFmmu: info.fmmus.assign(p, p + size); break;
          case sii_category::kSyncManager:
            for (std::size_t i = 0; i + 8 <= size; i += 8) {
              info.sms.push_back(SiiSm{get16(p + i), get16(p + i + 2), p[i + 4], p[i + 6], p[i + 7]});
            }
            break;
          case sii_category::kTxPdo: parse_pdos(p, size, info.tx_pdos, info, pos); break;
          case sii_category::kRxPdo: parse_pdos(p, size, info.rx_pdos, info, pos); break;
          case sii_category::kDc: info.has_dc_category = true; break;
          default: break;
        }
      }
      pos += 4 + size;
    }
  }
  return info;
}

std::vector<uint8_t> build_sii(const SiiInfo& info) {
  std::vector<uint8_t> img(kCategoriesStart, 0);
  uint8_t* w = img.data();
  put16(w + 8, info.alias);
  w[14] = sii_crc8(w, 14);
  put32(w + 0x10, info.vendor_id);
  put32(w + 0x14, info.product_code);
  put32(w + 0x18, info.revision);
  put32(w + 0x1C, info.serial);
  put16(w + 0x30, info.mailbox_rx_offset);
  put16(w + 0x32, info.mailbox_rx_size);
  put16(w + 0x34, info.mailbox_tx_offset);
  put16(w + 0x36, info.mailbox_tx_size);
  put16(w + 0x38, info.mailbox_protocols);
  put16(w + 0x7C, 1);  // EEPROM size: 2 kbit... (n + 1) kbit
  put16(w + 0x7E, 1);  // version
  w[14] = sii_crc8(w, 14);

  std::vector<std::string> strings;
  auto str = [&](const std::string& s) -> uint8_t {
    if (s.empty()) return 0;
    for (std::size_t i = 0; i < strings.size(); ++i) {
      if (strings[i] == s) return static_cast<uint8_t>(i + 1);
    }
    strings.push_back(s.substr(0, 255));
    return static_cast<uint8_t>(strings.size());
  };
  std::vector<uint8_t> general(32, 0);
  general[0] = str(info.group);
  general[2] = str(info.order);
  general[3] = str(info.name);
  general[5] = info.coe_details;
  auto pdo_bytes = [&](const std::vector<SiiPdo>& pdos) {
    std::vector<uint8_t> b;
    for (const SiiPdo& p : pdos) {
      uint8_t h[8] = {};
      put16(h, p.index);
      h[2] = static_cast<uint8_t>(p.entries.size());
      h[3] = p.sm;
      h[5] = str(p.name);
      b.insert(b.end(), h, h + 8);
      for (const SiiPdoEntry& e : p.entries) {
        uint8_t x[8] = {};
        put16(x, e.index);
        x[2] = e.sub;
        x[3] = str(e.name);
        x[4] = e.data_type;
        x[5] = e.bits;
        b.insert(b.end(), x, x + 8);
      }
    }
    return b;
  };
  const std::vector<uint8_t> tx = pdo_bytes(info.tx_pdos), rx = pdo_bytes(info.rx_pdos);
  std::vector<uint8_t> sms;
  for (const SiiSm& s : info.sms) {
    uint8_t x[8] = {};
    put16(x, s.start);
    put16(x + 2, s.length);
    x[4] = s.control;
    x[6] = s.enable;
    x[7] = s.type;
    sms.insert(sms.end(), x, x + 8);
  }
  std::vector<uint8_t> text{static_cast<uint8_t>(strings.size())};
  for (const std::string& s : strings) {
    text.push_back(static_cast<uint8_t>(s.size()));
    text.insert(text.end(), s.begin(), s.end());
  }
  auto category = [&](uint16_t type, std::vector<uint8_t> data) {
    if (data.size() % 2) data.push_back(0);
    uint8_t h[4];
    put16(h, type);
    put16(h + 2, static_cast<uint16_t>(data.size() / 2));
    img.insert(img.end(), h, h + 4);
    img.insert(img.end(), data.begin(), data.end());
  };
  category(sii_category::kStrings, text);
  category(sii_category::kGeneral, general);
  if (!info.fmmus.empty()) category(sii_category::kFmmu, info.fmmus);
  if (!sms.empty()) category(sii_category::kSyncManager, sms);
  if (!tx.empty()) category(sii_category::kTxPdo, tx);
  if (!rx.empty()) category(sii_category::kRxPdo, rx);
  if (info.has_dc_category) category(sii_category::kDc, std::vector<uint8_t>(24, 0));
  img.push_back(0xFF);
  img.push_back(0xFF);
  return img;
}

}  // namespace cnc::ethercat
