// Small string helpers shared by the file parsers (INI, HAL, tool table,
// device descriptions). Number parsing is strict: the whole text must be a
// number, or the result is empty.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cnc {

std::string_view trim(std::string_view s) noexcept;
std::vector<std::string> split(std::string_view s, char sep, bool skip_empty = false);
// The logical lines of a HAL file or halcmd input: a trailing backslash
// joins the next line (with a blank); trailing CR and blanks are dropped.
// Each keeps the number (1-based) of its first physical line.
struct NumberedLine {
  int line = 0;
  std::string text;
};
std::vector<NumberedLine> continued_lines(std::string_view text);
// Splits on runs of blanks (space, tab).
std::vector<std::string> split_blanks(std::string_view s);
bool iequals(std::string_view a, std::string_view b) noexcept;
std::string to_upper(std::string_view s);
std::string to_lower(std::string_view s);
bool starts_with_icase(std::string_view s, std::string_view prefix) noexcept;

// Decimal or scientific floating point; "inf"/"nan" are refused.
std::optional<double> parse_double(std::string_view s) noexcept;
// Decimal, or with 0x / 0o / 0b prefix; optional sign.
std::optional<int64_t> parse_int(std::string_view s) noexcept;
std::optional<uint64_t> parse_uint(std::string_view s) noexcept;
// TRUE/YES/ON/1 and FALSE/NO/OFF/0, any case.
std::optional<bool> parse_bool(std::string_view s) noexcept;

// Shortest text that reads back as the same double ("%.17g" trimmed).
std::string format_double(double v);

}  // namespace cnc
