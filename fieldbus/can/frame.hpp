// One CAN frame type for every transport: classic CAN now, with room for
// CAN FD (64 data bytes, FD flags). Trivially copyable, so frames cross
// lock-free queues and the servo thread by value without allocating.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <initializer_list>

namespace cnc::can {

inline constexpr std::size_t kClassicMaxData = 8;
inline constexpr std::size_t kFdMaxData = 64;
inline constexpr uint32_t kStandardIdMask = 0x7FF;
inline constexpr uint32_t kExtendedIdMask = 0x1FFFFFFF;

// Frame::flags bits.
enum FrameFlag : uint8_t {
  kExtended = 0x01,  // 29-bit identifier
  kRemote = 0x02,    // remote transmission request (classic only)
  kError = 0x04,     // an error report (Linux error-frame layout, see error_frame.hpp)
  kFd = 0x08,        // CAN FD frame
  kBitRateSwitch = 0x10,
  kErrorStateIndicator = 0x20,
};

struct Frame {
  uint32_t id = 0;            // identifier (11 or 29 bits); error class bits for kError frames
  uint8_t len = 0;            // data bytes: 0-8 classic; 0-8,12,16,20,24,32,48,64 FD
  uint8_t flags = 0;          // FrameFlag bits
  uint16_t reserved = 0;
  int64_t timestamp_ns = 0;   // CLOCK_MONOTONIC: end of reception (0 when unknown)
  std::array<uint8_t, kFdMaxData> data{};

  bool is_extended() const noexcept { return (flags & kExtended) != 0; }
  bool is_remote() const noexcept { return (flags & kRemote) != 0; }
  bool is_error() const noexcept { return (flags & kError) != 0; }
  bool is_fd() const noexcept { return (flags & kFd) != 0; }

  // A classic data frame with a standard identifier.
  static Frame make(uint32_t id, std::initializer_list<uint8_t> bytes) noexcept {
    Frame f;
    f.id = id & kStandardIdMask;
    for (uint8_t b : bytes) {
      if (f.len == kClassicMaxData) break;
      f.data[f.len++] = b;
    }
    return f;
  }
  static Frame make(uint32_t id, const uint8_t* bytes, std::size_t n) noexcept {
    Frame f;
    f.id = id & kStandardIdMask;
    f.len = static_cast<uint8_t>(n < kClassicMaxData ? n : kClassicMaxData);
    if (f.len) std::memcpy(f.data.data(), bytes, f.len);
    return f;
  }
  static Frame remote(uint32_t id, uint8_t dlc = 0) noexcept {
    Frame f;
    f.id = id & kStandardIdMask;
    f.flags = kRemote;
    f.len = dlc > kClassicMaxData ? kClassicMaxData : dlc;
    return f;
  }
};

// Valid length for the frame kind (classic 0-8; FD one of the DLC steps).
bool is_valid_length(const Frame& f) noexcept;
// CAN FD data-length code from a byte count, rounding up (0-15).
uint8_t fd_len_to_dlc(std::size_t len) noexcept;
std::size_t fd_dlc_to_len(uint8_t dlc) noexcept;

// Same identifier, kind and payload (timestamps are ignored).
bool same_content(const Frame& a, const Frame& b) noexcept;

// "0x181 [6] 27 02 10 00 00 00" style text for logs and test messages.
// Writes at most `size` bytes including the terminator; returns `buf`.
char* format(const Frame& f, char* buf, std::size_t size) noexcept;

}  // namespace cnc::can
