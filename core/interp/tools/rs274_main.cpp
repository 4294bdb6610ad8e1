// cnc-rs274: interprets an RS274/NGC program against a tool table and a
// parameter file and prints the canonical calls in the format of LinuxCNC's
// stand-alone `rs274 -g`, so that both outputs compare line by line.
// Errors go to stderr as LinuxCNC prints them: the message, then the line.
#include <cstdio>
#include <cstring>
#include <string>

#include <unistd.h>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"
#include "core/interp/text_canon.hpp"
#include "core/tooltable/tool_table.hpp"
#include "core/util/error.hpp"

namespace {
void usage() {
  std::fprintf(stderr,
               "Usage: cnc-rs274 [-t tool.tbl] [-v var-file.var] [-i file.ini] [-b] [-g] [-r] [-m mm|inch]\n"
               "                 [-a AXES] [-q] program.ngc [output]\n"
               "    -t: tool table (LinuxCNC format)\n"
               "    -v: parameter file (read at start, written at the end)\n"
               "    -i: INI file ([RS274NGC], [EMCIO]RANDOM_TOOLCHANGER, [TRAJ]COORDINATES)\n"
               "    -b: block delete on ('/' lines skipped)\n"
               "    -g: batch mode (accepted for rs274 compatibility; always on)\n"
               "    -r: random tool changer\n"
               "    -m: machine (tool table and parameter) units, default inch as rs274\n"
               "    -a: axis letters, default XYZABC as rs274\n"
               "    -q: do not print the canonical calls (for timing)\n");
}
}  // namespace

int main(int argc, char** argv) {
  using namespace cnc::interp;
  std::string tbl, var, ini_path, axes = "XYZABC";
  bool block_delete = false, random = false, quiet = false;
  Units machine = Units::Inch;
  int opt;
  while ((opt = getopt(argc, argv, "t:v:i:bgrm:a:qn:p:sT")) != -1) {
    switch (opt) {
      case 't': tbl = optarg; break;
      case 'v': var = optarg; break;
      case 'i': ini_path = optarg; break;
      case 'b': block_delete = !block_delete; break;
      case 'g': break;
      case 'r': random = true; break;
      case 'm': machine = std::strcmp(optarg, "mm") == 0 ? Units::Mm : Units::Inch; break;
      case 'a': axes = optarg; break;
      case 'q': quiet = true; break;
      case 'n': case 'p': case 's': case 'T': break;
      default: usage(); return 2;
    }
  }
  if (optind >= argc) {
    usage();
    return 2;
  }
  const char* program = argv[optind];
  std::FILE* out = stdout;
  if (optind + 1 < argc) {
    out = std::fopen(argv[optind + 1], "w");
    if (out == nullptr) {
      std::perror(argv[optind + 1]);
      return 2;
    }
  }
  try {
    cnc::ini::IniFile ini;
    Config cfg;
    if (!ini_path.empty()) {
      ini = cnc::ini::IniFile::load(ini_path);
      cfg = Config::from_ini(ini);
    }
    if (random) cfg.random_toolchanger = true;
    cfg.block_delete = block_delete;
    unsigned mask = 0;
    for (char c : axes) {
      const int a = cnc::axis_index(c);
      if (a >= 0) mask |= 1u << a;
    }
    if (ini_path.empty() || ini.find("TRAJ", "COORDINATES") == std::nullopt) cfg.axis_mask = mask;
    if (!var.empty()) cfg.parameter_file = var;
    const auto kind = cfg.random_toolchanger ? cnc::tooltable::ChangerKind::Random : cnc::tooltable::ChangerKind::NonRandom;
    cnc::tooltable::ToolTable table(kind);
    if (!tbl.empty()) table = cnc::tooltable::ToolTable::load(tbl, kind);
    TextCanon canon(quiet ? nullptr : out, table, machine);
    Interpreter interp(canon, cfg);
    std::fprintf(stderr, "executing\n");
    int rc = 0;
    try {
      interp.init();
      canon.on_reset();
      interp.open(program);
      interp.run_to_end();
    } catch (const InterpError& e) {
      canon.flush();
      std::fprintf(stderr, "%s\n%s\n", e.message().c_str(), e.block_text().c_str());
      rc = 1;
    }
    canon.clear_block();
    canon.on_reset();
    canon.on_reset();
    canon.flush();
    if (!var.empty()) interp.save_parameters();
    if (out != stdout) std::fclose(out);
    return rc;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-rs274: %s\n", e.what());
    return 2;
  }
}
