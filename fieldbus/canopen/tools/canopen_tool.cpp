// cnc-canopen: the CANopen master from the command line, for commissioning
// and tests.
//   cnc-canopen load INI [SECTION]           bus-load plan of a configuration
//   cnc-canopen boot INI [SECTION] [--run-s S] [--echo A=B]
//                                            boot every node as the controller
//                                            does, then optionally run the cycle
//   cnc-canopen read IF NODE INDEX:SUB [--block]
//   cnc-canopen write IF NODE INDEX:SUB:TYPE VALUE [--segmented|--block]
//   cnc-canopen nmt IF start|stop|preop|reset|reset-comm NODE
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "core/util/messages.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/can/frame_timing.hpp"
#include "fieldbus/canopen/master.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: cnc-canopen load INI [SECTION]\n"
               "       cnc-canopen boot INI [SECTION] [--run-s S] [--echo INDEX:SUB=INDEX:SUB]\n"
               "       cnc-canopen read IF NODE INDEX:SUB [--block]\n"
               "       cnc-canopen write IF NODE INDEX:SUB:TYPE VALUE [--segmented|--block]\n"
               "       cnc-canopen nmt IF start|stop|preop|reset|reset-comm NODE\n"
               "IF is socketcan:<interface>; TYPE u8..u64, s8..s64, f32, f64, str, hex.\n");
  return 2;
}

void drain_messages(MessageQueue& q) {
  Message m;
  while (q.pop(m)) std::printf("%s: %s: %s\n", to_string(m.kind), m.source.c_str(), m.text.c_str());
}

int cmd_load(const BusConfig& c) {
  std::printf("%s on %s: SYNC period %lld us, %u kbit/s, budgets %.0f %% average (MAX_BUS_LOAD), %.0f %% of the "
              "busiest cycle (MAX_CYCLE_LOAD)\n",
              c.name.c_str(), c.interface.c_str(), static_cast<long long>(c.cycle_ns / 1000), c.bitrate / 1000,
              c.max_bus_load * 100, c.max_cycle_load * 100);
  std::printf("  %-30s %5s %6s %-11s %-16s %9s %9s %10s %9s\n", "frame", "COB", "bytes", "class", "rate",
              "avg/cycle", "max/cycle", "worst bits", "avg bits");
  const auto frames = c.schedule();
  for (const auto& f : frames) {
    char rate[32];
    switch (f.frame_class()) {
      case can::FrameClass::Synchronous:
        if (f.every_n_cycles <= 1) std::snprintf(rate, sizeof rate, "every cycle");
        else if (f.slot >= 0) std::snprintf(rate, sizeof rate, "1/%u, slot %d", f.every_n_cycles, f.slot);
        else std::snprintf(rate, sizeof rate, "1/%u, any slot", f.every_n_cycles);
        break;
      case can::FrameClass::Sporadic:
        std::snprintf(rate, sizeof rate, "<= 1 per %.1f ms", static_cast<double>(f.period_ns) / 1e6);
        break;
      case can::FrameClass::Allowance: std::snprintf(rate, sizeof rate, "%u per cycle", f.per_cycle); break;
    }
    const double bits = can::worst_case_frame_bits(f.extended, f.data_bytes);
    std::printf("  %-30s 0x%03X %6u %-11s %-16s %9.3f %9u %10.0f %9.1f\n", f.label.c_str(), f.cob_id, f.data_bytes,
                can::to_string(f.frame_class()), rate, f.average_per_cycle(c.cycle_ns), f.max_per_cycle(c.cycle_ns), bits,
                f.average_per_cycle(c.cycle_ns) * bits);
  }
  const can::BusLoad l = c.load();
  std::printf("average: %.1f bits per cycle nominal, %.1f worst case of %.0f bit times: %.1f %% nominal, %.1f %% worst case\n",
              l.nominal_bits_per_cycle, l.worst_bits_per_cycle, l.cycle_bits, l.nominal() * 100, l.worst_case() * 100);
  std::printf("per cycle slot (worst-case stuffing; synchronous frames, higher-priority events and allowances, one\n"
              "lower-priority frame already on the wire):\n");
  std::printf("  %5s %12s %13s %9s %7s %7s\n", "slot", "synchronous", "interference", "blocking", "total", "cycle");
  for (const auto& s : l.slots) {
    std::printf("  %5u %12.0f %13.0f %9.0f %7.0f %6.1f%%%s\n", s.slot, s.synchronous_bits, s.interference_bits,
                s.blocking_bits, s.total(), s.total() / l.cycle_bits * 100,
                &s == &l.slots[l.worst_slot] ? "  <- busiest" : "");
  }
  if (!l.slots.empty() && l.slots[l.worst_slot].response_bits > 0) {
    std::printf("  (the totals include %.0f bit times waiting for the slowest device's SYNC response, SYNC_RESPONSE_US)\n",
                l.slots[l.worst_slot].response_bits);
  }
  std::printf("load: %.1f %% nominal, %.1f %% worst case on average; busiest cycle %.1f %%\n", l.nominal() * 100,
              l.worst_case() * 100, l.worst_cycle() * 100);
  const std::string problem = c.load_problem();
  if (!problem.empty()) {
    std::printf("%s: %s\n", c.load_override ? "WARNING (LOAD_OVERRIDE)" : "REFUSED", problem.c_str());
    return c.load_override ? 0 : 1;
  }
  std::printf("fits\n");
  return 0;
}

