// Runs a program the way LinuxCNC's `rs274 -g` does (init, ON_RESET, the
// program, two ON_RESETs at the end) with the rs274-format TextCanon. Shared
// by the cnc-rs274 tool and the golden tests.
#pragma once

#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"

namespace cnc::interp {

struct Rs274Options {
  std::filesystem::path program;
  std::filesystem::path tool_table;      // empty: no tools
  std::filesystem::path parameter_file;  // empty: no persistence
  std::filesystem::path ini;             // empty: none
  bool block_delete = false;
  bool random_toolchanger = false;
  Units machine_units = Units::Inch;  // rs274's saicanon works in inches
  std::string axes = "XYZABC";         // rs274's saicanon axes
  // Errors as LinuxCNC's rs274 prints them (message, then the block) when
  // true; otherwise "file:line: message", then the block.
  bool rs274_error_format = true;
  // rs274 -n: after an error 0 goes on with the next line (leaving any
  // subroutine in progress), 1 reads MDI lines from `mdi_in` until "quit"
  // and then asks whether to go on, 2 stops (default).
  int on_error = 2;
  std::FILE* mdi_in = nullptr;
  // rs274 -s: print the subroutine call stack after an error message.
  bool print_stack = false;
  // rs274 -T: run as in the task controller (#<_task> reads 1).
  bool task = false;
  // rs274 -p: the interpreter plugin. LinuxCNC's canon interpreter
  // "canterp.so" (any directory) selects the built-in canon replay
  // (canon_replay.hpp): `program` is a file of canonical calls. Empty: the
  // RS274/NGC interpreter. Others: refused (run_rs274 throws).
  std::string plugin;
  // Makes the embedded-script host (the tool passes make_python_host): from
  // the INI (null when none) and a function that writes out what the text
  // canon buffered. Empty: no scripts.
  std::function<std::shared_ptr<ScriptHost>(const cnc::ini::IniFile* ini, std::function<void()> flush)> make_script;
};

// True when `plugin` (an rs274 -p argument) names LinuxCNC's canterp.
bool is_canon_replay_plugin(const std::string& plugin);

// Writes the canonical calls to `out` (may be null). On an interpreter
// error (with on_error 2, or an error in an MDI answer) returns false and sets `error` to "message\nline text" as rs274
// prints it (or "file:line: message\nline text"), and writes that text to `err_out` when not null (before the
// closing calls, as rs274 does). Throws for unreadable tool table / INI.
bool run_rs274(const Rs274Options& options, std::FILE* out, std::string& error, std::FILE* err_out = nullptr);

}  // namespace cnc::interp
