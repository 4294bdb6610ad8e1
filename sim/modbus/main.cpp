// cnc-modbus-sim: a simulated VFD or remote I/O module on Modbus, for trying
// configurations and for tests. Fault injection by lines on standard input.
#include <signal.h>
#include <poll.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>

#include "sim/modbus/server.hpp"

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

int usage() {
  std::fprintf(stderr,
               "usage: cnc-modbus-sim --family gs2|delta|yaskawa|atv|huanyang|io [--slave N]\n"
               "                      (--tcp PORT | --pty LINK) [--baud B] [--max-hz F] [--ramp HZ_S]\n"
               "                      [--load A] [--trip A] [--quiet]\n"
               "  --tcp PORT  serve Modbus TCP on 127.0.0.1:PORT (0: any free port, printed)\n"
               "  --pty LINK  serve RTU on a pseudo-terminal; LINK becomes a symbolic link to\n"
               "              the device a client opens (e.g. /tmp/vfd)\n"
               "  --baud B    RTU: delay each answer by the line time of both frames at B baud\n"
               "Fault injection, one command a line on standard input:\n"
               "  overcurrent | silent on|off | badcrc N | exception CODE [N] | drop | clear |\n"
               "  load A | status\n");
  return 2;
}

void print_status(cnc::modbus_sim::Server& s) {
  s.with_device([&](cnc::modbus_sim::Device& d) {
    const auto& m = d.model();
    std::printf("run=%d reverse=%d ref=%.2f Hz out=%.2f Hz current=%.2f A fault=%u requests=%llu\n", m.run(),
                m.reverse(), m.reference_hz(), m.output_hz(), m.current_a(), m.fault_code(),
                static_cast<unsigned long long>(0));
  });
  const auto st = s.stats();
  std::printf("requests=%llu answered=%llu bad-frames=%llu\n", static_cast<unsigned long long>(st.requests),
              static_cast<unsigned long long>(st.answered), static_cast<unsigned long long>(st.bad_frames));
  std::fflush(stdout);
}

bool command(cnc::modbus_sim::Server& s, const std::string& line) {
  std::istringstream in(line);
  std::string w;
  in >> w;
  if (w.empty()) return true;
  if (w == "overcurrent") s.trip_overcurrent();
  else if (w == "silent") {
    std::string on;
    in >> on;
    s.set_silent(on != "off");
  } else if (w == "badcrc") {
    int n = 1;
    in >> n;
    s.set_bad_crc(n);
  } else if (w == "exception") {
    int code = 4, n = -1;
    in >> code >> n;
    s.set_exception(static_cast<uint8_t>(code), n);
  } else if (w == "drop") s.drop_connection();
  else if (w == "clear") s.clear_faults();
  else if (w == "load") {
    double a = 1;
    in >> a;
    s.with_device([&](cnc::modbus_sim::Device& d) { d.model().set_load_a(a); });
  } else if (w == "status") print_status(s);
  else {
    std::fprintf(stderr, "cnc-modbus-sim: unknown command '%s'\n", w.c_str());
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  cnc::modbus_sim::ServerConfig c;
  std::string link;
  bool have_endpoint = false, quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    const char* v = nullptr;
    if (a == "--quiet") {
      quiet = true;
      continue;
    }
    if (a == "--help" || a == "-h") return usage();
    if (!(v = next())) return usage();
    if (a == "--family") {
      if (!cnc::modbus_sim::parse_family(v, c.family)) return usage();
    } else if (a == "--slave") c.slave = static_cast<uint8_t>(std::atoi(v));
    else if (a == "--tcp") c.tcp = true, c.port = std::atoi(v), have_endpoint = true;
    else if (a == "--pty") c.tcp = false, link = v, have_endpoint = true;
    else if (a == "--baud") c.line_baud = std::atoi(v);
    else if (a == "--max-hz") c.motor.max_hz = std::atof(v);
    else if (a == "--ramp") c.motor.ramp_hz_s = std::atof(v);
    else if (a == "--load") c.motor.load_a = std::atof(v);
    else if (a == "--trip") c.motor.trip_a = std::atof(v);
    else return usage();
  }
  if (!have_endpoint) return usage();
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  cnc::modbus_sim::Server server(c);
  try {
    server.start();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-modbus-sim: %s\n", e.what());
    return 1;
  }
  if (!link.empty()) {
    std::error_code ec;
    std::filesystem::remove(link, ec);
    std::filesystem::create_symlink(server.pty_path(), link, ec);
    if (ec) {
      std::fprintf(stderr, "cnc-modbus-sim: cannot link %s to %s: %s\n", link.c_str(), server.pty_path().c_str(),
                   ec.message().c_str());
      return 1;
    }
  }
  if (!quiet) {
    if (c.tcp) std::printf("cnc-modbus-sim: %s slave %u on tcp 127.0.0.1:%d\n", to_string(c.family), c.slave, server.port());
    else std::printf("cnc-modbus-sim: %s slave %u on rtu %s (%s)\n", to_string(c.family), c.slave, link.c_str(), server.pty_path().c_str());
    std::fflush(stdout);
  }
  std::string line;
  bool stdin_open = true;
  while (!g_stop) {
    if (!stdin_open) {
      usleep(50'000);
      continue;
    }
    pollfd p{0, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    if (!std::getline(std::cin, line)) {
      stdin_open = false;  // detached (loadusr): serve until a signal
      continue;
    }
    command(server, line);
  }
  server.stop();
  if (!link.empty()) std::filesystem::remove(link);
  return 0;
}
