// Embedded Python for the interpreter (LinuxCNC's [PYTHON] section): O-word
// subroutines written as Python functions and `;py,` statements, with the
// interpreter seen from Python as LinuxCNC 2.9 shows it (a subset, listed in
// docs/interpreter.md, "Embedded Python"):
//
//   module `interpreter`: `this` (the interpreter; also the `self` of every
//     function: attributes set on it stay), INTERP_OK, INTERP_EXIT,
//     INTERP_EXECUTE_FINISH, INTERP_ENDFILE, INTERP_FILE_NOT_OPEN,
//     INTERP_ERROR, equal(a, b);
//   `this.params[n]`, `this.params["name"]` (read and write), `this.return_value`,
//   `this.value_returned`, `this.call_level`, `this.tool_offset.x` (.. w),
//   `this.tool_table[i].toolno` (pocketno, diameter, frontangle, backangle,
//   orientation, offset.x .. w); `this.execute(line)` (a line of G-code run
//   now; errors raise interpreter.InterpreterException), `this.blocks[n]`;
//   REMAP procedures that are generators: `yield INTERP_EXECUTE_FINISH`
//   suspends them until the interpreter resumes them (ScriptHost::resume_remap);
//   module `emccanon`: STRAIGHT_TRAVERSE, STRAIGHT_FEED (line, x y z a b c u
//     v w), MESSAGE, COMMENT, SET_FEED_RATE.
//
// [PYTHON]PATH_PREPEND / PATH_APPEND are added to sys.path (relative to the
// INI's folder), TOPLEVEL is run once in __main__ when the interpreter
// initialises; O-word functions are those of the module it binds to the name
// `oword` (LinuxCNC's convention: `import oword`); a function `__init__(self)`
// in TOPLEVEL is called then. Python starts in the process on first use and
// stays; calls hold the GIL for their duration only.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"

namespace cnc::interp {

struct PythonSettings {
  std::vector<std::filesystem::path> path_prepend;
  std::vector<std::filesystem::path> path_append;
  std::filesystem::path toplevel;  // empty: none
  // The [PYTHON] section exists (Python is configured).
  bool configured = false;
};

// [PYTHON] of `ini`; paths relative to the INI file's folder. A TOPLEVEL
// that does not exist throws ConfigError naming the key.
PythonSettings python_settings(const cnc::ini::IniFile& ini);

// A ScriptHost on embedded Python. `before_output` runs before Python code
// (so that what the caller buffered, e.g. canonical calls, is written before
// what Python prints); Python's stdout is flushed after every call.
std::shared_ptr<ScriptHost> make_python_host(PythonSettings settings, std::function<void()> before_output = {});

}  // namespace cnc::interp
