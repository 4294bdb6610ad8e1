#include "core/daemon/ini_check.hpp"

#include <algorithm>
#include <map>

#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::daemon {
namespace {

// Section families the controller reads: LinuxCNC's own and the fieldbus,
// drive and simulator families of this controller (docs/configuration.md).
// A section of these families that no loaded component read is reported.
constexpr const char* kControllerFamilies[] = {
    "EMC",    "TASK",         "RS274NGC", "EMCMOT",       "HAL",       "TRAJ",           "KINS",
    "EMCIO",  "AXIS",         "JOINT",    "SPINDLE",      "CANOPEN",   "CANOPEN_NODE",   "CIA402",
    "CIA402_DRIVE", "CIA402_SIM", "CIA402_SIM_NODE", "ETHERCAT", "ETHERCAT_SLAVE", "MODBUS", "MODBUS_VFD",
    "MODBUS_IO",
};

constexpr const char* kScreenSections[] = {"DISPLAY", "FILTER", "MDI_COMMAND_LIST"};

// Keys of the controller's sections that the operator screen reads
// (docs/hmi.md); LinuxCNC runs them from its screen as well.
constexpr IgnoredKey kScreenKeys[] = {{"HAL", "POSTGUI_HALFILE"}, {"HAL", "POSTGUI_HALCMD"}};

// Keys of the controller read only when they are used, possibly after
// start-up (a `loadusr` typed into halcmd): the record cannot show them
// read, so they are never reported.
constexpr IgnoredKey kRunTimeKeys[] = {{"HAL", "LOADUSR_PATH"}};

bool is_digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

bool contains(const auto& list, std::string_view name) {
  return std::any_of(std::begin(list), std::end(list), [&](const char* s) { return name == s; });
}

bool is_controller_family(std::string_view family) { return contains(kControllerFamilies, family); }

// "ARC_BLEND_*" matches every key starting with ARC_BLEND_; "*" any key.
bool key_matches(std::string_view pattern, std::string_view key) {
  if (!pattern.empty() && pattern.back() == '*') return key.substr(0, pattern.size() - 1) == pattern.substr(0, pattern.size() - 1);
  return pattern == key;
}

bool listed(const auto& list, std::string_view family, std::string_view key) {
  return std::any_of(std::begin(list), std::end(list),
                     [&](const IgnoredKey& k) { return family == k.family && key_matches(k.key, key); });
}

// "[JOINT_n]" for messages about a family.
std::string family_label(std::string_view family, std::string_view example) {
  if (family == "AXIS") return "[AXIS_L]";
  if (family == example) return "[" + std::string(family) + "]";
  return "[" + std::string(family) + "_n]";
}

IniIssue issue(IniIssue::Kind kind, const ini::Entry& at, std::string text) {
  return IniIssue{kind, at.file, at.line, std::move(text)};
}

}  // namespace

std::string IniIssue::where_and_what() const {
  return file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + text;
}

std::string section_family(std::string_view section) {
  const auto parts = split(section, '_');
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (is_digits(parts[i])) continue;
    // The axis letter of [AXIS_X].
    if (i == parts.size() - 1 && parts[i].size() == 1 && !out.empty() && out == "AXIS") continue;
    if (!out.empty()) out += '_';
    out += parts[i];
  }
  return out;
}

bool is_screen_section(std::string_view section) { return contains(kScreenSections, section); }

const std::vector<IgnoredKey>& ignored_linuxcnc_keys() {
  static const std::vector<IgnoredKey> keys = {
      {"EMC", "VERSION"},
      {"EMC", "DEBUG"},
      {"EMC", "NML_FILE"},
      {"TASK", "TASK"},
      {"RS274NGC", "FEATURES"},
      {"RS274NGC", "HAL_PIN_VARS"},
      {"RS274NGC", "INI_VARS"},
      {"RS274NGC", "LOG_LEVEL"},
      {"RS274NGC", "USER_DEFINED_FUNCTION_MAX_DIRS"},
      {"EMCMOT", "EMCMOT"},
      {"EMCMOT", "BASE_PERIOD"},
      {"EMCMOT", "TRAJ_PERIOD"},
      {"HAL", "TWOPASS"},
      {"TRAJ", "ARC_BLEND_*"},
      {"TRAJ", "DEFAULT_LINEAR_ACCELERATION"},
      {"TRAJ", "DEFAULT_ANGULAR_VELOCITY"},
      {"TRAJ", "DEFAULT_ANGULAR_ACCELERATION"},
      {"TRAJ", "MAX_ANGULAR_ACCELERATION"},
      {"TRAJ", "POSITION_FILE"},
      {"TRAJ", "HOME"},
      {"AXIS", "OFFSET_AV_RATIO"},
      {"AXIS", "LOCKING_INDEXER_JOINT"},
      {"JOINT", "HOME_INDEX_NO_ENCODER_RESET"},
      {"SPINDLE", "HOME_SEARCH_VELOCITY"},
      {"SPINDLE", "HOME_SEQUENCE"},
      {"EMCIO", "EMCIO"},
      {"EMCIO", "CYCLE_TIME"},
      {"EMCIO", "TOOL_CHANGE_AT_G30"},
      {"EMCIO", "DB_PROGRAM"},
      {"HALUI", "*"},
      {"APPLICATIONS", "*"},
      {"PYTHON", "LOG_LEVEL"},
  };
  return keys;
}

