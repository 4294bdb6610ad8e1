#include "hmi/config.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>

#include "core/ini/ini_file.hpp"
#include "core/util/pose.hpp"
#include "core/util/strings.hpp"

namespace cnc::hmi {
namespace {

constexpr double kMmPerInch = 25.4;

std::string where(const ini::Entry* e) {
  if (!e) return {};
  return e->file + ":" + std::to_string(e->line) + ": [" + e->section + "]" + e->key + ": ";
}

// A length unit word -> millimetres per unit; 0 when unknown.
double unit_mm(std::string_view word) {
  const std::string w = to_lower(word);
  if (w == "mm" || w == "millimeter" || w == "millimeters" || w == "millimetre" || w == "millimetres") return 1.0;
  if (w == "cm") return 10.0;
  if (w == "um" || w == "micron" || w == "microns") return 0.001;
  if (w == "in" || w == "inch" || w == "inches" || w == "\"") return kMmPerInch;
  if (w == "mil" || w == "mils" || w == "thou") return kMmPerInch / 1000.0;
  return 0.0;
}

// "0.5", "1/8", ".25" -> value.
std::optional<double> parse_amount(std::string_view s) {
  const auto slash = s.find('/');
  if (slash != std::string_view::npos) {
    const auto n = parse_double(s.substr(0, slash));
    const auto d = parse_double(s.substr(slash + 1));
    if (!n || !d || *d == 0) return std::nullopt;
    return *n / *d;
  }
  std::string t(s);
  if (!t.empty() && t[0] == '.') t.insert(0, "0");
  return parse_double(t);
}

// Splits "0.1mm" into number and unit; "1/8" stays whole.
void split_number_unit(const std::string& token, std::string& number, std::string& unit) {
  std::size_t i = 0;
  while (i < token.size() && (std::isdigit(static_cast<unsigned char>(token[i])) || token[i] == '.' ||
                              token[i] == '/' || token[i] == '-' || token[i] == '+')) {
    ++i;
  }
  number = token.substr(0, i);
  unit = token.substr(i);
}

double get_number(const ini::IniFile& ini, std::string_view section, std::string_view key, double def,
                  std::vector<std::string>& warnings) {
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) return def;
  const auto v = parse_double(trim(e->value));
  if (!v) {
    warnings.push_back(where(e) + "\"" + e->value + "\" is not a number; using " + format_double(def));
    return def;
  }
  return *v;
}

bool get_flag(const ini::IniFile& ini, std::string_view section, std::string_view key, bool def,
              std::vector<std::string>& warnings) {
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) return def;
  const auto v = parse_bool(trim(e->value));
  if (!v) {
    warnings.push_back(where(e) + "\"" + e->value + "\" is not a boolean (TRUE/FALSE, YES/NO, ON/OFF, 1/0)");
    return def;
  }
  return *v;
}

double get_override(const ini::IniFile& ini, std::string_view key, double def, std::vector<std::string>& warnings) {
  const ini::Entry* e = ini.find_entry("DISPLAY", key);
  if (!e) return def;
  bool ok = false;
  const double v = parse_override_limit(e->value, ok);
  if (!ok) {
    warnings.push_back(where(e) + "\"" + e->value + "\": expected a ratio (1.2) or a percentage (120)");
    return def;
  }
  return v;
}

double get_velocity(const ini::IniFile& ini, std::string_view key, double def, std::vector<std::string>& warnings) {
  const ini::Entry* e = ini.find_entry("DISPLAY", key);
  if (!e) return def;
  bool ok = false;
  const double v = parse_jog_velocity(e->value, ok);
  if (!ok) {
    warnings.push_back(where(e) + "\"" + e->value + "\": expected a velocity (units/s, or \"N/min\")");
    return def;
  }
  return v;
}

std::string coordinates_of(const ini::IniFile& ini) {
  std::string letters;
  if (const auto kins = ini.find("KINS", "KINEMATICS")) {
    for (const auto& w : split_blanks(*kins)) {
      if (starts_with_icase(w, "coordinates=")) letters = to_upper(w.substr(12));
    }
  }
  return letters;
}

}  // namespace

