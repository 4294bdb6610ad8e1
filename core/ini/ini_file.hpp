// LinuxCNC-style INI files: sections, repeated keys that keep their order,
// `#`/`;` comment lines, `\` continuation, `#INCLUDE`, typed getters whose
// errors name the file, the line and the key. Loaded once at start-up; never
// used from the servo thread. Optionally records which keys were looked up,
// so that the controller can report the keys nobody reads (misspelt or in
// the wrong section) after start-up.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <set>
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
  // Where a section's header first appears (file, line); null when absent
  // or created by set(). The entry's key and value are empty.
  const Entry* section_header(std::string_view section) const;
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

  // Read tracking. While on, every lookup (find*, the typed getters,
  // section_entries) records the section and key asked for, present or
  // not, and marks the entries it returns as read. Off by default; the
  // daemon turns it on after loading and off again after its start-up
  // check, before any other thread can read the file (the records are
  // not synchronised).
  void record_reads(bool on) noexcept { recording_ = on; }
  // Entries no lookup returned while recording was on, in file order.
  std::vector<const Entry*> unread_entries() const;
  // Keys asked for in a section, present or not, sorted.
  std::vector<std::string> keys_asked(std::string_view section) const;
  // Sections at least one key was asked for, or whose entries were listed.
  bool section_asked(std::string_view section) const;
  // Every such section, present in the file or not, sorted.
  std::vector<std::string> sections_asked() const;

 private:
  void parse_into(std::string_view text, const std::string& filename, int depth);
  void note(std::string_view section, std::string_view key) const;
  void mark(const Entry& e) const;

  std::filesystem::path path_;
  std::vector<Entry> entries_;
  std::vector<std::string> section_order_;
  std::vector<Entry> section_headers_;  // first header of each section, in file order
  bool recording_ = false;
  mutable std::vector<bool> read_;  // parallel to entries_
  mutable std::set<std::pair<std::string, std::string>> asked_;  // (section, key); key "" = listed
};

// Edit distance between two names, ignoring case (optimal string alignment:
// insertions, deletions, substitutions and swaps of neighbours cost 1).
std::size_t name_distance(std::string_view a, std::string_view b);
// The candidate closest to `name` (case ignored) if it is close enough to be
// a likely misspelling: at most 1 edit for names up to 4 characters, 2 up to
// 8, 3 beyond; otherwise the shortest candidate that contains `name` or is
// contained in it (5 characters or more). None when nothing is close.
std::optional<std::string> nearest_name(std::string_view name, const std::vector<std::string>& candidates);

// "[SECTION]KEY" for messages.
std::string key_name(std::string_view section, std::string_view key);

}  // namespace cnc::ini
