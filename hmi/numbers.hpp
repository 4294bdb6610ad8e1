// Numbers the operator types and the screen shows (LinuxCNC developer
// manual, chapter 6.2): a comma or a point is accepted as the decimal
// separator, but only one separator and only once; every number on the
// screen is displayed with the same separator. No Qt here: the widgets'
// validator and the tests share this code.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace cnc::hmi {

// Parses "12.5", "12,5", "-0,25", ".5", "7." (blanks around are ignored).
// Refuses "1,5.3", "1.2.3", "1 5", "1e3", "" and anything else, saying why
// in `why` when given.
std::optional<double> parse_operator_number(std::string_view text, std::string* why = nullptr);

// True when `text` could still become a number by typing more ("-", "1,").
bool is_partial_operator_number(std::string_view text);

// Formats numbers with one decimal separator everywhere on the screen.
class NumberFormat {
 public:
  explicit NumberFormat(char decimal_point = '.') : point_(decimal_point == ',' ? ',' : '.') {}
  char decimal_point() const noexcept { return point_; }
  // Fixed decimals; "-0.000" is shown as "0.000".
  std::string fixed(double value, int decimals) const;
  // As fixed, right-aligned in `width` characters.
  std::string fixed_width(double value, int decimals, int width) const;

 private:
  char point_;
};

}  // namespace cnc::hmi
