// cnc-cia402-sim: simulated CiA 402 drives on a CAN interface, as a process
// of their own (VM tests on vcan, a bench without drives).
//
//   cnc-cia402-sim --ini FILE [--section CIA402_SIM] [--interface SPEC]
//                  [--nodes 1,2,...] [--status-ms N] [--quiet]
//
// The drives are those of [SECTION] (NODE = ...) and their node sections;
// --interface overrides INTERFACE (socketcan:vcan0), --nodes picks some of
// them (one process per drive, or several per process). Runs until SIGINT
// or SIGTERM. Fault injection: one command per line on standard input,
// "drive <node> <what> [value]" (see sim/cia402/sim_host.hpp); each answered
// "ok" or "error: <why>" on standard output.
#include <poll.h>
#include <signal.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"

using namespace cnc;
using namespace cnc::cia402;

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

[[noreturn]] void usage(const char* why) {
  if (why) std::fprintf(stderr, "cnc-cia402-sim: %s\n", why);
  std::fprintf(stderr,
               "usage: cnc-cia402-sim --ini FILE [--section CIA402_SIM] [--interface SPEC] [--nodes 1,2] "
               "[--status-ms N] [--quiet]\n");
  std::exit(2);
}

void print_status(sim::SimHost& host) {
  for (std::size_t i = 0; i < host.size(); ++i) {
    const sim::CanopenDrive& d = host.at(i);
    const sim::DriveModel& m = d.model();
    std::printf("node %u (%s): %s, mode %s, statusword 0x%04X, position %lld, table %.4f mm, error 0x%04X, syncs %llu\n",
                d.node_id(), d.name().c_str(), to_string(m.state()), to_string(m.mode()), m.statusword(),
                static_cast<long long>(m.position()), m.plant().table_position() * 1000.0, m.error_code(),
                static_cast<unsigned long long>(m.syncs()));
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::string ini_path, section = "CIA402_SIM", interface;
  std::vector<int> nodes;
  int status_ms = 0;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + a).c_str());
      return argv[++i];
    };
    if (a == "--ini") ini_path = next();
    else if (a == "--section") section = next();
    else if (a == "--interface") interface = next();
    else if (a == "--nodes") {
      for (const std::string& w : split(next(), ',', true)) {
        const auto v = parse_int(w);
        if (!v || *v < 1 || *v > 127) usage(("bad node-ID " + w).c_str());
        nodes.push_back(static_cast<int>(*v));
      }
    } else if (a == "--status-ms") {
      const auto v = parse_int(next());
      if (!v || *v < 0) usage("--status-ms needs a number");
      status_ms = static_cast<int>(*v);
    } else if (a == "--quiet") quiet = true;
    else if (a == "-h" || a == "--help") usage(nullptr);
    else usage(("unknown argument " + a).c_str());
  }
  if (ini_path.empty()) usage("--ini is required");
  try {
    const ini::IniFile ini = ini::IniFile::load(ini_path);
    sim::SimBusConfig cfg = sim::load_sim_config(ini, section, nodes);
    if (!interface.empty()) cfg.interface = interface;
    can::register_virtual_transport();
    auto transport = can::open_transport(cfg.interface);
    sim::SimHost host(*transport);
    for (const auto& n : cfg.nodes) host.add(n);
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    host.start();
    if (!quiet) {
      std::printf("cnc-cia402-sim: %zu drive(s) on %s\n", host.size(), cfg.interface.c_str());
      std::fflush(stdout);
    }
    std::string line;
    int64_t next_status = monotonic_ns() + int64_t{status_ms} * 1'000'000;
    bool stdin_open = true;
    while (!g_stop) {
      pollfd p{STDIN_FILENO, POLLIN, 0};
      const int r = stdin_open ? ::poll(&p, 1, 50) : (::usleep(50'000), 0);
      if (r > 0) {
        char buf[512];
        const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
        if (n <= 0) {
          stdin_open = false;
        } else {
          line.append(buf, static_cast<std::size_t>(n));
          std::size_t eol;
          while ((eol = line.find('\n')) != std::string::npos) {
            const std::string cmd(trim(line.substr(0, eol)));
            line.erase(0, eol + 1);
            if (cmd.empty()) continue;
            if (cmd == "status") {
              print_status(host);
              continue;
            }
            const std::string why = host.inject(cmd, 0, false);
            std::printf(why.empty() ? "ok\n" : "error: %s\n", why.c_str());
            std::fflush(stdout);
          }
        }
      }
      if (status_ms > 0 && monotonic_ns() >= next_status) {
        print_status(host);
        next_status += int64_t{status_ms} * 1'000'000;
      }
    }
    host.stop();
    if (!quiet) print_status(host);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-cia402-sim: %s\n", e.what());
    return 1;
  }
  return 0;
}