std::vector<Increment> parse_increments(std::string_view text, double machine_units_per_mm, bool angular,
                                        std::vector<std::string>& warnings) {
  std::vector<Increment> out;
  out.push_back(Increment{true, 0, "continuous"});
  // Entries: "number [unit]" separated by commas; without commas, blanks
  // separate the entries and a unit word belongs to the number before it.
  std::vector<std::pair<std::string, std::string>> entries;  // number, unit
  std::vector<std::string> bad;
  const bool commas = text.find(',') != std::string_view::npos;
  const auto is_unit = [&](const std::string& w) {
    return angular ? (iequals(w, "deg") || iequals(w, "degree") || iequals(w, "degrees")) : unit_mm(w) > 0;
  };
  if (commas) {
    for (const auto& group : split(text, ',', true)) {
      const auto words = split_blanks(group);
      if (words.empty()) continue;
      std::string number, unit;
      if (words.size() == 1) split_number_unit(words[0], number, unit);
      else if (words.size() == 2) number = words[0], unit = words[1];
      else number = std::string(trim(group)), unit = "?";
      entries.emplace_back(number, unit);
    }
  } else {
    const auto words = split_blanks(text);
    for (std::size_t i = 0; i < words.size(); ++i) {
      std::string number, unit;
      split_number_unit(words[i], number, unit);
      if (unit.empty() && i + 1 < words.size() && is_unit(words[i + 1])) unit = words[++i];
      entries.emplace_back(number, unit);
    }
  }
  for (const auto& [number, unit] : entries) {
    if (iequals(number + unit, "continuous")) continue;  // already first
    const std::string label = unit.empty() ? number : number + " " + unit;
    const auto amount = number.empty() ? std::nullopt : parse_amount(number);
    if (!amount || *amount <= 0) {
      warnings.push_back("increment \"" + label + "\" is not a positive number with an optional unit");
      continue;
    }
    double distance = *amount;
    if (!unit.empty()) {
      if (!is_unit(unit)) {
        warnings.push_back("increment \"" + label + "\": unknown unit \"" + unit + "\"" +
                           (angular ? " (degrees only)" : " (mm, cm, um, inch, mil)"));
        continue;
      }
      if (!angular) distance = *amount * unit_mm(unit) * machine_units_per_mm;
    }
    const Increment inc{false, distance, label};
    if (std::find(out.begin(), out.end(), inc) == out.end()) out.push_back(inc);
  }
  return out;
}

double parse_override_limit(std::string_view text, bool& ok) {
  std::string t(trim(text));
  bool percent = false;
  if (!t.empty() && t.back() == '%') {
    percent = true;
    t.pop_back();
  }
  const auto v = parse_double(trim(t));
  ok = v && *v >= 0;
  if (!ok) return 0;
  return (percent || *v > 10) ? *v / 100.0 : *v;
}

double parse_jog_velocity(std::string_view text, bool& ok) {
  std::string t = to_lower(trim(text));
  double per = 1.0;
  for (const char* suffix : {"/min", "per minute", "/minute"}) {
    const std::string s(suffix);
    if (t.size() > s.size() && t.compare(t.size() - s.size(), s.size(), s) == 0) {
      per = 60.0;
      t = std::string(trim(t.substr(0, t.size() - s.size())));
    }
  }
  for (const char* suffix : {"/s", "/sec", "per second"}) {
    const std::string s(suffix);
    if (t.size() > s.size() && t.compare(t.size() - s.size(), s.size(), s) == 0) t = std::string(trim(t.substr(0, t.size() - s.size())));
  }
  const auto v = parse_double(t);
  ok = v && *v >= 0;
  return ok ? *v / per : 0;
}