void check_section_names(const ini::IniFile& ini) {
  for (const std::string& s : ini.sections()) {
    const std::string upper = to_upper(s);
    if (upper == s) continue;
    const std::string family = section_family(upper);
    if (!is_controller_family(family) && !is_screen_section(upper) && !listed(ignored_linuxcnc_keys(), family, "*")) {
      continue;  // a section of the user's own, such as [probe]
    }
    const ini::Entry* h = ini.section_header(s);
    throw ConfigError(h ? h->file : ini.path().string(), h ? h->line : 0,
                      "[" + s + "]: section names are case-sensitive; this controller (as LinuxCNC) reads [" + upper +
                          "], so every key in [" + s + "] would be ignored. Write [" + upper + "]");
  }
}

std::vector<IniIssue> find_unread_keys(const ini::IniFile& ini) {
  // Keys asked for per family ("JOINT": the union over every [JOINT_n]),
  // and which sections asked for a key: the candidates for suggestions.
  std::map<std::string, std::vector<std::string>> family_keys;
  const std::vector<std::string> asked_sections = ini.sections_asked();
  for (const std::string& s : asked_sections) {
    auto& keys = family_keys[section_family(s)];
    for (std::string& k : ini.keys_asked(s)) {
      if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(std::move(k));
    }
  }
  const auto unread = ini.unread_entries();
  std::vector<IniIssue> out;
  std::vector<std::string> reported_sections;
  for (const ini::Entry* e : unread) {
    const std::string& s = e->section;
    if (is_screen_section(s)) continue;
    const std::string family = section_family(s);
    if (listed(kScreenKeys, family, e->key) || listed(kRunTimeKeys, family, e->key)) continue;
    const std::string name = ini::key_name(s, e->key);
    if (listed(ignored_linuxcnc_keys(), family, e->key)) {
      out.push_back(issue(IniIssue::Kind::Ignored, *e, name + ": a LinuxCNC key this controller does not use"));
      continue;
    }
    if (!ini.section_asked(s)) {
      // One report per section: the whole section has no effect.
      if (std::find(reported_sections.begin(), reported_sections.end(), s) != reported_sections.end()) continue;
      reported_sections.push_back(s);
      const ini::Entry* h = ini.section_header(s);
      const ini::Entry& at = h ? *h : *e;
      if (is_controller_family(family)) {
        out.push_back(issue(IniIssue::Kind::UnusedSection, at,
                            "[" + s + "]: no loaded component reads this section; none of its keys has an effect (is "
                            "its component loaded, and JOINTS, NODE or DRIVE right?)"));
      } else if (const auto near = ini::nearest_name(s, asked_sections)) {
        out.push_back(issue(IniIssue::Kind::UnusedSection, at,
                            "[" + s + "]: no loaded component reads this section; did you mean [" + *near + "]?"));
      }
      // Otherwise a section of the user's own (read by a HAL file's
      // [SECTION]KEY at run time, or by another program): left alone.
      continue;
    }
    // A repeated scalar key: the first occurrence is the one used.
    const ini::Entry* first = nullptr;
    for (const ini::Entry& o : ini.entries()) {
      if (&o == e) break;
      if (o.section == s && o.key == e->key) {
        first = &o;
        break;
      }
    }
    if (first) {
      out.push_back(issue(IniIssue::Kind::Unused, *e,
                          name + ": repeated; only the first occurrence (" + first->file + ":" +
                              std::to_string(first->line) + ") is used"));
      continue;
    }
    const auto& known = family_keys[family];
    if (std::find(known.begin(), known.end(), e->key) != known.end()) {
      out.push_back(issue(IniIssue::Kind::Unused, *e,
                          name + ": not used in this configuration (read for other " + family_label(family, s) +
                              " sections; see docs/configuration.md for when it applies)"));
      continue;
    }
    if (const auto near = ini::nearest_name(e->key, known)) {
      out.push_back(issue(IniIssue::Kind::Unknown, *e,
                          name + ": unknown key, ignored; did you mean " + ini::key_name(s, *near) + "?"));
      continue;
    }
    // The right key in the wrong section: the first section that reads it.
    std::string home;
    for (const std::string& other : asked_sections) {
      const auto keys = ini.keys_asked(other);
      if (std::find(keys.begin(), keys.end(), e->key) != keys.end()) {
        home = other;
        break;
      }
    }
    out.push_back(issue(IniIssue::Kind::Unknown, *e,
                        home.empty() ? name + ": unknown key, ignored (no part of this controller reads it)"
                                     : name + ": unknown key here, ignored; " + ini::key_name(home, e->key) +
                                           " is where it is read"));
  }
  return out;
}

}  // namespace cnc::daemon
