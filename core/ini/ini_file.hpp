// LinuxCNC-style INI files: sections, repeated keys that keep their order,
// `#`/`;` comment lines, `\` continuation, `#INCLUDE`, typed getters whose
// errors name the file, the line and the key. Loaded once at start-up; never
// used from the servo thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/util/error.hpp"

namespace cnc::ini {

// One `KEY = value` line, with where it came from (after #INCLUDE).
struct Entry {
  std::string section;
  std::string key;
  std::string value;
  std::string file;
  int line = 0;
};

struct Range {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
};

class IniFile {
 public:
  IniFile() = default;

  // Reads a file (and what it includes); throws ConfigError.
  static IniFile load(const std::filesystem::path& path);
  // Parses text; `filename` is used in messages and to resolve #INCLUDE.
  static IniFile parse(std::string_view text, const std::string& filename = "<string>");

  const std::filesystem::path& path() const noexcept { return path_; }
  // Folder of the main file: relative paths in values are resolved from it.
  std::filesystem::path directory() const;
  std::filesystem::path resolve_path(std::string_view value) const;

  // First occurrence of a key (LinuxCNC semantics for scalar keys).
  std::optional<std::string> find(std::string_view section, std::string_view key) const;
  const Entry* find_entry(std::string_view section, std::string_view key) const;
  // Every occurrence, in file order (HALFILE, PROGRAM_EXTENSION, ...).
  std::vector<std::string> find_all(std::string_view section, std::string_view key) const;
  std::vector<const Entry*> find_all_entries(std::string_view section, std::string_view key) const;

  bool has_section(std::string_view section) const;
  std::vector<std::string> sections() const;
  std::vector<const Entry*> section_entries(std::string_view section) const;
  const std::vector<Entry>& entries() const noexcept { return entries_; }

  // Typed getters: a missing key yields the default; a present key that does
  // not parse or is out of range throws ConfigError naming file, line and key.
  std::string get_string(std::string_view section, std::string_view key, std::string_view def) const;
  double get_double(std::string_view section, std::string_view key, double def, Range range = {}) const;
  int64_t get_int(std::string_view section, std::string_view key, int64_t def, Range range = {}) const;
  bool get_bool(std::string_view section, std::string_view key, bool def) const;
  // Required forms: a missing key throws "missing, expected ...".
  std::string require_string(std::string_view section, std::string_view key) const;
  double require_double(std::string_view section, std::string_view key, Range range = {}) const;
  int64_t require_int(std::string_view section, std::string_view key, Range range = {}) const;

  // Throws a ConfigError pointing at an entry (or at the file when null).
  [[noreturn]] void fail(const Entry* at, const std::string& what) const;

  // Adds or replaces (first occurrence) a value; used by tests and tools.
  void set(std::string_view section, std::string_view key, std::string_view value);

 private:
  void parse_into(std::string_view text, const std::string& filename, int depth);

  std::filesystem::path path_;
  std::vector<Entry> entries_;
  std::vector<std::string> section_order_;
};

// "[SECTION]KEY" for messages.
std::string key_name(std::string_view section, std::string_view key);

}  // namespace cnc::ini
