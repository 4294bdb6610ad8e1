// The master's heartbeat and SYNC under host load (issue 16: drives faulted
// with 0x8130 when load starved the normal-priority thread that sent the
// heartbeat). Production code throughout: the CANopen master (servo cycle
// in an rt::PeriodicTask, SCHED_FIFO when allowed; its acyclic thread at
// normal priority) and simulated CiA 402 drives (cia402/sim SimHost, their
// own thread, each drive a controller of its own, 0x1016 watching the
// master), on an in-process virtual bus in real time. Busy threads at
// normal priority load every core. Prints the heartbeat and SYNC intervals
// seen on the bus, how late the acyclic thread ran (what the heartbeat's
// timing was before it moved into the servo thread), the drives'
// heartbeat-consumer trips, and then, with the servo cycle stopped, how
// long each drive takes to notice. Prints figures; never fails on them.
//   canopen_heartbeat_load [seconds=10] [busy_threads=4] [drives=3]
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"
#include "core/ini/ini_file.hpp"
#include "core/rt/periodic_task.hpp"
#include "core/util/messages.hpp"
#include "core/util/time.hpp"
#include "sim/can/virtual_bus.hpp"
#include "fieldbus/canopen/config.hpp"
#include "fieldbus/canopen/master.hpp"

using namespace cnc;

namespace {

std::string machine_ini(int drives) {
  std::string nodes, sim;
  for (int i = 1; i <= drives; ++i) nodes += " " + std::to_string(i);
  std::string text = "[EMCMOT]\nSERVO_PERIOD = 1000000\n\n[CANOPEN]\nINTERFACE = virtual:hbload\nNODE =" + nodes +
                     "\nMASTER_HEARTBEAT_MS = 100\nMAX_BUS_LOAD = 100\n";
  for (int i = 1; i <= drives; ++i) {
    const std::string n = std::to_string(i);
    text += "\n[CANOPEN_NODE_" + n + "]\nNAME = axis-" + n +
            "\nHEARTBEAT_MS = 100\nMASTER_HEARTBEAT_TIMEOUT_MS = 250\n"
            "RPDO1 = 0x6040:0:u16 0x607A:0:s32\nTPDO1 = 0x6041:0:u16 0x6064:0:s32\n";
  }
  text += "\n[CIA402_SIM]\nINTERFACE = virtual:hbload\nNODE =" + nodes + "\n";
  for (int i = 1; i <= drives; ++i) text += "\n[CIA402_SIM_NODE_" + std::to_string(i) + "]\nNAME = axis-" + std::to_string(i) + "\n";
  return text;
}

void set_fifo(int priority) {
  if (std::getenv("CNC_NO_REALTIME")) return;
  sched_param p{};
  p.sched_priority = priority;
  pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
}

struct Series {
  std::vector<int64_t> v;
  void add(int64_t x) { v.push_back(x); }
  int64_t q(double f) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(f * static_cast<double>(v.size() - 1) + 0.5))];
  }
  void print(const char* what) {
    std::printf("  %-34s n %6zu  median %8.3f ms  p99 %8.3f ms  max %8.3f ms\n", what, v.size(), q(0.5) / 1e6, q(0.99) / 1e6,
                q(1.0) / 1e6);
  }
};

// The servo thread's functions for the bus.
struct Servo {
  canopen::Master* master = nullptr;
  static void cycle(void* arg, const rt::CycleInfo& info) {
    auto* s = static_cast<Servo*>(arg);
    s->master->cyclic_read(info.now_ns);
    s->master->cyclic_write(info.now_ns);
  }
};

}  // namespace

