#include "fieldbus/ethercat/frame.hpp"

#include <cstring>

namespace cnc::ethercat {

void FrameBuilder::begin(uint8_t* buffer, const Mac& source) noexcept {
  buf_ = buffer;
  std::memset(buf_, 0xFF, 6);  // broadcast
  std::memcpy(buf_ + 6, source, 6);
  buf_[12] = static_cast<uint8_t>(kEtherType >> 8);
  buf_[13] = static_cast<uint8_t>(kEtherType & 0xFF);
  pos_ = kEthHeader + kEcatHeader;
  count_ = 0;
  last_ = 0;
}

std::size_t FrameBuilder::room() const noexcept {
  const std::size_t used = pos_ + kDatagramHeader + kWkcSize;
  return used >= kMaxFrame ? 0 : kMaxFrame - used;
}

DatagramRef FrameBuilder::add(Command c, uint8_t index, uint32_t address, uint16_t length, const void* data) noexcept {
  if (!buf_ || length > 0x7FF || length > room()) return DatagramRef{};
  uint8_t* h = buf_ + pos_;
  h[0] = static_cast<uint8_t>(c);
  h[1] = index;
  put32(h + 2, address);
  put16(h + 6, length);
  put16(h + 8, 0);
  if (data) std::memcpy(h + kDatagramHeader, data, length);
  else std::memset(h + kDatagramHeader, 0, length);
  put16(h + kDatagramHeader + length, 0);
  if (count_ > 0) {
    uint8_t* prev = buf_ + last_;
    put16(prev + 6, static_cast<uint16_t>(get16(prev + 6) | 0x8000));
  }
  last_ = pos_;
  pos_ += kDatagramHeader + length + kWkcSize;
  ++count_;
  return DatagramRef(h);
}

std::size_t FrameBuilder::finish() noexcept {
  const std::size_t ecat_len = pos_ - kEthHeader - kEcatHeader;
  put16(buf_ + kEthHeader, static_cast<uint16_t>((ecat_len & 0x07FF) | (1u << 12)));
  std::size_t n = pos_;
  if (n < kMinFrame) {
    std::memset(buf_ + n, 0, kMinFrame - n);
    n = kMinFrame;
  }
  return n;
}

const char* parse_result_text(ParseResult r) noexcept {
  switch (r) {
    case ParseResult::Ok: return "ok";
    case ParseResult::TooShort: return "frame too short";
    case ParseResult::NotEthercat: return "not an EtherCAT frame (EtherType is not 0x88A4)";
    case ParseResult::BadType: return "EtherCAT header type is not 1 (datagrams)";
    case ParseResult::BadLength: return "datagram lengths do not fit the frame";
  }
  return "?";
}

ParseResult parse_frame(uint8_t* frame, std::size_t size, FrameView& out) noexcept {
  out.count = 0;
  if (size < kEthHeader + kEcatHeader) return ParseResult::TooShort;
  if (frame[12] != (kEtherType >> 8) || frame[13] != (kEtherType & 0xFF)) return ParseResult::NotEthercat;
  const uint16_t eh = get16(frame + kEthHeader);
  if ((eh >> 12) != 1) return ParseResult::BadType;
  const std::size_t ecat_len = eh & 0x07FF;
  if (kEthHeader + kEcatHeader + ecat_len > size) return ParseResult::BadLength;
  std::size_t pos = kEthHeader + kEcatHeader;
  const std::size_t end = pos + ecat_len;
  while (pos < end) {
    if (pos + kDatagramHeader + kWkcSize > end) return ParseResult::BadLength;
    DatagramRef d(frame + pos);
    if (pos + d.total_size() > end) return ParseResult::BadLength;
    if (out.count == FrameView::kMaxDatagrams) return ParseResult::BadLength;
    out.datagrams[out.count++] = d;
    pos += d.total_size();
    if (!d.more()) break;
  }
  return out.count > 0 ? ParseResult::Ok : ParseResult::BadLength;
}

uint16_t expected_wkc(Command c, unsigned readers, unsigned writers) noexcept {
  switch (c) {
    case Command::APRD: case Command::FPRD: case Command::BRD: case Command::LRD:
      return static_cast<uint16_t>(readers);
    case Command::APWR: case Command::FPWR: case Command::BWR: case Command::LWR:
      return static_cast<uint16_t>(writers);
    case Command::APRW: case Command::FPRW: case Command::BRW: case Command::LRW:
      return static_cast<uint16_t>(readers + 2 * writers);
    case Command::ARMW: case Command::FRMW:
      return static_cast<uint16_t>(readers + writers);
    case Command::NOP: return 0;
  }
  return 0;
}

}  // namespace cnc::ethercat
