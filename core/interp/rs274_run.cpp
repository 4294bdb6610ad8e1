#include "core/interp/rs274_run.hpp"

#include "core/ini/ini_file.hpp"
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

bool run_rs274(const Rs274Options& o, std::FILE* out, std::string& error, std::FILE* err_out) {
  cnc::ini::IniFile ini;
  Config cfg;
  if (!o.ini.empty()) {
    ini = cnc::ini::IniFile::load(o.ini);
    cfg = Config::from_ini(ini);
  }
  if (o.random_toolchanger) cfg.random_toolchanger = true;
  cfg.block_delete = o.block_delete;
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
  Interpreter interp(canon, cfg);
  bool ok = true;
  try {
    interp.init();
    try {
      interp.open(o.program);
    } catch (const InterpError& e) {
      // rs274 stops at once when the program cannot be opened
      canon.flush();
      error = describe(e, o);
      if (err_out != nullptr) std::fprintf(err_out, "%s\n", error.c_str());
      return false;
    }
    canon.on_reset();
    interp.run_to_end();
  } catch (const InterpError& e) {
    canon.flush();
    error = describe(e, o);
    if (err_out != nullptr) std::fprintf(err_out, "%s\n", error.c_str());
    ok = false;
  }
  canon.clear_block();
  canon.on_reset();
  canon.on_reset();
  canon.flush();
  if (!o.parameter_file.empty()) interp.save_parameters();
  return ok;
}

}  // namespace cnc::interp
