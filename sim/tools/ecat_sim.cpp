// ecat-sim: simulated CiA 402 drives in a line behind an Ethernet interface
// (a real NIC or one end of a veth pair), answering EtherCAT frames like
// ESCs would, with optional fault injection once the drives are in OP.
// Every change of a slave's AL state and of a drive's CiA 402 state is
// printed ("ecat-sim: slave 2 OP -> INIT", "ecat-sim: drive 2 operation
// enabled -> quick stop active"), so tests can see how a master left them.
//
//   ecat-sim --iface ecs --drives 3 [--fault break:2|drop|wkc|refuse:<n>:<state>|sdo-abort:<n>:<index>]
//            [--fault-after-ms 1000] [--seconds 0] [--switches NEG,HOME_MIN,HOME_MAX,POS]
// --switches: every drive's table has limit switches at NEG and POS and a
// home switch over [HOME_MIN, HOME_MAX] (mm from where it powers up).
// --reversed K: drive K's motor is mounted the other way round (what a
// commissioning direction test finds).
#include <sched.h>
#include <signal.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "fieldbus/ethercat/link.hpp"
#include "fieldbus/ethercat/protocol.hpp"
#include "sim/ethercat/segment.hpp"

using namespace cnc::ethercat;

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "ecat-sim: %s\nusage: ecat-sim --iface IF [--drives N] [--fault break:K|drop|wkc|refuse:K:STATE|"
               "sdo-abort:K:INDEX] [--fault-after-ms MS] [--seconds S] [--switches NEG,HOME_MIN,HOME_MAX,POS] [--reversed K]\n",
               why);
  std::exit(2);
}

