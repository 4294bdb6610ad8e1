#include "comp/comp_table.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::comp {

double CompTable::interpolate(const std::vector<double>& values, double pos) const noexcept {
  const std::size_t n = nominal.size();
  if (n == 0) return 0;
  if (!(pos > nominal.front())) return values.front();  // also NaN: the first entry
  if (pos >= nominal.back()) return values.back();
  // The entry at or below pos, as LinuxCNC's lookup walks to it.
  const auto it = std::upper_bound(nominal.begin(), nominal.end(), pos);
  const std::size_t i = static_cast<std::size_t>(it - nominal.begin()) - 1;
  const double span = nominal[i + 1] - nominal[i];
  return values[i] + (values[i + 1] - values[i]) * ((pos - nominal[i]) / span);
}

double CompTable::at(double pos, int direction) const noexcept {
  if (direction > 0) return forward_at(pos);
  if (direction < 0) return reverse_at(pos);
  return (forward_at(pos) + reverse_at(pos)) / 2;
}

double CompTable::max_abs_trim() const noexcept {
  double m = 0;
  for (std::size_t i = 0; i < size(); ++i) m = std::max({m, std::fabs(forward[i]), std::fabs(reverse[i])});
  return m;
}

double CompTable::max_abs_slope() const noexcept {
  double m = 0;
  for (std::size_t i = 1; i < size(); ++i) {
    const double dx = nominal[i] - nominal[i - 1];
    m = std::max({m, std::fabs(forward[i] - forward[i - 1]) / dx, std::fabs(reverse[i] - reverse[i - 1]) / dx});
  }
  return m;
}

namespace {

std::string_view strip_comment(std::string_view line) {
  const std::size_t c = line.find_first_of("#;");
  return c == std::string_view::npos ? line : line.substr(0, c);
}

// Exactly three numbers; false otherwise.
bool parse_triplet(std::string_view text, double (&v)[3]) {
  const std::vector<std::string> words = split_blanks(text);
  if (words.size() != 3) return false;
  for (int k = 0; k < 3; ++k) {
    const auto d = parse_double(words[static_cast<std::size_t>(k)]);
    if (!d) return false;
    v[k] = *d;
  }
  return true;
}

std::string quote(std::string_view s) {
  std::string t(trim(s));
  if (t.size() > 60) t = t.substr(0, 57) + "...";
  return "'" + t + "'";
}

std::string num(double v) { return format_double(v); }

}  // namespace

CompTable parse_comp_table(std::string_view text, CompFileType type, const std::string& file_name,
                           const CompParseOptions& options) {
  const std::string expected =
      "three numbers 'nominal " +
      std::string(type == CompFileType::Positions ? "forward-position reverse-position" : "forward-trim reverse-trim") +
      "' (COMP_FILE_TYPE " + std::to_string(static_cast<int>(type)) + ")";
  CompTable t;
  int line_no = 0, last_entry_line = 0, end_line = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view body = trim(strip_comment(line));
    if (body.empty()) {
      // A comment or blank line: LinuxCNC's loader stops at it, so it ends
      // the table, and before the first entry it would leave the joint
      // without one.
      if (t.empty()) {
        throw ConfigError(file_name, line_no,
                          "the table must start on the first line: LinuxCNC stops reading a COMP_FILE at the first "
                          "line that is not three numbers, so this " +
                              std::string(trim(line).empty() ? "blank line" : "comment") +
                              " would leave the joint without compensation there; put notes after the table");
      }
      if (end_line == 0) end_line = line_no;
      continue;
    }
    double v[3];
    if (!parse_triplet(body, v)) {
      throw ConfigError(file_name, line_no,
                        "expected " + expected + ", found " + quote(line) +
                            (t.empty() ? std::string()
                                       : "; a line that is not an entry ends the table where LinuxCNC stops reading, "
                                         "so notes after the table must be comments ('#')"));
    }
    if (end_line != 0) {
      throw ConfigError(file_name, line_no,
                        "an entry after the end of the table: line " + std::to_string(end_line) +
                            " is a comment or blank, and LinuxCNC stops reading there; remove that line or move the "
                            "notes after the table");
    }
    const double nominal = v[0];
    const double fwd = type == CompFileType::Positions ? nominal - v[1] : v[1];
    const double rev = type == CompFileType::Positions ? nominal - v[2] : v[2];
    if (!t.empty() && !(nominal > t.nominal.back())) {
      throw ConfigError(file_name, line_no,
                        "nominal " + num(nominal) + " is not greater than the previous one (" + num(t.nominal.back()) +
                            ", line " + std::to_string(last_entry_line) + "): entries must be in ascending order");
    }
    for (const double trim_value : {fwd, rev}) {
      if (!(std::fabs(trim_value) <= options.max_abs_trim)) {
        throw ConfigError(
            file_name, line_no,
            "correction " + num(trim_value) + " at nominal " + num(nominal) + " is larger than " +
                num(options.max_abs_trim) +
                " machine units; is COMP_FILE_TYPE right? (type 0: nominal, position reached moving +, position "
                "reached moving -; type 1: nominal, forward trim, reverse trim)");
      }
    }
    t.nominal.push_back(nominal);
    t.forward.push_back(fwd);
    t.reverse.push_back(rev);
    last_entry_line = line_no;
  }
  if (t.empty()) throw ConfigError(file_name, 0, "no entries (expected lines of " + expected + ")");
  return t;
}

CompTable load_comp_file(const std::filesystem::path& path, CompFileType type, const CompParseOptions& options) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const std::exception& e) {
    throw ConfigError(path.string(), 0, std::string("cannot read the compensation file: ") + e.what());
  }
  return parse_comp_table(text, type, path.string(), options);
}

std::string format_comp_table(const CompTable& table, CompFileType type, const std::vector<std::string>& notes) {
  std::string out;
  // Room for any double in %f (309 digits before the point): a large
  // nominal must not cut the line short.
  char buf[1100];
  // Nominals in micrometres (%.6f), unless a neighbour would then read as
  // the same or a smaller number (two nominals closer than 1e-6, -1e-7
  // next to 0): those two get every digit they need.
  std::vector<std::string> rounded(table.size());
  std::vector<double> rounded_value(table.size());
  for (std::size_t i = 0; i < table.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.6f", table.nominal[i]);
    rounded[i] = buf;
    rounded_value[i] = std::strtod(buf, nullptr);
  }
  for (std::size_t i = 0; i < table.size(); ++i) {
    const double x = table.nominal[i];
    const double a = type == CompFileType::Positions ? x - table.forward[i] : table.forward[i];
    const double b = type == CompFileType::Positions ? x - table.reverse[i] : table.reverse[i];
    const bool exact = (i > 0 && !(rounded_value[i] > rounded_value[i - 1])) ||
                       (i + 1 < table.size() && !(rounded_value[i + 1] > rounded_value[i]));
    const std::string nominal = exact ? format_double(x) : rounded[i];
    std::snprintf(buf, sizeof buf, "%s %.9f %.9f\n", nominal.c_str(), a, b);
    out += buf;
  }
  for (const std::string& n : notes) out += "# " + n + "\n";
  return out;
}

}  // namespace cnc::comp
