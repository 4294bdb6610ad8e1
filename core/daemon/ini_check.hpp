// The start-up check of the INI file against what the controller read: a
// misspelt key, a key in the wrong section, a repeated scalar key or a
// section no loaded component reads would otherwise be ignored and its
// default used without a word. The IniFile records every lookup while the
// controller starts (ini::IniFile::record_reads); after the HAL files ran,
// on_ready was called and the task controller exists, every entry of a
// section the controller owns that nobody looked up is reported with the
// nearest key that was looked up. docs/configuration.md, "Unknown keys".
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/ini/ini_file.hpp"

namespace cnc::daemon {

struct IniIssue {
  enum class Kind {
    Unknown,        // a key no component asked for: misspelt, wrong section
    Unused,         // a key others of its kind use, not read here; or a repeat
    UnusedSection,  // a controller section no loaded component reads
    Ignored,        // a LinuxCNC key or section this controller does not use
  };
  Kind kind = Kind::Unknown;
  std::string file;
  int line = 0;
  std::string text;  // "[JOINT_0]MAX_VELOCTY: unknown key; did you mean MAX_VELOCITY?"

  // "file:line: text", as the log and the message channel show it.
  std::string where_and_what() const;
  // Ignored keys are information; the others are mistakes (errors with
  // cncd --strict or [EMC]UNKNOWN_KEYS = ERROR).
  bool is_mistake() const noexcept { return kind != Kind::Ignored; }
};

// The family a section belongs to: digits and the axis letter dropped
// ("JOINT_0" -> "JOINT", "CANOPEN_1_NODE_4" -> "CANOPEN_NODE", "AXIS_X" ->
// "AXIS", "CIA402_1_DRIVE_0" -> "CIA402_DRIVE").
std::string section_family(std::string_view section);

// Sections of the operator screen ([DISPLAY], [FILTER], [MDI_COMMAND_LIST]):
// the screen reads them; the controller's check leaves them alone.
bool is_screen_section(std::string_view section);

// Refuses a section spelt like one of the controller's or the screen's in
// another case (`[traj]`): LinuxCNC's names are case-sensitive, so every
// key in it would be ignored. Throws ConfigError at the section's header.
void check_section_names(const ini::IniFile& ini);

// After start-up (read tracking on since loading): every entry of the
// controller's sections that no lookup returned, in file order.
std::vector<IniIssue> find_unread_keys(const ini::IniFile& ini);

// The keys LinuxCNC reads that this controller does not (docs/configuration.md,
// "Keys LinuxCNC reads that are ignored here"), as "FAMILY" and key patterns
// ("ARC_BLEND_*"); a test keeps the page and this list equal.
struct IgnoredKey {
  const char* family;
  const char* key;
};
const std::vector<IgnoredKey>& ignored_linuxcnc_keys();

}  // namespace cnc::daemon