AlState parse_state(const std::string& s) {
  if (s == "PREOP") return AlState::PreOp;
  if (s == "SAFEOP") return AlState::SafeOp;
  if (s == "OP") return AlState::Op;
  usage(("unknown state " + s).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  std::string iface, fault;
  unsigned drives = 3;
  int64_t fault_after_ms = 1000, seconds = 0;
  sim::CoeDriveConfig base;
  std::vector<unsigned> reversed;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + a).c_str());
      return argv[++i];
    };
    if (a == "--iface") iface = value();
    else if (a == "--drives") drives = static_cast<unsigned>(std::stoul(value()));
    else if (a == "--fault") fault = value();
    else if (a == "--fault-after-ms") fault_after_ms = std::stoll(value());
    else if (a == "--seconds") seconds = std::stoll(value());
    else if (a == "--reversed") reversed.push_back(static_cast<unsigned>(std::stoul(value())));
    else if (a == "--switches") {
      double mm[4];
      const std::string v = value();
      if (std::sscanf(v.c_str(), "%lf,%lf,%lf,%lf", &mm[0], &mm[1], &mm[2], &mm[3]) != 4 || !(mm[0] < mm[1]) ||
          !(mm[1] < mm[2]) || !(mm[2] < mm[3]))
        usage(("--switches " + v + ": expected NEG,HOME_MIN,HOME_MAX,POS in mm, increasing").c_str());
      auto& p = base.drive.plant;
      p.neg_limit = mm[0] / 1000, p.home_min = mm[1] / 1000, p.home_max = mm[2] / 1000, p.pos_limit = mm[3] / 1000;
    }
    else usage(("unknown option " + a).c_str());
  }
  if (iface.empty()) usage("--iface is required");
  if (drives < 1 || drives > 64) usage("--drives must be 1..64");
  sched_param sp{};
  sp.sched_priority = 70;  // answer like hardware would, when permitted
  (void)sched_setscheduler(0, SCHED_FIFO, &sp);
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);

  auto seg = std::make_shared<sim::Segment>();
  for (unsigned k : reversed)
    if (k < 1 || k > drives) usage("--reversed K needs 1 <= K <= drives");
  for (unsigned k = 1; k <= drives; ++k) {
    sim::CoeDriveConfig c = base;
    c.drive.motor_reversed = std::find(reversed.begin(), reversed.end(), k) != reversed.end();
    seg->add_drives(1, c);
  }
  std::unique_ptr<Link> link;
  try {
    link = open_raw_link(iface);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ecat-sim: %s\n", e.what());
    return 1;
  }
  // Faults present from the start.
  bool timed = false;
  if (fault.rfind("refuse:", 0) == 0) {
    const auto c1 = fault.find(':', 7);
    const unsigned k = static_cast<unsigned>(std::stoul(fault.substr(7, c1 - 7)));
    if (k < 1 || k > drives || c1 == std::string::npos) usage("refuse:K:STATE needs 1 <= K <= drives");
    seg->slave(k - 1).refuse_state(parse_state(fault.substr(c1 + 1)), al::kSyncError);
  } else if (fault.rfind("sdo-abort:", 0) == 0) {
    const auto c1 = fault.find(':', 10);
    const unsigned k = static_cast<unsigned>(std::stoul(fault.substr(10, c1 - 10)));
    if (k < 1 || k > drives || c1 == std::string::npos) usage("sdo-abort:K:INDEX needs 1 <= K <= drives");
    seg->drive(k - 1)->abort_sdo(static_cast<uint16_t>(std::stoul(fault.substr(c1 + 1), nullptr, 0)), 0x06090030);
  } else if (!fault.empty()) {
    timed = true;
  }
  std::fprintf(stderr, "ecat-sim: %u drive%s on %s%s%s\n", drives, drives == 1 ? "" : "s", iface.c_str(),
               fault.empty() ? "" : ", fault ", fault.c_str());
  uint8_t buf[kMaxFrame];
  const int64_t start = now_ns();
  int64_t all_op_since = -1, last_poll = 0;
  bool injected = false;
  uint64_t frames = 0;
  std::vector<AlState> al_seen(seg->size(), AlState::Init);
  std::vector<cnc::cia402::State> drive_seen(seg->size(), cnc::cia402::State::NotReadyToSwitchOn);
  auto report_changes = [&] {
    for (std::size_t i = 0; i < seg->size(); ++i) {
      const AlState al = seg->slave(i).state();
      if (al != al_seen[i]) {
        std::fprintf(stderr, "ecat-sim: slave %zu %s -> %s\n", i + 1, al_state_name(static_cast<uint8_t>(al_seen[i])),
                     al_state_name(static_cast<uint8_t>(al)));
        al_seen[i] = al;
      }
      if (sim::CoeDrive* d = seg->drive(i)) {
        const cnc::cia402::State st = d->model().state();
        if (st != drive_seen[i]) {
          std::fprintf(stderr, "ecat-sim: drive %zu %s -> %s\n", i + 1, cnc::cia402::to_string(drive_seen[i]),
                       cnc::cia402::to_string(st));
          drive_seen[i] = st;
        }
      }
    }
  };
  while (!g_stop) {
    const int64_t t = now_ns();
    if (seconds > 0 && t - start > seconds * 1'000'000'000) break;
    const std::size_t n = link->receive(buf, 1'000'000);
    if (n > 0 && seg->process(buf, n)) {
      ++frames;
      link->send(buf, n);
    }
    const int64_t t2 = now_ns();
    if (t2 - last_poll > 500'000) {
      seg->poll();
      last_poll = t2;
      report_changes();
      bool all_op = true;
      for (std::size_t i = 0; i < seg->size(); ++i) all_op = all_op && seg->slave(i).state() == AlState::Op;
      if (all_op && all_op_since < 0) all_op_since = t2;
      if (timed && !injected && all_op_since >= 0 && t2 - all_op_since > fault_after_ms * 1'000'000) {
        injected = true;
        std::fprintf(stderr, "ecat-sim: injecting %s\n", fault.c_str());
        if (fault.rfind("break:", 0) == 0) seg->break_after(static_cast<unsigned>(std::stoul(fault.substr(6))));
        else if (fault == "drop") seg->drop_frames(~0u);
        else if (fault == "wkc") seg->corrupt_wkc(1'000'000, -1);
        else std::fprintf(stderr, "ecat-sim: unknown fault %s (ignored)\n", fault.c_str());
      }
    }
  }
  std::fprintf(stderr, "ecat-sim: %llu frames answered\n", static_cast<unsigned long long>(frames));
  return 0;
}
