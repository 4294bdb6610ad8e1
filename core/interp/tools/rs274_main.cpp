// cnc-rs274: interprets an RS274/NGC program against a tool table and a
// parameter file and prints the canonical calls in the format of LinuxCNC's
// stand-alone `rs274 -g`, so that both outputs compare line by line.
// Errors go to stderr as "file:line: message", then the block; run under the
// name `rs274` (LinuxCNC's regression tests put it on PATH so), exactly as
// LinuxCNC prints them: the message, then the block.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <unistd.h>

#include "core/interp/python_host.hpp"
#include "core/interp/rs274_run.hpp"

namespace {
void usage() {
  std::fprintf(stderr,
               "Usage: cnc-rs274 [-t tool.tbl] [-v var-file.var] [-i file.ini] [-n 0|1|2] [-b] [-s] [-g] [-T]\n"
               "                 [-l level] [-r] [-m mm|inch] [-a AXES] [-q] [-p canterp.so] program.ngc [output]\n"
               "    -t: tool table (LinuxCNC format)\n"
               "    -v: parameter file (read at start, written atomically at the end)\n"
               "    -i: INI file ([RS274NGC], [EMCIO]RANDOM_TOOLCHANGER, [TRAJ]COORDINATES)\n"
               "    -n: after an error 0: go on, 1: read MDI lines from stdin, 2: stop (default)\n"
               "    -b: toggle block delete (default off: '/' lines run)\n"
               "    -s: toggle printing the subroutine call stack after an error\n"
               "    -T: run as in the task controller (#<_task> is 1)\n"
               "    -l: log level (accepted for rs274 compatibility; no debug log)\n"
               "    -g: batch mode (accepted for rs274 compatibility; always on)\n"
               "    -r: random tool changer\n"
               "    -m: machine (tool table and parameter) units, default inch as rs274\n"
               "    -a: axis letters, default XYZABC as rs274\n"
               "    -q: do not print the canonical calls (for timing)\n"
               "    -p canterp.so: the program is a file of canonical calls (rs274 -g output), replayed\n");
}
}  // namespace

int main(int argc, char** argv) {
  using namespace cnc::interp;
  Rs274Options o;
  const char* slash = std::strrchr(argv[0], '/');
  o.rs274_error_format = std::strcmp(slash ? slash + 1 : argv[0], "rs274") == 0;
  bool quiet = false;
  int opt;
  while ((opt = getopt(argc, argv, "t:v:i:bgrm:a:qn:p:sTl:")) != -1) {
    switch (opt) {
      case 't': o.tool_table = optarg; break;
      case 'v': o.parameter_file = optarg; break;
      case 'i': o.ini = optarg; break;
      case 'b': o.block_delete = !o.block_delete; break;
      case 'g': break;
      case 'r': o.random_toolchanger = true; break;
      case 'm': o.machine_units = std::strcmp(optarg, "mm") == 0 ? Units::Mm : Units::Inch; break;
      case 'a': o.axes = optarg; break;
      case 'q': quiet = true; break;
      case 'n': o.on_error = std::atoi(optarg); break;
      case 's': o.print_stack = !o.print_stack; break;
      case 'T': o.task = true; break;
      case 'l': break;
      case 'p':
        if (!is_canon_replay_plugin(optarg)) {
          std::fprintf(stderr,
                       "cnc-rs274: -p %s: unknown interpreter plugin; the one known is canterp.so (LinuxCNC's canon "
                       "interpreter: the program is a file of canonical calls, replayed)\n",
                       optarg);
          return 2;
        }
        o.plugin = optarg;
        break;
      default: usage(); return 2;
    }
  }
  // Without -t LinuxCNC's rs274 reads the sample tool table of its
  // installation; CNC_RS274_TOOL_TABLE names the stand-in (the regression
  // suite's run sets it).
  if (o.tool_table.empty()) {
    if (const char* t = std::getenv("CNC_RS274_TOOL_TABLE"); t != nullptr && *t != 0) o.tool_table = t;
  }
  if (optind >= argc) {
    usage();
    return 2;
  }
  o.program = argv[optind];
  // [PYTHON] of the INI: O-word functions and `;py,` statements
  o.make_script = [](const cnc::ini::IniFile* ini, std::function<void()> flush) {
    return make_python_host(ini != nullptr ? python_settings(*ini) : PythonSettings{}, std::move(flush));
  };
  o.mdi_in = stdin;
  std::FILE* out = stdout;
  if (optind + 1 < argc) {
    out = std::fopen(argv[optind + 1], "w");
    if (out == nullptr) {
      std::perror(argv[optind + 1]);
      return 2;
    }
  }
  std::fprintf(stderr, "executing\n");
  int rc = 0;
  try {
    std::string error;
    if (!run_rs274(o, quiet ? nullptr : out, error, stderr)) rc = 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-rs274: %s\n", e.what());
    rc = 2;
  }
  if (out != stdout) std::fclose(out);
  return rc;
}
