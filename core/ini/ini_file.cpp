#include "core/ini/ini_file.hpp"

#include <algorithm>
#include <cmath>

#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::ini {
namespace {

constexpr int kMaxIncludeDepth = 16;

bool is_name_char(char c, bool first) {
  if (c == '_' || (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z')) return true;
  return !first && c >= '0' && c <= '9';
}

bool is_valid_name(std::string_view s) {
  if (s.empty()) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (!is_name_char(s[i], i == 0)) return false;
  }
  return true;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void append_utf8(std::string& out, uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

// Escapes \t \n \\ \xHH \uHHHH; any other backslash is kept as written.
std::string unescape(std::string_view v) {
  std::string out;
  out.reserve(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] != '\\' || i + 1 >= v.size()) {
      out += v[i];
      continue;
    }
    const char e = v[i + 1];
    if (e == 't') { out += '\t'; ++i; continue; }
    if (e == 'n') { out += '\n'; ++i; continue; }
    if (e == '\\') { out += '\\'; ++i; continue; }
    const std::size_t digits = e == 'x' ? 2 : e == 'u' ? 4 : 0;
    if (digits > 0 && i + 1 + digits < v.size()) {
      uint32_t cp = 0;
      bool ok = true;
      for (std::size_t k = 0; ok && k < digits; ++k) {
        const int h = hex_value(v[i + 2 + k]);
        if (h < 0) ok = false; else cp = cp * 16 + static_cast<uint32_t>(h);
      }
      if (ok) {
        if (e == 'x') out += static_cast<char>(cp); else append_utf8(out, cp);
        i += 1 + digits;
        continue;
      }
    }
    out += v[i];
  }
  return out;
}

// Where a comment after the value starts, or npos. LinuxCNC keeps such a
// comment in the value, so `KEY = 5 # mm` would silently be "5 # mm" (a
// number that does not parse, a file name that does not exist, a name with
// a comment in it); it is refused instead. A comment is a blank followed by
// `;`, or by `#` and then a blank, a letter or the end; G-code parameters
// (`X #1`, `#<_x>`, `#[...]`) stay values.
std::size_t trailing_comment_at(std::string_view v) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    if (v[i - 1] != ' ' && v[i - 1] != '\t') continue;
    if (v[i] == ';') return i;
    if (v[i] != '#') continue;
    const char next = i + 1 < v.size() ? v[i + 1] : ' ';
    if (next == ' ' || next == '\t' || is_name_char(next, true)) return i;
  }
  return std::string_view::npos;
}

}  // namespace

std::string key_name(std::string_view section, std::string_view key) {
  return "[" + std::string(section) + "]" + std::string(key);
}

IniFile IniFile::load(const std::filesystem::path& path) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const FileError& e) {
    throw ConfigError(path.string(), 0, "cannot read INI file: " + e.reason());
  }
  IniFile ini;
  ini.path_ = path;
  ini.parse_into(text, path.string(), 0);
  return ini;
}

IniFile IniFile::parse(std::string_view text, const std::string& filename) {
  IniFile ini;
  ini.path_ = filename;
  ini.parse_into(text, filename, 0);
  return ini;
}

