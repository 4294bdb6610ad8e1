#include "core/interp/rs274_run.hpp"

#include <functional>
#include <stdexcept>

#include "core/ini/ini_file.hpp"
#include "core/interp/canon_replay.hpp"
#include "core/interp/text_canon.hpp"
#include "core/tooltable/tool_table.hpp"

namespace cnc::interp {
namespace {

std::string describe(const InterpError& e, const Rs274Options& o) {
  if (o.rs274_error_format || e.file().empty()) return e.message() + "\n" + e.block_text();
  return e.file() + (e.line() > 0 ? ":" + std::to_string(e.line()) : std::string()) + ": " + e.message() + "\n" +
         e.block_text();
}

}  // namespace

namespace {

// rs274 -n 1: MDI lines from `in` until "quit" or its end, then "continue
// program? y/n". Returns true to go on with the program.
bool mdi_then_continue(Interpreter& interp, std::FILE* in, const std::function<void(const InterpError&)>& report) {
  std::fprintf(stderr, "starting MDI\n");
  char line[512];
  for (;;) {
    std::fprintf(stderr, "READ => ");
    if (in == nullptr || std::fgets(line, sizeof line, in) == nullptr) break;
    std::string text(line);
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
    if (text == "quit") break;
    try {
      interp.execute(text);
    } catch (const InterpError& e) {
      report(e);
      interp.unwind();
    }
  }
  std::fprintf(stderr, "continue program? y/n =>");
  return in != nullptr && std::fgets(line, sizeof line, in) != nullptr && line[0] == 'y';
}

// An error that reading again cannot get past (rs274 -n 0 would repeat it
// for ever): the end of the file.
bool at_end_of_input(const InterpError& e) {
  return e.message().starts_with("File ended with no percent sign") || e.message().starts_with("EOF in file");
}

// interpret_from_file of LinuxCNC's rs274 driver: read and execute to the
// program end, after an error stop, go on or ask (Rs274Options::on_error).
bool run_program(Interpreter& interp, const Rs274Options& o, const std::function<void(const InterpError&)>& report) {
  for (;;) {
    Status st = Status::Ok;
    try {
      st = interp.read();
    } catch (const InterpError& e) {
      report(e);
      interp.unwind();
      if (o.on_error == 2 || at_end_of_input(e)) return false;
      if (o.on_error == 1 && !mdi_then_continue(interp, o.mdi_in, report)) return false;
      continue;
    }
    if (st == Status::SynchRequired) {
      interp.synch();
      continue;
    }
    if (st == Status::Yield) continue;
    if (st != Status::Ok) return true;
    try {
      st = interp.execute();
    } catch (const InterpError& e) {
      report(e);
      interp.unwind();
      if (o.on_error == 2) return false;
      if (o.on_error == 1 && !mdi_then_continue(interp, o.mdi_in, report)) return false;
      continue;
    }
    if (st == Status::ExecuteFinish) interp.synch();
    if (st == Status::ProgramEnd) return true;
  }
}

}  // namespace

bool is_canon_replay_plugin(const std::string& plugin) {
  const std::string name = std::filesystem::path(plugin).filename().string();
  return name == "canterp.so" || name == "canterp";
}

bool run_rs274(const Rs274Options& o, std::FILE* out, std::string& error, std::FILE* err_out) {
  error.clear();
  cnc::ini::IniFile ini;
  Config cfg;
  if (!o.ini.empty()) {
    ini = cnc::ini::IniFile::load(o.ini);
    cfg = Config::from_ini(ini);
    // LinuxCNC's rs274 starts in millimetres whatever [TRAJ]LINEAR_UNITS
    // says (its saicanon reports CANON_UNITS_MM until G20); the INI's units
    // still give #<_metric_machine>
    cfg.default_units = Units::Mm;
  }
  if (o.random_toolchanger) cfg.random_toolchanger = true;
  cfg.block_delete = o.block_delete;
  cfg.task = o.task;
  if (o.ini.empty() || !ini.find("TRAJ", "COORDINATES")) {
    unsigned mask = 0;
    for (char c : o.axes) {
      const int a = cnc::axis_index(c);
      if (a >= 0) mask |= 1u << a;
    }
    cfg.axis_mask = mask;
  }
  if (!o.parameter_file.empty()) cfg.parameter_file = o.parameter_file;
  const auto kind = cfg.random_toolchanger ? cnc::tooltable::ChangerKind::Random : cnc::tooltable::ChangerKind::NonRandom;
  cnc::tooltable::ToolTable table(kind);
  if (!o.tool_table.empty()) table = cnc::tooltable::ToolTable::load(o.tool_table, kind);
  TextCanon canon(out, table, o.machine_units);
  if (!o.plugin.empty()) {
    if (!is_canon_replay_plugin(o.plugin)) {
      throw std::runtime_error("-p " + o.plugin +
                               ": unknown interpreter plugin; the one known is canterp.so, LinuxCNC's canon interpreter "
                               "(here the built-in canon replay)");
    }
    // canterp makes no calls of its own at start and end, only the file's
    try {
      replay_canon_file(o.program, canon);
    } catch (const InterpError& e) {
      canon.flush();
      error = describe(e, o);
      if (err_out != nullptr) std::fprintf(err_out, "%s\n", error.c_str());
      return false;
    }
    canon.flush();
    return true;
  }
  if (o.make_script) {
    cfg.script = o.make_script(o.ini.empty() ? nullptr : &ini, [&canon, out] {
      canon.flush();
      if (out != nullptr) std::fflush(out);
    });
  }
  Interpreter interp(canon, cfg);
  // Errors go out as they happen, after the calls made before them.
  const std::function<void(const InterpError&)> report = [&](const InterpError& e) {
    canon.flush();
    std::string text = describe(e, o);
    if (o.print_stack) {
      for (const std::string& f : interp.call_stack()) text += "\n" + f;
    }
    if (error.empty()) error = text;
    if (err_out != nullptr) std::fprintf(err_out, "%s\n", text.c_str());
  };
  bool ok = true;
  try {
    interp.init();
    try {
      interp.open(o.program);
    } catch (const InterpError& e) {
      // rs274 stops at once when the program cannot be opened
      report(e);
      return false;
    }
    canon.on_reset();
    ok = run_program(interp, o, report);
  } catch (const InterpError& e) {
    report(e);
    ok = false;
  }
  canon.clear_block();
  // rs274 resets at close and at exit; with an INI file LinuxCNC closes
  // lazily (no reset at close).
  if (o.ini.empty()) canon.on_reset();
  canon.on_reset();
  canon.flush();
  if (!o.parameter_file.empty()) interp.save_parameters();
  return ok;
}

}  // namespace cnc::interp
