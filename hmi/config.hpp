// What the operator screen reads from the machine's INI file: the [DISPLAY]
// keys of the developer manual's chapter 6 (title, icon, cycle time, jog
// increments and speeds, override limits, file paths, machine type, user
// dialogs, embedded tabs), [FILTER], [MDI_COMMAND_LIST], the POSTGUI keys of
// [HAL], and the axes, joints and limits the screen draws. Plain C++ (no
// Qt); never talks to the controller.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "hmi/probing.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::hmi {

// One jog increment: continuous, or a distance in machine units (linear) or
// degrees (angular). `label` is what the INI said ("0.1 inch").
struct Increment {
  bool continuous = false;
  double distance = 0;
  std::string label;
  bool operator==(const Increment&) const = default;
};

// [FILTER]PROGRAM_EXTENSION = .ngc,.nc Description
struct ProgramFilter {
  std::string description;
  std::vector<std::string> extensions;  // lower case, without the dot
};

// [FILTER]<ext> = program: the program gets the file as its argument and
// prints G-code on stdout.
struct FilterProgram {
  std::string extension;  // lower case, without the dot
  std::string program;
};

// [MDI_COMMAND_LIST]MDI_COMMAND_MACRO<n> = G-code;G-code, Label\nText
struct Macro {
  int index = 0;
  std::string commands;  // before the first comma; ';' separates lines
  std::string label;     // after the first comma (line breaks kept); the commands when absent
};

// [DISPLAY]EMBED_TAB_NAME / EMBED_TAB_COMMAND / EMBED_TAB_LOCATION.
struct EmbedTab {
  std::string name;
  std::string command;   // "{XID}" is replaced by the native window id to embed into
  std::string location;  // where the tab goes ("" or a known name: see docs/hmi.md)
};

struct AxisConfig {
  int index = 0;  // 0..8 = X Y Z A B C U V W
  char letter = 'X';
  bool angular = false;
  double min_limit = -1e9, max_limit = 1e9;
  double max_velocity = 0;  // units/s, 0: unknown
};

struct JointConfig {
  int index = 0;
  bool angular = false;
  int axis = -1;  // from the kinematics' coordinates, -1 unknown (the status says at run time)
  double min_limit = -1e9, max_limit = 1e9;
  bool has_home_sequence = false;
  int home_sequence = 0;
};

struct HmiConfig {
  std::filesystem::path ini_path;
  std::string machine;          // [EMC]MACHINE
  std::string title;            // [DISPLAY]TITLE, else the machine name
  std::filesystem::path icon;   // [DISPLAY]ICON, empty: none
  int cycle_time_ms = 100;      // [DISPLAY]CYCLE_TIME (seconds below 1, else milliseconds)

  bool lathe = false;           // MACHINE_TYPE_HINT = LATHE, or LATHE = 1
  bool back_tool_lathe = false; // BACK_TOOL_LATHE = 1
  bool foam = false;            // MACHINE_TYPE_HINT = FOAM (drawn as a mill)

  bool machine_inch = false;        // [TRAJ]LINEAR_UNITS
  double machine_units_per_mm = 1;  // 1/25.4 for inch machines
  std::vector<AxisConfig> axes;     // in XYZABCUVW order
  std::vector<JointConfig> joints;

  std::vector<Increment> increments;          // first is always continuous
  std::vector<Increment> angular_increments;  // first is always continuous
  // Jog speeds in machine units (degrees) per second.
  double default_linear_velocity = 0, min_linear_velocity = 0, max_linear_velocity = 0;
  double default_angular_velocity = 0, min_angular_velocity = 0, max_angular_velocity = 0;
  double trajectory_max_velocity = 0;  // [TRAJ]MAX_LINEAR_VELOCITY, units/s

  // Overrides as ratios (1.0 = 100 %).
  double max_feed_override = 1.2;
  double max_rapid_override = 1.0;
  double min_spindle_override = 0.5, max_spindle_override = 1.2;

  // Spindle manual controls ([DISPLAY] or [SPINDLE_0]).
  double default_spindle_speed = 500, spindle_increment = 100, max_spindle_speed = 0;

  bool position_feedback_actual = false;  // POSITION_FEEDBACK = ACTUAL
  bool position_offset_machine = false;   // POSITION_OFFSET = MACHINE: machine position shown large
  int dro_decimals_mm = 3, dro_decimals_inch = 4;  // DRO_FORMAT_MM / DRO_FORMAT_IN ("%9.3f")
  int64_t graphical_max_file_size = 20 * 1024 * 1024;  // bytes (the key is in MB)

  std::filesystem::path mdi_history_file;
  std::filesystem::path log_file;        // empty: no log file
  std::filesystem::path program_prefix;  // where the file dialog opens
  std::filesystem::path open_file;       // opened at start-up, empty: none
  std::filesystem::path tool_table;      // [EMCIO]TOOL_TABLE
  std::filesystem::path parameter_file;  // [RS274NGC]PARAMETER_FILE
  bool random_toolchanger = false;

  std::vector<ProgramFilter> program_filters;
  std::vector<FilterProgram> filter_programs;
  std::vector<Macro> macros;
  std::vector<EmbedTab> embed_tabs;
  std::vector<std::filesystem::path> postgui_halfiles;
  std::vector<std::string> postgui_halcmds;

  probing::Settings probe;  // [PROBE]

  // What the reader could not use, for the screen's log (file:line: ...).
  std::vector<std::string> warnings;

  // Throws ConfigError for keys that exist but cannot be read at all.
  static HmiConfig from_ini(const ini::IniFile& ini);

  const AxisConfig* axis(int index) const noexcept;
  // Decimals of a DRO in the given units.
  int dro_decimals(bool inch) const noexcept { return inch ? dro_decimals_inch : dro_decimals_mm; }
  // The filter program for a file name, or null.
  const FilterProgram* filter_for(const std::string& file_name) const;
};

// INCREMENTS / ANGULAR_INCREMENTS: "continuous, 10 mm, 1.0 mm, 0.1 inch,
// 1/8 inch, 0.5" (comma- or blank-separated; a number without a unit is in
// machine units, or degrees). "continuous" is always first, added when the
// INI leaves it out. Entries that cannot be read go to `warnings`.
std::vector<Increment> parse_increments(std::string_view text, double machine_units_per_mm, bool angular,
                                        std::vector<std::string>& warnings);

// An override limit: "1.2" is a ratio, "120" or "120%" a percentage (values
// above 10 are read as percent: see docs/hmi.md). Returns the ratio.
double parse_override_limit(std::string_view text, bool& ok);

// A jog velocity: bare numbers are machine units per second (as
// ini-config.adoc and the shipped configurations); "1200/min" or
// "1200 per minute" is per minute, "20/s" per second. Returns units/s.
double parse_jog_velocity(std::string_view text, bool& ok);

// "%9.3f" -> 3; -1 when the text has no precision.
int parse_dro_format(std::string_view text);

}  // namespace cnc::hmi