int parse_dro_format(std::string_view text) {
  const auto dot = text.find('.');
  if (dot == std::string_view::npos) return -1;
  int n = 0, digits = 0;
  for (std::size_t i = dot + 1; i < text.size() && std::isdigit(static_cast<unsigned char>(text[i])); ++i, ++digits) {
    n = n * 10 + (text[i] - '0');
  }
  return digits > 0 && n <= 9 ? n : -1;
}

const AxisConfig* HmiConfig::axis(int index) const noexcept {
  for (const auto& a : axes) {
    if (a.index == index) return &a;
  }
  return nullptr;
}

const FilterProgram* HmiConfig::filter_for(const std::string& file_name) const {
  const auto dot = file_name.rfind('.');
  if (dot == std::string::npos) return nullptr;
  const std::string ext = to_lower(file_name.substr(dot + 1));
  for (const auto& f : filter_programs) {
    if (f.extension == ext) return &f;
  }
  return nullptr;
}

HmiConfig HmiConfig::from_ini(const ini::IniFile& ini) {
  HmiConfig c;
  auto& w = c.warnings;
  c.ini_path = ini.path();
  c.machine = ini.get_string("EMC", "MACHINE", "");
  c.title = ini.get_string("DISPLAY", "TITLE", c.machine.empty() ? "CNC" : c.machine);
  if (const auto v = ini.find("DISPLAY", "ICON"); v && !trim(*v).empty()) c.icon = ini.resolve_path(trim(*v));

  if (const ini::Entry* e = ini.find_entry("DISPLAY", "CYCLE_TIME")) {
    const auto v = parse_double(trim(e->value));
    if (!v || *v <= 0) {
      w.push_back(where(e) + "\"" + e->value + "\" is not a positive number; using 100 ms");
    } else {
      const double ms = *v < 1.0 ? *v * 1000.0 : *v;  // 0.1 (seconds) or 100 (milliseconds)
      c.cycle_time_ms = static_cast<int>(std::lround(std::clamp(ms, 20.0, 1000.0)));
      if (ms < 20.0 || ms > 1000.0) w.push_back(where(e) + "limited to " + std::to_string(c.cycle_time_ms) + " ms");
    }
  }

  const std::string hint = to_upper(trim(ini.get_string("DISPLAY", "MACHINE_TYPE_HINT", "")));
  c.lathe = hint == "LATHE" || get_flag(ini, "DISPLAY", "LATHE", false, w);
  c.foam = hint == "FOAM";
  c.back_tool_lathe = get_flag(ini, "DISPLAY", "BACK_TOOL_LATHE", false, w);
  if (c.back_tool_lathe) c.lathe = true;
  if (!hint.empty() && hint != "LATHE" && hint != "FOAM" && hint != "MILL") {
    w.push_back(where(ini.find_entry("DISPLAY", "MACHINE_TYPE_HINT")) + "\"" + hint + "\" unknown (LATHE, FOAM or MILL); a mill is shown");
  }

  const std::string units = to_lower(trim(ini.get_string("TRAJ", "LINEAR_UNITS", "mm")));
  c.machine_inch = units == "inch" || units == "in" || units == "imperial";
  c.machine_units_per_mm = c.machine_inch ? 1.0 / kMmPerInch : 1.0;

  // Axes: [TRAJ]COORDINATES, else the kinematics' coordinates=, else XYZ.
  const std::string kins_letters = coordinates_of(ini);
  std::string letters = to_upper(ini.get_string("TRAJ", "COORDINATES", ""));
  if (letters.find_first_not_of(" \t") == std::string::npos) letters = kins_letters;
  if (letters.find_first_not_of(" \t") == std::string::npos) letters = "XYZ";
  unsigned mask = 0;
  for (char ch : letters) {
    const int a = axis_index(ch);
    if (a >= 0) mask |= 1u << a;
  }
  c.trajectory_max_velocity = get_number(ini, "TRAJ", "MAX_LINEAR_VELOCITY", 0, w);
  for (int a = 0; a < kNumAxes; ++a) {
    if (!(mask & (1u << a))) continue;
    AxisConfig ax;
    ax.index = a;
    ax.letter = kAxisLetters[a];
    ax.angular = a >= 3 && a <= 5;
    const std::string sec = std::string("AXIS_") + ax.letter;
    ax.min_limit = get_number(ini, sec, "MIN_LIMIT", ax.min_limit, w);
    ax.max_limit = get_number(ini, sec, "MAX_LIMIT", ax.max_limit, w);
    ax.max_velocity = get_number(ini, sec, "MAX_VELOCITY", 0, w);
    c.axes.push_back(ax);
  }
  const std::string joint_letters = [&] {
    std::string s;
    for (char ch : kins_letters.empty() ? letters : kins_letters) {
      if (axis_index(ch) >= 0) s += ch;
    }
    return s;
  }();
  const int joints = static_cast<int>(get_number(ini, "KINS", "JOINTS", static_cast<double>(joint_letters.size()), w));
  for (int j = 0; j < std::clamp(joints, 0, kMaxJoints); ++j) {
    JointConfig jc;
    jc.index = j;
    jc.axis = j < static_cast<int>(joint_letters.size()) ? axis_index(joint_letters[static_cast<std::size_t>(j)]) : -1;
    const std::string sec = "JOINT_" + std::to_string(j);
    jc.angular = iequals(trim(ini.get_string(sec, "TYPE", "LINEAR")), "ANGULAR");
    jc.min_limit = get_number(ini, sec, "MIN_LIMIT", jc.min_limit, w);
    jc.max_limit = get_number(ini, sec, "MAX_LIMIT", jc.max_limit, w);
    if (ini.find(sec, "HOME_SEQUENCE")) {
      jc.has_home_sequence = true;
      jc.home_sequence = static_cast<int>(get_number(ini, sec, "HOME_SEQUENCE", 0, w));
    }
    c.joints.push_back(jc);
  }

  const char* default_incr = c.machine_inch ? "continuous, 0.1 inch, 0.01 inch, 0.001 inch" : "continuous, 1 mm, 0.1 mm, 0.01 mm";
  {
    const ini::Entry* e = ini.find_entry("DISPLAY", "INCREMENTS");
    std::vector<std::string> iw;
    c.increments = parse_increments(e ? std::string_view(e->value) : default_incr, c.machine_units_per_mm, false, iw);
    for (auto& m : iw) w.push_back(where(e) + m);
    const ini::Entry* ea = ini.find_entry("DISPLAY", "ANGULAR_INCREMENTS");
    iw.clear();
    c.angular_increments = parse_increments(ea ? std::string_view(ea->value) : "continuous, 10, 1, 0.1", 1.0, true, iw);
    for (auto& m : iw) w.push_back(where(ea) + m);
  }

  // Jog speeds, units per second.
  double fastest_axis = 0;
  for (const auto& a : c.axes) {
    if (!a.angular) fastest_axis = std::max(fastest_axis, a.max_velocity);
  }
  const double machine_max = c.trajectory_max_velocity > 0 ? c.trajectory_max_velocity : fastest_axis > 0 ? fastest_axis : 50.0;
  c.max_linear_velocity = get_velocity(ini, "MAX_LINEAR_VELOCITY", machine_max, w);
  if (c.max_linear_velocity > machine_max * 1.0001) {
    w.push_back(where(ini.find_entry("DISPLAY", "MAX_LINEAR_VELOCITY")) + "above the machine's " + format_double(machine_max) +
                " units/s; limited to it (write \"N/min\" for units per minute)");
    c.max_linear_velocity = machine_max;
  }
  c.min_linear_velocity = get_velocity(ini, "MIN_LINEAR_VELOCITY", c.max_linear_velocity / 100.0, w);
  c.default_linear_velocity = get_velocity(ini, "DEFAULT_LINEAR_VELOCITY", c.max_linear_velocity / 4.0, w);
  c.max_angular_velocity = get_velocity(ini, "MAX_ANGULAR_VELOCITY", 360.0, w);
  c.min_angular_velocity = get_velocity(ini, "MIN_ANGULAR_VELOCITY", c.max_angular_velocity / 100.0, w);
  c.default_angular_velocity = get_velocity(ini, "DEFAULT_ANGULAR_VELOCITY", c.max_angular_velocity / 4.0, w);
  c.min_linear_velocity = std::min(c.min_linear_velocity, c.max_linear_velocity);
  c.default_linear_velocity = std::clamp(c.default_linear_velocity, c.min_linear_velocity, c.max_linear_velocity);
  c.min_angular_velocity = std::min(c.min_angular_velocity, c.max_angular_velocity);
  c.default_angular_velocity = std::clamp(c.default_angular_velocity, c.min_angular_velocity, c.max_angular_velocity);

  c.max_feed_override = get_override(ini, "MAX_FEED_OVERRIDE", 1.2, w);
  c.max_rapid_override = std::min(1.0, get_override(ini, "MAX_RAPID_OVERRIDE", 1.0, w));
  c.min_spindle_override = get_override(ini, "MIN_SPINDLE_0_OVERRIDE", get_override(ini, "MIN_SPINDLE_OVERRIDE", 0.5, w), w);
  c.max_spindle_override = get_override(ini, "MAX_SPINDLE_0_OVERRIDE", get_override(ini, "MAX_SPINDLE_OVERRIDE", 1.2, w), w);
  if (c.min_spindle_override > c.max_spindle_override) {
    w.push_back("[DISPLAY]MIN_SPINDLE_0_OVERRIDE is above MAX_SPINDLE_0_OVERRIDE; using the maximum for both");
    c.min_spindle_override = c.max_spindle_override;
  }

  c.default_spindle_speed = get_number(ini, "DISPLAY", "DEFAULT_SPINDLE_0_SPEED", get_number(ini, "DISPLAY", "DEFAULT_SPINDLE_SPEED", 500, w), w);
  c.spindle_increment = get_number(ini, "SPINDLE_0", "INCREMENT", get_number(ini, "DISPLAY", "SPINDLE_INCREMENT", 100, w), w);
  // [SPINDLE_0]MAX_FORWARD_VELOCITY is motion's: the screen shows the speed
  // motion sends (the status's speed_out), limits applied.
  c.max_spindle_speed = get_number(ini, "DISPLAY", "MAX_SPINDLE_0_SPEED", 0, w);

  c.position_feedback_actual = iequals(trim(ini.get_string("DISPLAY", "POSITION_FEEDBACK", "COMMANDED")), "ACTUAL");
  c.position_offset_machine = iequals(trim(ini.get_string("DISPLAY", "POSITION_OFFSET", "RELATIVE")), "MACHINE");
  for (auto [key, target] : {std::pair{"DRO_FORMAT_MM", &c.dro_decimals_mm}, std::pair{"DRO_FORMAT_IN", &c.dro_decimals_inch}}) {
    if (const ini::Entry* e = ini.find_entry("DISPLAY", key)) {
      const int d = parse_dro_format(e->value);
      if (d < 0) w.push_back(where(e) + "\"" + e->value + "\": expected a printf format such as %9.3f");
      else *target = d;
    }
  }
  const double max_mb = get_number(ini, "DISPLAY", "GRAPHICAL_MAX_FILE_SIZE", 20, w);
  c.graphical_max_file_size = static_cast<int64_t>(std::max(0.0, max_mb) * 1024 * 1024);

  const auto path_key = [&](std::string_view section, std::string_view key, std::string_view def) -> std::filesystem::path {
    const auto v = ini.find(section, key);
    const std::string_view value = v ? trim(*v) : def;
    return value.empty() ? std::filesystem::path() : ini.resolve_path(value);
  };
  c.mdi_history_file = path_key("DISPLAY", "MDI_HISTORY_FILE", "~/.cnc_mdi_history");
  c.log_file = path_key("DISPLAY", "LOG_FILE", "");
  c.program_prefix = path_key("DISPLAY", "PROGRAM_PREFIX", ".");
  c.open_file = path_key("DISPLAY", "OPEN_FILE", "");
  c.tool_table = path_key("EMCIO", "TOOL_TABLE", "");
  c.parameter_file = path_key("RS274NGC", "PARAMETER_FILE", "");
  c.random_toolchanger = get_flag(ini, "EMCIO", "RANDOM_TOOLCHANGER", false, w);

  for (const ini::Entry* e : ini.section_entries("FILTER")) {
    if (e->key == "PROGRAM_EXTENSION") {
      const std::string v(trim(e->value));
      const auto blank = v.find_first_of(" \t");
      ProgramFilter f;
      f.description = blank == std::string::npos ? "" : std::string(trim(v.substr(blank)));
      for (auto ext : split(v.substr(0, blank), ',', true)) {
        ext = std::string(trim(ext));
        while (!ext.empty() && (ext[0] == '.' || ext[0] == '*')) ext.erase(0, 1);
        if (!ext.empty()) f.extensions.push_back(to_lower(ext));
      }
      if (f.extensions.empty()) {
        w.push_back(where(e) + "no extension before the description");
        continue;
      }
      if (f.description.empty()) f.description = "Programs";
      c.program_filters.push_back(f);
    } else {
      std::string ext = to_lower(e->key);
      while (!ext.empty() && ext[0] == '.') ext.erase(0, 1);
      if (!trim(e->value).empty()) c.filter_programs.push_back(FilterProgram{ext, std::string(trim(e->value))});
    }
  }

  for (int i = 0; i < 64; ++i) {
    const auto v = ini.find("MDI_COMMAND_LIST", "MDI_COMMAND_MACRO" + std::to_string(i));
    if (!v) break;
    Macro m;
    m.index = i;
    const auto comma = v->find(',');
    m.commands = std::string(trim(v->substr(0, comma)));
    std::string label = comma == std::string::npos ? m.commands : std::string(trim(v->substr(comma + 1)));
    for (std::size_t p; (p = label.find("\\n")) != std::string::npos;) label.replace(p, 2, "\n");
    m.label = label;
    c.macros.push_back(m);
  }

  for (const ini::Entry* e : ini.section_entries("DISPLAY")) {
    if (e->key == "EMBED_TAB_NAME") {
      c.embed_tabs.push_back(EmbedTab{std::string(trim(e->value)), "", ""});
    } else if (e->key == "EMBED_TAB_COMMAND" || e->key == "EMBED_TAB_LOCATION") {
      if (c.embed_tabs.empty()) {
        w.push_back(where(e) + "comes before any EMBED_TAB_NAME; ignored");
        continue;
      }
      (e->key == "EMBED_TAB_COMMAND" ? c.embed_tabs.back().command : c.embed_tabs.back().location) = std::string(trim(e->value));
    }
  }
  for (auto it = c.embed_tabs.begin(); it != c.embed_tabs.end();) {
    if (it->command.empty()) {
      w.push_back("[DISPLAY]EMBED_TAB_NAME = " + it->name + " has no EMBED_TAB_COMMAND; not shown");
      it = c.embed_tabs.erase(it);
    } else {
      ++it;
    }
  }
  for (const auto& f : ini.find_all("HAL", "POSTGUI_HALFILE")) {
    std::string_view v = trim(f);
    if (starts_with_icase(v, "LIB:")) {
      w.push_back("[HAL]POSTGUI_HALFILE = " + std::string(v) + ": LIB: files are not supported; skipped");
      continue;
    }
    c.postgui_halfiles.push_back(ini.resolve_path(v));
  }
  for (const auto& cmd : ini.find_all("HAL", "POSTGUI_HALCMD")) c.postgui_halcmds.emplace_back(trim(cmd));
  c.probe = probing::Settings::from_ini(ini);
  c.probe.inch = c.machine_inch;  // the routines set G20 or G21 for their numbers
  return c;
}

}  // namespace cnc::hmi
