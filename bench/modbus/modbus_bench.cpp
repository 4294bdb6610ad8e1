// Modbus poll rate and latency against the simulator: RTU on a pty pair
// with the simulator emulating the line time at 9600, 19200 and 115200
// baud (a pty itself has no baud rate), the bare pty, and TCP loopback.
// Prints figures beside the theoretical frame time; never fails on them.
//   modbus_bench [seconds per case]
#include <modbus/modbus.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <thread>
#include <vector>

#include "core/ini/ini_file.hpp"
#include "core/util/time.hpp"
#include "fieldbus/modbus/link.hpp"
#include "sim/modbus/server.hpp"

using namespace cnc;

namespace {

struct Case {
  const char* name;
  bool tcp;
  int baud;  // 0: no line emulation
};

double pct(std::vector<int64_t>& v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return static_cast<double>(v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))]) * 1e-6;
}

// Reading one holding register: 8 request bytes, 7 answer bytes, and a
// 3.5-character silence after each frame; 10 bits per character (8N1).
double frame_time_ms(int baud) { return baud > 0 ? (8 + 7 + 7) * 10.0 * 1e3 / baud : 0; }

void run_case(const Case& c, double seconds) {
  modbus_sim::ServerConfig sc;
  sc.family = modbus_sim::Family::Delta;
  sc.tcp = c.tcp;
  sc.line_baud = c.baud;
  modbus_sim::Server server(sc);
  server.start();

  // 1. Round trips of single-register reads with a bare libmodbus client.
  modbus_t* ctx = c.tcp ? modbus_new_tcp("127.0.0.1", server.port())
                        : modbus_new_rtu(server.pty_path().c_str(), c.baud > 0 ? c.baud : 115200, 'N', 8, 1);
  modbus_set_slave(ctx, 1);
  modbus_set_response_timeout(ctx, 1, 0);
  if (modbus_connect(ctx) != 0) {
    std::printf("%-18s cannot connect: %s\n", c.name, modbus_strerror(errno));
    modbus_free(ctx);
    return;
  }
  std::vector<int64_t> rtt;
  int errors = 0;
  const int64_t end = monotonic_ns() + static_cast<int64_t>(seconds * 1e9 / 2);
  while (monotonic_ns() < end) {
    uint16_t v = 0;
    const int64_t t0 = monotonic_ns();
    if (modbus_read_registers(ctx, 0x2103, 1, &v) == 1) rtt.push_back(monotonic_ns() - t0);
    else ++errors;
  }
  modbus_close(ctx);
  modbus_free(ctx);
  const double n = static_cast<double>(rtt.size());
  const double rate = n / (seconds / 2);
  const double ft = frame_time_ms(c.baud);

  // 2. Whole VFD polls (speed and run writes when changed, three reads) by
  // the product's link thread, as fast as it can (POLL_MS = 0).
  std::string text = "[MODBUS]\n";
  if (c.tcp) text += "TRANSPORT = TCP\nHOST = 127.0.0.1\nPORT = " + std::to_string(server.port()) + "\n";
  else text += "TRANSPORT = RTU\nDEVICE = " + server.pty_path() + "\nBAUD = " + std::to_string(c.baud > 0 ? c.baud : 115200) + "\n";
  text += "TIMEOUT_MS = 1000\nVFD = 1\n[MODBUS_VFD_1]\nPROFILE = delta\nPOLL_MS = 0\n";
  const auto ini = ini::IniFile::parse(text, "bench.ini");
  modbus::Link link(modbus::load_link_config(ini, "MODBUS", "modbus.0"), nullptr);
  modbus::VfdCommand cmd;
  cmd.run = true;
  cmd.speed_rpm = 12000;
  link.vfds()[0]->command.write(cmd);
  link.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // With a steady command a poll is three reads (frequency, current, fault).
  const uint32_t x0 = link.vfds()[0]->counters.exchanges.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int64_t>(seconds * 500)));
  const uint32_t x1 = link.vfds()[0]->counters.exchanges.load();
  const int64_t max_latency = link.vfds()[0]->counters.max_latency_ns.load();
  link.stop();
  const double link_rate = static_cast<double>(x1 - x0) / (seconds / 2);
  const double median_rtt = pct(rtt, 0.5);
  std::printf("%-18s %8.0f req/s  rtt median %7.3f ms p99 %7.3f ms max %7.3f ms  frame time %7.3f ms  (x%.2f)  "
              "errors %d | link thread %8.0f req/s = %7.1f VFD polls/s, slowest request %7.3f ms\n",
              c.name, rate, median_rtt, pct(rtt, 0.99), pct(rtt, 1.0), ft, ft > 0 ? median_rtt / ft : 0.0, errors,
              link_rate, link_rate / 3, static_cast<double>(max_latency) * 1e-6);
}

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 4.0;
  std::printf("Modbus against cnc-modbus-sim (delta family), %.1f s per case; read of one register\n", seconds);
  std::printf("theoretical frame time = (8 + 7 bytes + 2 x 3.5 silent chars) x 10 bits / baud\n");
  const Case cases[] = {{"rtu pty 9600", false, 9600},   {"rtu pty 19200", false, 19200},
                        {"rtu pty 115200", false, 115200}, {"rtu pty (no line)", false, 0},
                        {"tcp loopback", true, 0}};
  for (const Case& c : cases) run_case(c, seconds);
  return 0;
}
