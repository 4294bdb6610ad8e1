#include "core/util/strings.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>

namespace cnc {

std::string_view trim(std::string_view s) noexcept {
  const auto is_blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string> split(std::string_view s, char sep, bool skip_empty) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t pos = s.find(sep, start);
    const std::string_view part = s.substr(start, pos == std::string_view::npos ? std::string_view::npos : pos - start);
    if (!(skip_empty && part.empty())) out.emplace_back(part);
    if (pos == std::string_view::npos) break;
    start = pos + 1;
  }
  return out;
}

std::vector<NumberedLine> continued_lines(std::string_view text) {
  const auto lines = split(text, '\n');
  std::vector<NumberedLine> out;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    NumberedLine l{static_cast<int>(i) + 1, lines[i]};
    auto trim_end = [](std::string& t) {
      while (!t.empty() && (t.back() == '\r' || t.back() == ' ')) t.pop_back();
    };
    trim_end(l.text);
    while (!l.text.empty() && l.text.back() == '\\' && i + 1 < lines.size()) {
      l.text.pop_back();
      l.text += " " + lines[++i];
      trim_end(l.text);
    }
    out.push_back(std::move(l));
  }
  return out;
}

std::vector<std::string> split_blanks(std::string_view s) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.emplace_back(s.substr(start, i - start));
  }
  return out;
}

bool iequals(std::string_view a, std::string_view b) noexcept {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(a[i])) != std::tolower(static_cast<unsigned char>(b[i]))) return false;
  }
  return true;
}

bool starts_with_icase(std::string_view s, std::string_view prefix) noexcept {
  return s.size() >= prefix.size() && iequals(s.substr(0, prefix.size()), prefix);
}

std::string to_upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

std::string to_lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::optional<double> parse_double(std::string_view s) noexcept {
  s = trim(s);
  if (s.empty()) return std::nullopt;
  if (s.front() == '+') s.remove_prefix(1);
  double v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

namespace {
template <class Int>
std::optional<Int> parse_integer(std::string_view s) noexcept {
  s = trim(s);
  bool negative = false;
  if (!s.empty() && (s.front() == '+' || s.front() == '-')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  int base = 10;
  if (s.size() > 2 && s[0] == '0') {
    const char p = static_cast<char>(std::tolower(static_cast<unsigned char>(s[1])));
    if (p == 'x') base = 16;
    if (p == 'o') base = 8;
    if (p == 'b') base = 2;
    if (base != 10) s.remove_prefix(2);
  }
  if (s.empty()) return std::nullopt;
  uint64_t mag = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), mag, base);
  if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
  if constexpr (std::is_signed_v<Int>) {
    if (negative) {
      if (mag > static_cast<uint64_t>(INT64_MAX) + 1) return std::nullopt;
      return static_cast<Int>(-static_cast<int64_t>(mag - 1) - 1);
    }
    if (mag > static_cast<uint64_t>(INT64_MAX)) return std::nullopt;
    return static_cast<Int>(mag);
  } else {
    if (negative && mag != 0) return std::nullopt;
    return static_cast<Int>(mag);
  }
}
}  // namespace

std::optional<int64_t> parse_int(std::string_view s) noexcept { return parse_integer<int64_t>(s); }
std::optional<uint64_t> parse_uint(std::string_view s) noexcept { return parse_integer<uint64_t>(s); }

std::optional<bool> parse_bool(std::string_view s) noexcept {
  s = trim(s);
  if (iequals(s, "true") || iequals(s, "yes") || iequals(s, "on") || s == "1") return true;
  if (iequals(s, "false") || iequals(s, "no") || iequals(s, "off") || s == "0") return false;
  return std::nullopt;
}

std::string format_double(double v) {
  char buf[40];
  if (v == std::floor(v) && std::fabs(v) < 1e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return v == 0 && std::signbit(v) ? "-0" : buf;
  }
  for (int prec = 6; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

}  // namespace cnc
