#include "hmi/numbers.hpp"

#include <cmath>
#include <cstdio>

#include "core/util/strings.hpp"

namespace cnc::hmi {
namespace {

bool is_digit(char c) noexcept { return c >= '0' && c <= '9'; }

// Checks the shape: [sign] digits [sep digits]; returns the separator
// count and digit count through the out parameters; false on any other
// character.
bool scan(std::string_view s, int& separators, int& digits, char& separator, std::string* why) {
  separators = digits = 0;
  separator = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    if (is_digit(c)) {
      ++digits;
    } else if ((c == '-' || c == '+') && i == 0) {
    } else if (c == '.' || c == ',') {
      if (separators > 0) {
        if (why) *why = c == separator ? "more than one decimal separator" : "both a comma and a point: use only one";
        return false;
      }
      ++separators;
      separator = c;
    } else {
      if (why) *why = std::string("unexpected character '") + c + "'";
      return false;
    }
  }
  return true;
}

}  // namespace

std::optional<double> parse_operator_number(std::string_view text, std::string* why) {
  const std::string_view s = trim(text);
  if (s.empty()) {
    if (why) *why = "empty";
    return std::nullopt;
  }
  int separators = 0, digits = 0;
  char separator = 0;
  if (!scan(s, separators, digits, separator, why)) return std::nullopt;
  if (digits == 0) {
    if (why) *why = "no digits";
    return std::nullopt;
  }
  std::string normal(s);
  for (char& c : normal) {
    if (c == ',') c = '.';
  }
  if (normal.back() == '.') normal += '0';
  if (normal.front() == '.' || ((normal.front() == '-' || normal.front() == '+') && normal[1] == '.')) {
    normal.insert(normal.front() == '.' ? 0 : 1, "0");
  }
  if (normal.front() == '+') normal.erase(0, 1);
  const auto v = parse_double(normal);
  if (!v || !std::isfinite(*v)) {
    if (why) *why = "not a number";
    return std::nullopt;
  }
  return *v;
}

bool is_partial_operator_number(std::string_view text) {
  const std::string_view s = trim(text);
  int separators = 0, digits = 0;
  char separator = 0;
  return scan(s, separators, digits, separator, nullptr);
}

std::string NumberFormat::fixed(double value, int decimals) const {
  char buf[64];
  const double shown = std::fabs(value) < 0.5 * std::pow(10.0, -decimals) ? 0.0 : value;
  std::snprintf(buf, sizeof buf, "%.*f", decimals, shown);
  std::string out(buf);
  if (point_ != '.') {
    for (char& c : out) {
      if (c == '.') c = point_;
    }
  }
  return out;
}

std::string NumberFormat::fixed_width(double value, int decimals, int width) const {
  std::string s = fixed(value, decimals);
  if (static_cast<int>(s.size()) < width) s.insert(0, static_cast<std::size_t>(width) - s.size(), ' ');
  return s;
}

}  // namespace cnc::hmi
