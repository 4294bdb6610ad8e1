// cnc-estimate: how long a program's motion takes on a configuration,
// estimated offline by the controller's own trajectory planner
// (core/task/estimate.hpp; docs/tp.md, "Time estimate"). No controller
// needs to run.
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>

#include "core/task/estimate.hpp"
#include "core/util/error.hpp"

using namespace cnc;

namespace {

int usage(FILE* to) {
  std::fprintf(to,
               "Usage: cnc-estimate --ini FILE [--start X,Y,Z] PROGRAM.ngc\n"
               "Estimates a program's motion time on the configuration FILE by running it through the\n"
               "controller's interpreter, task canon and trajectory planner offline (G20, work offsets,\n"
               "G92, rotation, tool offsets, the limits and look-ahead cncd would use).\n"
               "  --ini FILE      the configuration (as cncd reads it)\n"
               "  --start X,Y,Z   where the machine is (machine coordinates); default: where homing leaves it\n"
               "Prints the motion time, the moves, the stops (where the controller waits for motion: M6,\n"
               "M66, probes...) and the end position in machine coordinates. Tool changes, spindle waits\n"
               "and pauses are not counted. Exit status: 0 done, 1 the program or its run failed, 2 usage\n"
               "or configuration error.\n");
  return to == stdout ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string ini, program;
  std::optional<Pose> start;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") return usage(stdout);
    if (a == "--ini" && i + 1 < argc) {
      ini = argv[++i];
    } else if (a == "--start" && i + 1 < argc) {
      Pose p;
      if (std::sscanf(argv[++i], "%lf,%lf,%lf", &p[0], &p[1], &p[2]) != 3) return usage(stderr);
      start = p;
    } else if (!a.empty() && a[0] != '-' && program.empty()) {
      program = a;
    } else {
      return usage(stderr);
    }
  }
  if (ini.empty() || program.empty()) return usage(stderr);
  try {
    const estimate::Machine m = estimate::load_machine(ini);
    estimate::Options o;
    o.start = start;
    const estimate::Result r = estimate::estimate(m, program, o);
    if (!r.completed && r.time_s == 0) {
      std::fprintf(stderr, "cnc-estimate: %s\n", r.error.c_str());
      return 1;
    }
    const int minutes = static_cast<int>(r.time_s / 60);
    std::printf("%s: %.3f s of motion (%d:%06.3f), %zu moves, %zu stops\n", program.c_str(), r.time_s, minutes,
                r.time_s - 60.0 * minutes, r.moves, r.stops);
    std::printf("end position X%.6f Y%.6f Z%.6f (machine)\n", r.end[0], r.end[1], r.end[2]);
    if (!r.completed) {
      std::fprintf(stderr, "cnc-estimate: %s\n", r.error.c_str());
      return 1;
    }
    return 0;
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "cnc-estimate: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-estimate: %s\n", e.what());
    return 2;
  }
}
