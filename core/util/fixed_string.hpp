// Fixed-capacity, always NUL-terminated string for messages that cross the
// servo thread or shared memory. Formatting never allocates.
#pragma once

#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <string_view>

namespace cnc {

template <std::size_t N>
struct FixedString {
  char data[N] = {};

  FixedString() = default;
  FixedString(std::string_view s) noexcept { assign(s); }  // NOLINT: implicit by design

  void assign(std::string_view s) noexcept {
    const std::size_t n = s.size() < N - 1 ? s.size() : N - 1;
    if (n > 0) std::memcpy(data, s.data(), n);  // an empty view may have no data() at all
    data[n] = '\0';
  }
  __attribute__((format(printf, 2, 3))) void format(const char* fmt, ...) noexcept {
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(data, N, fmt, ap);
    va_end(ap);
  }
  const char* c_str() const noexcept { return data; }
  std::string_view view() const noexcept { return std::string_view(data, ::strnlen(data, N)); }
  bool empty() const noexcept { return data[0] == '\0'; }
  static constexpr std::size_t capacity() noexcept { return N - 1; }
};

}  // namespace cnc
