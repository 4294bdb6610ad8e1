// cncd: the controller daemon. See docs/architecture.md.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include <pthread.h>
#include <signal.h>

#include "core/daemon/controller.hpp"
#include "core/daemon/plugins.hpp"
#include "core/ipc/segment.hpp"

namespace {
void usage() {
  std::fprintf(stderr,
               "usage: cncd [--instance NAME] [--verbose] [--strict] [--check] MACHINE.ini\n"
               "  Runs the controller for the machine the INI file describes until SIGINT,\n"
               "  SIGTERM or `cnc shutdown`. The instance (default: $CNC_INSTANCE or\n"
               "  \"default\") names the shared segment clients connect to.\n"
               "  --strict  unknown and unused INI keys stop the start-up (default: reported\n"
               "            as messages; also [EMC]UNKNOWN_KEYS = ERROR)\n"
               "  --check   load the INI and HAL files, create every component, check the\n"
               "            INI keys, then stop: nothing runs, no instance is used; exit 0\n"
               "            when the configuration loads\n");
}
}  // namespace

int main(int argc, char** argv) {
  cnc::daemon::Options opt;
  opt.instance = cnc::ipc::default_instance();
  opt.extra_components = cnc::daemon::plugin_registrars();
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--instance" || a == "-i") && i + 1 < argc) {
      opt.instance = argv[++i];
    } else if (a == "--verbose" || a == "-v") {
      opt.verbose = true;
    } else if (a == "--strict") {
      opt.strict = true;
    } else if (a == "--check") {
      opt.check_only = true;
    } else if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "cncd: unknown option %s\n", a.c_str());
      usage();
      return 2;
    } else if (!opt.ini_file.empty()) {
      std::fprintf(stderr, "cncd: one INI file, got %s and %s\n", opt.ini_file.c_str(), a.c_str());
      return 2;
    } else {
      opt.ini_file = a;
    }
  }
  if (opt.ini_file.empty()) {
    usage();
    return 2;
  }
  // Its children (halcmd, the task's programs) and its plug-ins (a shared
  // simulated bus names its socket after the instance) see the instance.
  ::setenv("CNC_INSTANCE", opt.instance.c_str(), 1);
  try {
    if (opt.check_only) {
      { cnc::daemon::Controller controller(opt); }  // its messages are printed as it stops
      std::fprintf(stderr, "cncd: %s loads\n", opt.ini_file.c_str());
      return 0;
    }
    // SIGINT and SIGTERM blocked before the controller starts any thread,
    // so that every thread inherits the mask and only run()'s sigtimedwait
    // takes them. Blocked in the main thread only, a signal arriving while
    // it was not waiting went to another thread and killed the process
    // (exit status 143 instead of a clean stop).
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
    cnc::daemon::Controller controller(opt);
    controller.run(true);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cncd: %s\n", e.what());
    return 1;
  }
  return 0;
}