std::optional<ObjectAddress> parse_addr(const std::string& s) {
  const auto parts = split(s, ':');
  if (parts.size() < 2) return std::nullopt;
  const auto i = parse_uint(parts[0]);
  const auto k = parse_uint(parts[1]);
  if (!i || !k || *i > 0xFFFF || *k > 0xFF) return std::nullopt;
  return ObjectAddress{static_cast<uint16_t>(*i), static_cast<uint8_t>(*k)};
}

// Boots the bus; with run_s > 0 runs the cycle at the SYNC period, writing a
// ramp to `echo.first` of every node that maps it and checking that
// `echo.second` comes back with the transport delay.
int cmd_boot(const BusConfig& c, double run_s, std::optional<std::pair<ObjectAddress, ObjectAddress>> echo) {
  MessageQueue messages;
  Master m(c, &messages);
  m.start_thread();
  try {
    m.boot();
  } catch (const std::exception& e) {
    drain_messages(messages);
    std::fprintf(stderr, "cnc-canopen: %s\n", e.what());
    return 1;
  }
  drain_messages(messages);
  std::printf("boot: %zu nodes operational\n", m.node_count());
  if (run_s <= 0) return 0;

  struct Track {
    uint8_t id;
    ProcessSlot out, in;
    std::vector<int32_t> commanded;
    uint64_t matches = 0, exact_delay = 0, future = 0, stale = 0;
  };
  std::vector<Track> tracks;
  if (echo) {
    for (const auto& n : c.nodes) {
      Track t{n.id, m.output(n.id, echo->first.index, echo->first.sub), m.input(n.id, echo->second.index, echo->second.sub), {}};
      if (t.out && t.in) tracks.push_back(std::move(t));
    }
    if (tracks.empty()) {
      std::fprintf(stderr, "cnc-canopen: --echo: no node maps both objects\n");
      return 1;
    }
  }
  const int64_t period = c.cycle_ns;
  const int64_t cycles = static_cast<int64_t>(run_s * 1e9) / period;
  timespec next;
  clock_gettime(CLOCK_MONOTONIC, &next);
  uint64_t fresh = 0, overruns = 0, skipped = 0;
  for (int64_t k = 0; k < cycles; ++k) {
    const int64_t now = monotonic_ns();
    m.cyclic_read(now);
    fresh += m.cyclic_status().inputs_fresh;
    for (Track& t : tracks) {
      const int32_t fb = read_slot<int32_t>(t.in);
      // The feedback must be a value commanded at least two cycles ago
      // (one cycle of transport, one of the echo device).
      const auto it = std::find(t.commanded.begin(), t.commanded.end(), fb);
      if (it != t.commanded.end()) {
        const auto age = t.commanded.end() - it;
        ++t.matches;
        if (age == 2) ++t.exact_delay;
        if (age < 2) ++t.future;
        if (age > 2) ++t.stale;
      }
      const int32_t cmd = static_cast<int32_t>(k * 10 + t.id * 1'000'000);
      t.commanded.push_back(cmd);
      write_slot<int32_t>(t.out, cmd);
    }
    m.cyclic_write(now);
    // Next period; after an overrun the schedule moves on instead of
    // sending a burst of SYNCs to catch up (what a servo thread does too).
    int64_t next_ns = static_cast<int64_t>(next.tv_sec) * 1'000'000'000 + next.tv_nsec + period;
    const int64_t after = monotonic_ns();
    if (next_ns < after) {
      const int64_t slots = (after - next_ns) / period + 1;
      ++overruns;
      skipped += static_cast<uint64_t>(slots);
      next_ns += slots * period;
    }
    next = to_timespec(next_ns);
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
  }
  drain_messages(messages);
  const CyclicStatus& s = m.cyclic_status();
  std::printf("run: %lld cycles, %llu SYNC, inputs fresh in %.1f %% of cycles, %u TPDOs missed, %u send errors, "
              "%llu overruns (%llu SYNC slots skipped)\n",
              static_cast<long long>(cycles), static_cast<unsigned long long>(s.sync_serial),
              cycles ? 100.0 * static_cast<double>(fresh) / static_cast<double>(cycles) : 0.0, s.pdo_missed, s.send_errors,
              static_cast<unsigned long long>(overruns), static_cast<unsigned long long>(skipped));
  bool ok = true;
  for (const Track& t : tracks) {
    std::printf("node %u: feedback matched a command in %llu cycles (exactly 2 cycles late in %llu, later in %llu)\n", t.id,
                static_cast<unsigned long long>(t.matches), static_cast<unsigned long long>(t.exact_delay),
                static_cast<unsigned long long>(t.stale));
    if (t.future) {
      std::printf("node %u: %llu feedback values came back sooner than the transport delay allows\n", t.id,
                  static_cast<unsigned long long>(t.future));
      ok = false;
    }
    if (t.matches < static_cast<uint64_t>(cycles) / 2) ok = false;
  }
  for (std::size_t i = 0; i < m.node_count(); ++i) {
    const NodeStatus st = m.node_status_at(i);
    if (!st.operational || st.fault) {
      std::printf("node %u: %s%s\n", st.id, to_string(st.state), st.fault ? ", fault" : "");
      ok = false;
    }
  }
  return ok ? 0 : 1;
}