int main(int argc, char** argv) {
  const double seconds = argc > 1 ? std::atof(argv[1]) : 10.0;
  const int busy = argc > 2 ? std::atoi(argv[2]) : 4;
  const int drives = argc > 3 ? std::clamp(std::atoi(argv[3]), 1, 8) : 3;
  const auto& caps = rt::prepare_process();

  const ini::IniFile ini = ini::IniFile::parse(machine_ini(drives), "heartbeat_load.ini");
  can::VirtualBusOptions bo;
  bo.manual_clock = false;  // real time
  auto bus = can::VirtualBus::named("hbload", bo);
  auto host_port = bus->open_port("sim");
  cia402::sim::SimHost host(*host_port);
  for (const auto& n : cia402::sim::load_sim_config(ini, "CIA402_SIM").nodes) {
    host.add(n, bus->open_port("sim-" + std::to_string(n.node_id)));
  }
  auto sniffer = bus->open_port("sniffer");
  std::vector<can::Filter> watch = {can::Filter::exact(0x77F), can::Filter::exact(0x080)};
  for (int i = 1; i <= drives; ++i) watch.push_back(can::Filter::exact(0x080 + static_cast<uint32_t>(i)));  // EMCY
  sniffer->set_filters(watch);
  sniffer->set_error_reports(false);

  MessageQueue messages;
  canopen::Master master(canopen::load_bus_config(ini, "CANOPEN", "canopen.0"), &messages);
  host.start();
  master.start_thread();
  master.boot();

  Servo servo{&master};
  rt::PeriodicTask task;
  task.start({"servo", 1'000'000, -1}, &Servo::cycle, &servo);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the cycle takes the heartbeat over

  // The observer: above the load, below the servo thread and the drives.
  // It reads the bus (heartbeat, SYNC, the drives' EMCY 0x8130 = a tripped
  // heartbeat consumer) and samples how long ago the acyclic thread ran.
  Series hb, sync, acyclic_lag;
  std::atomic<bool> loaded{false}, stop_watch{false};
  std::atomic<int64_t> last_hb{-1};
  std::vector<int64_t> trips_loaded, trips_after;  // EMCY 0x8130 times, the first per drive
  std::vector<uint32_t> tripped;
  std::thread watcher([&] {
    set_fifo(50);
    int64_t last_sync = -1;
    while (!stop_watch.load(std::memory_order_relaxed)) {
      const bool measuring = loaded.load(std::memory_order_relaxed);
      can::Frame f;
      while (sniffer->receive(f)) {
        if (f.id == 0x77F) {
          if (measuring && last_hb.load() >= 0) hb.add(f.timestamp_ns - last_hb.load());
          last_hb.store(f.timestamp_ns);
        } else if (f.id == 0x080) {
          if (measuring && last_sync >= 0) sync.add(f.timestamp_ns - last_sync);
          last_sync = f.timestamp_ns;
        } else if (f.len >= 2 && (f.data[0] | f.data[1] << 8) == 0x8130 &&
                   std::find(tripped.begin(), tripped.end(), f.id) == tripped.end()) {
          tripped.push_back(f.id);  // the node's EMCY, then the drive's fault EMCY: count the drive once
          (task.is_running() ? trips_loaded : trips_after).push_back(f.timestamp_ns);
        }
      }
      if (measuring) acyclic_lag.add(master.bus_now_ns() - master.last_poll_ns());
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });

  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the watcher has read what queued up before

  // Load: busy threads at normal priority, as many as asked, on every core.
  std::atomic<bool> stop_load{false};
  std::vector<std::thread> load;
  for (int i = 0; i < busy; ++i) {
    load.emplace_back([&] {
      volatile uint64_t x = 0;
      while (!stop_load.load(std::memory_order_relaxed)) x = x + 1;
    });
  }
  loaded.store(true);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  loaded.store(false);
  stop_load.store(true);
  for (auto& t : load) t.join();
  const auto s = task.stats().snapshot();
  const canopen::CyclicStatus cs = master.cyclic_status();  // the servo thread still runs: a snapshot

  // Then the servo cycle stops while the acyclic thread runs on.
  task.stop();
  const int64_t last_before_stop = last_hb.load();
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  stop_watch.store(true);
  watcher.join();
  host.stop();
  master.stop_thread();

  std::printf("CANopen master heartbeat and SYNC under load: %d drives, %.1f s, %d busy threads at normal priority on %u cores\n",
              drives, seconds, busy, std::thread::hardware_concurrency());
  std::printf("  servo thread: %s, memory %s; wake-up latency median %.1f us, max %.1f us; overruns %" PRIu64 " of %" PRIu64 "\n",
              task.uses_fifo() ? "SCHED_FIFO" : "normal scheduling", caps.memory_locked ? "locked" : "not locked",
              static_cast<double>(s.latency_percentile_ns(0.5)) / 1e3, static_cast<double>(s.latency_max_ns) / 1e3,
              s.overruns, s.cycles);
  if (!caps.note.empty()) std::printf("  note: %s\n", caps.note.c_str());
  std::printf("  cyclic frames refused by the transport: %u\n", cs.send_errors);
  hb.print("master heartbeat interval (100 ms)");
  sync.print("SYNC interval (1 ms)");
  acyclic_lag.print("acyclic thread: time since its step");
  std::printf("  drives' heartbeat-consumer trips (EMCY 0x8130) under load: %zu (0x1016:1 = 250 ms)\n", trips_loaded.size());
  std::printf("  servo cycle stopped, acyclic thread running: %zu of %d drives tripped;", trips_after.size(), drives);
  for (int64_t t : trips_after) std::printf(" %.1f", static_cast<double>(t - last_before_stop) / 1e6);
  std::printf(" ms after the last heartbeat\n");
  Message m;
  int shown = 0;
  while (messages.pop(m)) {
    if (m.kind == MessageKind::Error && shown++ < 5) std::printf("  message: %s: %s\n", m.source.c_str(), m.text.c_str());
  }
  return 0;
}
