// cnc-scope: captures HAL pins of a running controller with its `scope`
// component (docs/hal.md, "Scope") and writes them as CSV. It sends
// halcmd's `scope` lines on the controller's halcmd socket: setup, arm,
// state until done, csv; the file is written atomically.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "core/ipc/admin.hpp"
#include "core/ipc/segment.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace {
void usage() {
  std::fprintf(stderr,
               "usage: cnc-scope [-i INSTANCE] --pins PIN[,PIN...] [--trigger PIN] [--edge rising|falling|level|none]\n"
               "                 [--level V] [--pre PERCENT] [--samples N] [--mode single|auto] [--timeout S]\n"
               "                 --csv FILE\n"
               "  Needs `loadrt scope samples=N` and `addf scope.sample servo-thread` in the HAL.\n"
               "  One capture of N servo cycles (default: the buffer's size), PERCENT (10) of them before\n"
               "  the trigger, written to FILE ('-': standard output) as time_s,PIN,... rows.\n");
}

std::string request(cnc::ipc::AdminClient& c, const std::string& line) {
  const cnc::ipc::AdminReply r = c.request(line);
  if (!r.ok) throw std::runtime_error(r.text);
  return r.text;
}
}  // namespace

int main(int argc, char** argv) {
  std::string instance = cnc::ipc::default_instance();
  std::string pins, csv, setup_extra;
  double timeout_s = 30;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        usage();
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "-i" || a == "--instance") instance = value();
    else if (a == "--pins") pins = value();
    else if (a == "--csv") csv = value();
    else if (a == "--trigger") setup_extra += " trigger=" + value();
    else if (a == "--edge") setup_extra += " edge=" + value();
    else if (a == "--level") setup_extra += " level=" + value();
    else if (a == "--pre") setup_extra += " pre=" + value();
    else if (a == "--samples") setup_extra += " samples=" + value();
    else if (a == "--mode") setup_extra += " mode=" + value();
    else if (a == "--timeout") {
      const auto t = cnc::parse_double(value());
      if (!t || *t <= 0) {
        std::fprintf(stderr, "cnc-scope: --timeout: expected seconds\n");
        return 2;
      }
      timeout_s = *t;
    } else if (a == "-h" || a == "--help") {
      usage();
      return 0;
    } else {
      std::fprintf(stderr, "cnc-scope: unknown argument %s\n", a.c_str());
      usage();
      return 2;
    }
  }
  if (pins.empty() || csv.empty()) {
    usage();
    return 2;
  }
  try {
    cnc::ipc::AdminClient client(instance);
    request(client, "scope stop");
    request(client, "scope setup " + pins + setup_extra);
    request(client, "scope arm");
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    std::string state;
    for (;;) {
      state = std::string(cnc::trim(request(client, "scope state")));
      if (state.rfind("done", 0) == 0) break;
      if (std::chrono::steady_clock::now() > deadline) {
        request(client, "scope stop");
        std::fprintf(stderr, "cnc-scope: no trigger within %.1f s (%s)\n", timeout_s, state.c_str());
        return 1;
      }
      ::usleep(20'000);
    }
    const std::string text = request(client, "scope csv");
    if (csv == "-") std::fputs(text.c_str(), stdout);
    else cnc::write_file_atomically(csv, text);
    std::fprintf(stderr, "cnc-scope: %s\n", state.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-scope: %s\n", e.what());
    return 1;
  }
}