int run_sdo(const std::string& iface, uint8_t node, const std::function<void(SdoClient&, SdoClient::Done)>& start,
            SdoResult& out) {
  auto t = can::open_transport(iface);
  const can::Filter f[] = {can::Filter::exact(cob::sdo_response(node))};
  t->set_filters(f);
  t->set_error_reports(false);
  SdoClientOptions o;
  o.timeout_ns = 1'000'000'000;
  SdoClient client(*t, node, o);
  bool done = false;
  start(client, [&](const SdoResult& r) {
    out = r;
    done = true;
  });
  while (!done) {
    const int64_t now = monotonic_ns();
    can::Frame fr;
    while (t->receive(fr)) client.on_frame(fr, now);
    client.poll(now);
    if (!done) t->wait(1'000'000);
  }
  return out.ok() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  std::vector<std::string> args(argv + 2, argv + argc);
  try {
    if (cmd == "load" || cmd == "boot") {
      if (args.empty()) return usage();
      const auto ini = ini::IniFile::load(args[0]);
      std::string section = "CANOPEN";
      double run_s = 0;
      std::optional<std::pair<ObjectAddress, ObjectAddress>> echo;
      for (std::size_t i = 1; i < args.size(); ++i) {
        if (args[i] == "--run-s" && i + 1 < args.size()) {
          run_s = parse_double(args[++i]).value_or(0);
        } else if (args[i] == "--echo" && i + 1 < args.size()) {
          const std::string v = args[++i];
          const auto eq = v.find('=');
          const auto a = parse_addr(v.substr(0, eq));
          const auto b = eq == std::string::npos ? std::nullopt : parse_addr(v.substr(eq + 1));
          if (!a || !b) return usage();
          echo = std::make_pair(*a, *b);
        } else if (args[i].rfind("--", 0) != 0) {
          section = args[i];
        } else {
          return usage();
        }
      }
      const BusConfig c = load_bus_config(ini, section, "canopen.0");
      return cmd == "load" ? cmd_load(c) : cmd_boot(c, run_s, echo);
    }
    if (cmd == "read" || cmd == "write") {
      if (args.size() < (cmd == "read" ? 3u : 4u)) return usage();
      const auto node = parse_uint(args[1]);
      if (!node || !is_valid_node_id(static_cast<unsigned>(*node)) || *node > 127) return usage();
      SdoMode mode = SdoMode::Auto;
      for (const auto& a : args) {
        if (a == "--block") mode = SdoMode::Block;
        if (a == "--segmented") mode = SdoMode::Segmented;
      }
      SdoResult r;
      int rc;
      if (cmd == "read") {
        const auto a = parse_addr(args[2]);
        if (!a) return usage();
        rc = run_sdo(args[0], static_cast<uint8_t>(*node), [&](SdoClient& c, SdoClient::Done d) { c.upload(*a, d, mode); }, r);
        if (rc == 0) {
          std::string hex, text;
          bool printable = !r.data.empty();
          for (uint8_t b : r.data) {
            char buf[4];
            std::snprintf(buf, sizeof buf, "%02X ", b);
            hex += buf;
            printable = printable && b >= 0x20 && b < 0x7F;
          }
          std::printf("%s", hex.c_str());
          if (r.data.size() <= 4) std::printf("(%u)", r.as<uint32_t>());
          if (printable && r.data.size() > 4) std::printf("\"%s\"", std::string(r.data.begin(), r.data.end()).c_str());
          std::printf("\n");
        }
      } else {
        std::string err;
        std::string value;
        for (std::size_t i = 3; i < args.size(); ++i) {
          if (args[i].rfind("--", 0) == 0) continue;
          value += (value.empty() ? "" : " ") + args[i];
        }
        const auto w = parse_sdo_write(args[2] + " " + value, nullptr, err);
        if (!w) {
          std::fprintf(stderr, "cnc-canopen: %s\n", err.c_str());
          return 2;
        }
        rc = run_sdo(args[0], static_cast<uint8_t>(*node),
                     [&](SdoClient& c, SdoClient::Done d) { c.download(w->addr, w->data, d, mode); }, r);
      }
      if (rc) std::fprintf(stderr, "cnc-canopen: node %llu: %s\n", static_cast<unsigned long long>(*node), r.message().c_str());
      return rc;
    }
    if (cmd == "nmt") {
      if (args.size() < 3) return usage();
      const std::map<std::string, NmtCommand> names = {{"start", NmtCommand::Start},
                                                        {"stop", NmtCommand::Stop},
                                                        {"preop", NmtCommand::EnterPreOperational},
                                                        {"reset", NmtCommand::ResetNode},
                                                        {"reset-comm", NmtCommand::ResetCommunication}};
      const auto it = names.find(args[1]);
      const auto node = parse_uint(args[2]);
      if (it == names.end() || !node || *node > 127) return usage();
      auto t = can::open_transport(args[0]);
      const can::SendStatus s = t->send(can::Frame::make(cob::kNmt, {static_cast<uint8_t>(it->second), static_cast<uint8_t>(*node)}));
      if (s != can::SendStatus::Ok) {
        std::fprintf(stderr, "cnc-canopen: %s\n", can::to_string(s));
        return 1;
      }
      return 0;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-canopen: %s\n", e.what());
    return 1;
  }
  return usage();
}
