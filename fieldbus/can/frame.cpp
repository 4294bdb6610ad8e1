#include "fieldbus/can/frame.hpp"

#include <cstdio>

namespace cnc::can {
namespace {
constexpr std::array<uint8_t, 16> kFdLengths = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
}

bool is_valid_length(const Frame& f) noexcept {
  if (!f.is_fd()) return f.len <= kClassicMaxData;
  for (uint8_t n : kFdLengths) {
    if (n == f.len) return true;
  }
  return false;
}

uint8_t fd_len_to_dlc(std::size_t len) noexcept {
  for (uint8_t dlc = 0; dlc < kFdLengths.size(); ++dlc) {
    if (kFdLengths[dlc] >= len) return dlc;
  }
  return 15;
}

std::size_t fd_dlc_to_len(uint8_t dlc) noexcept { return kFdLengths[dlc & 0x0F]; }

bool same_content(const Frame& a, const Frame& b) noexcept {
  if (a.id != b.id || a.len != b.len || a.flags != b.flags) return false;
  if (a.is_remote()) return true;
  return std::memcmp(a.data.data(), b.data.data(), a.len) == 0;
}

char* format(const Frame& f, char* buf, std::size_t size) noexcept {
  if (size == 0) return buf;
  int n = std::snprintf(buf, size, f.is_extended() ? "0x%08X" : "0x%03X", static_cast<unsigned>(f.id));
  auto put = [&](const char* fmt, unsigned v) {
    if (n < 0 || static_cast<std::size_t>(n) >= size) return;
    n += std::snprintf(buf + n, size - static_cast<std::size_t>(n), fmt, v);
  };
  if (f.is_error()) put(" ERROR", 0);
  if (f.is_fd()) put(" FD", 0);
  if (f.is_remote()) {
    put(" RTR [%u]", f.len);
    return buf;
  }
  put(" [%u]", f.len);
  for (std::size_t i = 0; i < f.len; ++i) put(" %02X", f.data[i]);
  return buf;
}

}  // namespace cnc::can