void IniFile::parse_into(std::string_view text, const std::string& filename, int depth) {
  if (depth > kMaxIncludeDepth) throw ConfigError(filename, 0, "#INCLUDE nested deeper than 16 levels (a cycle?)");
  std::string section;
  const auto lines = split(text, '\n');
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const int line_no = static_cast<int>(i) + 1;
    std::string raw = lines[i];
    if (!raw.empty() && raw.back() == '\r') raw.pop_back();
    if (raw.rfind("#INCLUDE", 0) == 0) {
      const std::string target(trim(std::string_view(raw).substr(8)));
      if (target.empty()) throw ConfigError(filename, line_no, "#INCLUDE needs a file name");
      std::filesystem::path inc = target;
      if (!target.empty() && target[0] == '~') {
        const char* home = std::getenv("HOME");
        inc = std::string(home ? home : "") + target.substr(1);
      }
      if (inc.is_relative()) inc = std::filesystem::path(filename).parent_path() / inc;
      std::string inc_text;
      try {
        inc_text = read_file(inc);
      } catch (const FileError& e) {
        throw ConfigError(filename, line_no, "#INCLUDE: cannot read \"" + inc.string() + "\": " + e.reason());
      }
      const std::string saved = section;
      parse_into(inc_text, inc.string(), depth + 1);
      section = saved;
      continue;
    }
    std::string_view line = trim(raw);
    if (line.empty() || line.front() == '#' || line.front() == ';') continue;
    if (line.front() == '[') {
      const std::size_t close = line.find(']');
      if (close == std::string_view::npos) throw ConfigError(filename, line_no, "section header without ']'");
      const std::string_view name = line.substr(1, close - 1);
      if (!is_valid_name(name)) {
        throw ConfigError(filename, line_no, "section name \"" + std::string(name) +
                                                 "\": expected letters, digits and '_', not starting with a digit");
      }
      if (const std::string_view rest = trim(line.substr(close + 1)); !rest.empty()) {
        throw ConfigError(filename, line_no,
                          rest.front() == '#' || rest.front() == ';'
                              ? "a comment after the section header [" + std::string(name) +
                                    "]: put the comment on a line of its own"
                              : "text after section header");
      }
      section = std::string(name);
      if (std::find(section_order_.begin(), section_order_.end(), section) == section_order_.end()) {
        section_order_.push_back(section);
        section_headers_.push_back(Entry{section, "", "", filename, line_no});
      }
      continue;
    }
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos) {
      throw ConfigError(filename, line_no, "expected KEY = value, a [SECTION] header or a comment");
    }
    const std::string key(trim(line.substr(0, eq)));
    if (!is_valid_name(key)) {
      throw ConfigError(filename, line_no,
                        "key \"" + key + "\": expected letters, digits and '_', not starting with a digit");
    }
    if (section.empty()) throw ConfigError(filename, line_no, "key " + key + " before any [SECTION]");
    std::string value(trim(line.substr(eq + 1)));
    // A trailing backslash continues the value on the next line.
    while (!value.empty() && value.back() == '\\' && i + 1 < lines.size()) {
      value.pop_back();
      std::string next = lines[++i];
      if (!next.empty() && next.back() == '\r') next.pop_back();
      value = std::string(trim(value)) + " " + std::string(trim(next));
      value = std::string(trim(value));
    }
    if (const std::size_t at = trailing_comment_at(value); at != std::string_view::npos) {
      throw ConfigError(filename, line_no,
                        key_name(section, key) + ": \"" + value + "\" has a comment after the value (\"" +
                            value.substr(at) + "\"), which LinuxCNC keeps as part of the value: put the comment on a "
                            "line of its own (\\x23 writes a '#' that belongs to the value)");
    }
    entries_.push_back(Entry{section, key, unescape(value), filename, line_no});
  }
}

std::filesystem::path IniFile::directory() const {
  const auto p = path_.parent_path();
  return p.empty() ? std::filesystem::path(".") : p;
}

std::filesystem::path IniFile::resolve_path(std::string_view value) const {
  std::filesystem::path p{std::string(value)};
  if (!value.empty() && value[0] == '~') {
    const char* home = std::getenv("HOME");
    p = std::string(home ? home : "") + std::string(value.substr(1));
  }
  if (p.is_relative()) p = directory() / p;
  return p.lexically_normal();
}

void IniFile::note(std::string_view section, std::string_view key) const {
  if (recording_) asked_.emplace(std::string(section), std::string(key));
}

void IniFile::mark(const Entry& e) const {
  if (!recording_) return;
  if (read_.size() < entries_.size()) read_.resize(entries_.size(), false);
  read_[static_cast<std::size_t>(&e - entries_.data())] = true;
}

const Entry* IniFile::find_entry(std::string_view section, std::string_view key) const {
  note(section, key);
  for (const Entry& e : entries_) {
    if (e.section == section && e.key == key) {
      mark(e);
      return &e;
    }
  }
  return nullptr;
}

std::optional<std::string> IniFile::find(std::string_view section, std::string_view key) const {
  const Entry* e = find_entry(section, key);
  if (!e) return std::nullopt;
  return e->value;
}

std::vector<const Entry*> IniFile::find_all_entries(std::string_view section, std::string_view key) const {
  note(section, key);
  std::vector<const Entry*> out;
  for (const Entry& e : entries_) {
    if (e.section == section && e.key == key) {
      mark(e);
      out.push_back(&e);
    }
  }
  return out;
}

std::vector<std::string> IniFile::find_all(std::string_view section, std::string_view key) const {
  std::vector<std::string> out;
  for (const Entry* e : find_all_entries(section, key)) out.push_back(e->value);
  return out;
}

bool IniFile::has_section(std::string_view section) const {
  return std::find(section_order_.begin(), section_order_.end(), section) != section_order_.end();
}

std::vector<std::string> IniFile::sections() const { return section_order_; }

const Entry* IniFile::section_header(std::string_view section) const {
  for (const Entry& h : section_headers_) {
    if (h.section == section) return &h;
  }
  return nullptr;
}

std::vector<const Entry*> IniFile::section_entries(std::string_view section) const {
  // The caller takes every entry of the section: all count as read.
  note(section, "");
  std::vector<const Entry*> out;
  for (const Entry& e : entries_) {
    if (e.section == section) {
      mark(e);
      out.push_back(&e);
    }
  }
  return out;
}

std::vector<const Entry*> IniFile::unread_entries() const {
  std::vector<const Entry*> out;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (i >= read_.size() || !read_[i]) out.push_back(&entries_[i]);
  }
  return out;
}

