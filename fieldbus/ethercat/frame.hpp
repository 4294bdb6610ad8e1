// EtherCAT frames and datagrams: building a frame into a caller's buffer and
// walking the datagrams of a received one in place. Ethernet header with
// EtherType 0x88A4, the 2-byte EtherCAT header, datagrams of 10-byte header
// + data + working counter, padding to the 60-byte minimum. No allocation:
// usable in the servo thread.
#pragma once

#include <cstddef>
#include <cstdint>

#include "fieldbus/ethercat/protocol.hpp"

namespace cnc::ethercat {

using Mac = uint8_t[6];

// One datagram inside a frame buffer (a view: changes write through).
class DatagramRef {
 public:
  DatagramRef() = default;
  explicit DatagramRef(uint8_t* header) : h_(header) {}

  Command command() const noexcept { return static_cast<Command>(h_[0]); }
  uint8_t index() const noexcept { return h_[1]; }
  uint32_t address() const noexcept { return get32(h_ + 2); }
  uint16_t adp() const noexcept { return get16(h_ + 2); }
  uint16_t ado() const noexcept { return get16(h_ + 4); }
  void set_adp(uint16_t v) noexcept { put16(h_ + 2, v); }
  uint16_t length() const noexcept { return get16(h_ + 6) & 0x07FF; }
  bool circulated() const noexcept { return (get16(h_ + 6) & 0x4000) != 0; }
  bool more() const noexcept { return (get16(h_ + 6) & 0x8000) != 0; }
  uint16_t irq() const noexcept { return get16(h_ + 8); }
  uint8_t* data() const noexcept { return h_ + kDatagramHeader; }
  uint16_t wkc() const noexcept { return get16(data() + length()); }
  void set_wkc(uint16_t v) noexcept { put16(data() + length(), v); }
  void add_wkc(uint16_t v) noexcept { set_wkc(static_cast<uint16_t>(wkc() + v)); }
  std::size_t total_size() const noexcept { return kDatagramHeader + length() + kWkcSize; }
  explicit operator bool() const noexcept { return h_ != nullptr; }

 private:
  uint8_t* h_ = nullptr;
};

// Builds one frame. The buffer must hold kMaxFrame bytes.
class FrameBuilder {
 public:
  void begin(uint8_t* buffer, const Mac& source) noexcept;
  // Appends a datagram; data is copied when given, else zero-filled.
  // Returns the datagram, or an empty ref when the frame is full.
  DatagramRef add(Command c, uint8_t index, uint32_t address, uint16_t length, const void* data = nullptr) noexcept;
  // Sets the EtherCAT length, the "more" flags and the padding; returns
  // the frame's length in bytes.
  std::size_t finish() noexcept;
  std::size_t datagram_count() const noexcept { return count_; }
  std::size_t room() const noexcept;  // data bytes one more datagram could carry

 private:
  uint8_t* buf_ = nullptr;
  std::size_t pos_ = 0;
  std::size_t count_ = 0;
  std::size_t last_ = 0;  // offset of the last datagram header
};

// Walks the datagrams of a received frame in place.
enum class ParseResult : uint8_t { Ok, TooShort, NotEthercat, BadType, BadLength };
const char* parse_result_text(ParseResult r) noexcept;

struct FrameView {
  static constexpr std::size_t kMaxDatagrams = 32;
  DatagramRef datagrams[kMaxDatagrams];
  std::size_t count = 0;
};
ParseResult parse_frame(uint8_t* frame, std::size_t size, FrameView& out) noexcept;

// Working counter a datagram should come back with when `readers` slaves
// read and `writers` slaves wrote (reference §2).
uint16_t expected_wkc(Command c, unsigned readers, unsigned writers) noexcept;

}  // namespace cnc::ethercat
