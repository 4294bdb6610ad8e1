// Test bench: simulated CiA 402 drives on an in-process EtherCAT segment
// with a manual clock, the master on two in-process links, and one servo
// cycle stepped by hand (read, application, write, time advances by the
// period plus the DC lock's adjustment). The master's worker thread runs
// for real; the test yields briefly between cycles so that it can work.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "core/util/messages.hpp"
#include "fieldbus/ethercat/master.hpp"
#include "sim/ethercat/segment.hpp"
#include "tests/support/testing.hpp"

namespace cnc::ethercat::test {

struct Bus {
  explicit Bus(unsigned drives, MasterConfig cfg = {}, bool start = true, const sim::CoeDriveConfig& drive = {}) {
    segment = std::make_shared<sim::Segment>([this] { return time.load(); });
    segment->add_drives(drives, drive);
    name = cnc::testing::unique_name("ecat");
    cfg.interface = "sim:" + name;
    master = std::make_unique<Master>(cfg, &messages, sim::open_sim_link(segment, name), sim::open_sim_link(segment, name));
    if (start) start_up();
  }
  ~Bus() { master->stop(); }

  void start_up() {
    master->start_up();
    master->start_worker();
  }

  // One servo cycle; `app` runs between the master's read and write.
  void cycle(const std::function<void()>& app = {}, bool yield = true) {
    master->cyclic_read(time.load());
    if (app) app();
    master->cyclic_write(time.load());
    const int64_t adj = lock ? master->take_phase_adjust() : (master->take_phase_adjust(), 0);
    time.fetch_add(master->config().cycle_ns + adj);
    if (yield) std::this_thread::sleep_for(std::chrono::microseconds(30));
  }
  // Cycles until `done` (true) or `max` cycles (false).
  bool run_until(const std::function<bool()>& done, int max, const std::function<void()>& app = {}) {
    for (int i = 0; i < max; ++i) {
      if (done()) return true;
      cycle(app);
    }
    return done();
  }
  bool reach_op() {
    return run_until([&] { return master->is_operational() || master->has_fault(); }, 20000) && master->is_operational();
  }
  // Every message posted so far, one per line.
  std::string drain_messages() {
    Message m;
    while (messages.pop(m)) log += std::string(m.text.c_str()) + "\n";
    return log;
  }

  std::atomic<int64_t> time{1'000'000'000};
  bool lock = true;
  std::string name;
  std::string log;
  MessageQueue messages;
  std::shared_ptr<sim::Segment> segment;
  std::unique_ptr<Master> master;
};

}  // namespace cnc::ethercat::test