std::vector<std::string> IniFile::keys_asked(std::string_view section) const {
  std::vector<std::string> out;
  for (const auto& [s, k] : asked_) {
    if (s == section && !k.empty()) out.push_back(k);
  }
  return out;
}

bool IniFile::section_asked(std::string_view section) const {
  for (const auto& [s, k] : asked_) {
    if (s == section) return true;
  }
  return false;
}

std::vector<std::string> IniFile::sections_asked() const {
  std::vector<std::string> out;
  for (const auto& [s, k] : asked_) {
    if (out.empty() || out.back() != s) out.push_back(s);
  }
  return out;
}

std::size_t name_distance(std::string_view a, std::string_view b) {
  const auto lower = [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; };
  const std::size_t n = a.size(), m = b.size();
  // d[i][j]: distance between the first i characters of a and j of b.
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1, 0));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) && lower(a[i - 2]) == lower(b[j - 1])) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[n][m];
}

std::optional<std::string> nearest_name(std::string_view name, const std::vector<std::string>& candidates) {
  const std::size_t limit = name.size() <= 4 ? 1 : name.size() <= 8 ? 2 : 3;
  std::optional<std::string> best;
  std::size_t best_distance = limit + 1;
  for (const std::string& c : candidates) {
    const std::size_t d = name_distance(name, c);
    if (d < best_distance) {
      best_distance = d;
      best = c;
    }
  }
  if (best) return best;
  const std::string upper_name = to_upper(name);
  for (const std::string& c : candidates) {
    const std::string upper_c = to_upper(c);
    const bool related = upper_name.size() >= 5 && upper_c.size() >= 5 &&
                         (upper_c.find(upper_name) != std::string::npos || upper_name.find(upper_c) != std::string::npos);
    if (related && (!best || c.size() < best->size())) best = c;
  }
  return best;
}

void IniFile::fail(const Entry* at, const std::string& what) const {
  if (at) throw ConfigError(at->file, at->line, key_name(at->section, at->key) + ": " + what);
  throw ConfigError(path_.string(), 0, what);
}

namespace {
std::string range_text(Range r) {
  const bool has_min = std::isfinite(r.min);
  const bool has_max = std::isfinite(r.max);
  if (has_min && has_max) return " between " + format_double(r.min) + " and " + format_double(r.max);
  if (has_min) return " of at least " + format_double(r.min);
  if (has_max) return " of at most " + format_double(r.max);
  return "";
}
}  // namespace

std::string IniFile::get_string(std::string_view section, std::string_view key, std::string_view def) const {
  const Entry* e = find_entry(section, key);
  return e ? e->value : std::string(def);
}

double IniFile::get_double(std::string_view section, std::string_view key, double def, Range range) const {
  const Entry* e = find_entry(section, key);
  if (!e) return def;
  const auto v = parse_double(e->value);
  if (!v || *v < range.min || *v > range.max) {
    fail(e, "expected a number" + range_text(range) + ", got \"" + e->value + "\"");
  }
  return *v;
}

int64_t IniFile::get_int(std::string_view section, std::string_view key, int64_t def, Range range) const {
  const Entry* e = find_entry(section, key);
  if (!e) return def;
  const auto v = parse_int(e->value);
  if (!v || static_cast<double>(*v) < range.min || static_cast<double>(*v) > range.max) {
    fail(e, "expected an integer" + range_text(range) + ", got \"" + e->value + "\"");
  }
  return *v;
}

bool IniFile::get_bool(std::string_view section, std::string_view key, bool def) const {
  const Entry* e = find_entry(section, key);
  if (!e) return def;
  const auto v = parse_bool(e->value);
  if (!v) fail(e, "expected TRUE/YES/ON/1 or FALSE/NO/OFF/0, got \"" + e->value + "\"");
  return *v;
}

std::string IniFile::require_string(std::string_view section, std::string_view key) const {
  const Entry* e = find_entry(section, key);
  if (!e) fail(nullptr, key_name(section, key) + ": missing, expected a value");
  return e->value;
}

double IniFile::require_double(std::string_view section, std::string_view key, Range range) const {
  if (!find_entry(section, key)) fail(nullptr, key_name(section, key) + ": missing, expected a number" + range_text(range));
  return get_double(section, key, 0, range);
}

int64_t IniFile::require_int(std::string_view section, std::string_view key, Range range) const {
  if (!find_entry(section, key)) fail(nullptr, key_name(section, key) + ": missing, expected an integer" + range_text(range));
  return get_int(section, key, 0, range);
}

void IniFile::set(std::string_view section, std::string_view key, std::string_view value) {
  for (Entry& e : entries_) {
    if (e.section == section && e.key == key) {
      e.value = std::string(value);
      return;
    }
  }
  if (!has_section(section)) section_order_.emplace_back(section);
  entries_.push_back(Entry{std::string(section), std::string(key), std::string(value), path_.string(), 0});
}

}  // namespace cnc::ini
