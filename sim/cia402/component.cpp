#include "sim/cia402/component.hpp"

#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <climits>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"
#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/service.hpp"
#include "core/ipc/status.hpp"
#include "core/rt/periodic_task.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "sim/can/bus_share.hpp"
#include "sim/can/virtual_bus.hpp"

namespace cnc::cia402::sim {
namespace {

using hal::PinDir;
constexpr int64_t kBusStepNs = 20'000;

struct NodePins {
  hal::FloatPin table_position, ferror, temperature;
  hal::S32Pin state;
  hal::BitPin probe_in, probe_level;
  bool last_probe = false;
};

long futex_wait(std::atomic<uint32_t>* word, uint32_t expected, int64_t timeout_ns) noexcept {
  const timespec ts = to_timespec(timeout_ns < 0 ? 0 : timeout_ns);
  return ::syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), FUTEX_WAIT_PRIVATE, expected, &ts, nullptr, 0);
}
void futex_wake(std::atomic<uint32_t>* word) noexcept {
  ::syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
}

// One section's drives. CLOCK = SERVO: they live on an in-process virtual
// bus whose clock this component advances: in real time until the servo
// thread first calls update(), then exactly one servo period per servo
// cycle, in small steps (frames, arbitration and bit times as ever, but in
// a time that a loaded host cannot stretch). The servo thread only asks for
// the period (requested_ns); the component's stepper thread simulates it,
// so the bus engine and the drives never run in the servo thread. A thread
// stepped by hand (tests: CycleInfo::periodic false) simulates the period
// inline instead, deterministically. CLOCK = REALTIME: a thread of their own
// on any interface, in wall-clock time.
struct SimBus {
  enum Mode : int { kRealTime, kStepper, kInline };

  std::shared_ptr<can::VirtualBus> vbus;  // SERVO clock only
  std::unique_ptr<can::Transport> transport;
  std::unique_ptr<SimHost> host;
  std::vector<NodePins> pins;
  int64_t origin_ns = 0;                    // CLOCK_MONOTONIC at bus time 0 (real-time clock)
  std::atomic<int> mode{kRealTime};         // set once by the servo thread's first update()
  // [section]STEPPER: a servo thread on its own clock leaves the periods to
  // the stepper thread (true) or simulates them inline (false).
  bool stepper_when_periodic = true;
  std::atomic<int64_t> requested_ns{0};     // bus time asked for since then (servo thread)
  std::atomic<int64_t> done_ns{0};          // of it, simulated
  std::atomic<uint64_t> late{0};            // periods asked for before the previous was simulated
  std::atomic<uint64_t> helped{0};          // of them, simulated by the servo thread (the stepper had not started)
  std::atomic_flag busy = ATOMIC_FLAG_INIT; // a thread advances the bus (held by a real-time pass or a catch-up)
  int64_t base_ns = -1;                     // bus time at the first request
  class Stepper* stepper = nullptr;         // set before the HAL threads start

  // Servo thread, once per cycle (cia402-sim.<g>.update, after the bus's write).
  void update(const rt::CycleInfo& info) noexcept;

  void publish() noexcept {
    for (std::size_t i = 0; i < pins.size(); ++i) {
      NodePins& p = pins[i];
      DriveModel& m = host->at(i).model();
      p.table_position.set(m.plant().table_position() * 1000.0);
      p.ferror.set(m.following_error());
      p.temperature.set(m.temperature());
      p.state.set(static_cast<int32_t>(m.state()));
      p.probe_level.set(m.plant().probe_position_input());
      const bool probe = p.probe_in.get();
      if (probe != p.last_probe) m.plant().set_probe_override(probe);
      p.last_probe = probe;
    }
  }
  void advance_to(int64_t t, bool real_time) noexcept {
    while (vbus->now_ns() < t) {
      if (real_time && mode.load(std::memory_order_acquire) != kRealTime) return;
      vbus->advance(std::min(kBusStepNs, t - vbus->now_ns()));
      host->step(vbus->now_ns());
    }
  }
  // The stepper, before the servo thread takes over: bus time follows the
  // wall clock (the boot).
  void real_time_pass() noexcept {
    if (busy.test_and_set(std::memory_order_acquire)) return;
    advance_to(monotonic_ns() - origin_ns, true);
    busy.clear(std::memory_order_release);
  }
  // Simulates what the servo thread has asked for, unless another thread
  // is at it (never waits); false: nothing done.
  bool try_catch_up() noexcept {
    if (busy.test_and_set(std::memory_order_acquire)) return false;
    const bool worked = catch_up();
    busy.clear(std::memory_order_release);
    return worked;
  }
  // The same, by the one thread that advances the bus.
  bool catch_up() noexcept {
    const int64_t asked = requested_ns.load(std::memory_order_acquire);
    if (base_ns < 0) base_ns = vbus->now_ns();  // from where the real-time clock left the bus
    if (vbus->now_ns() >= base_ns + asked) return false;
    advance_to(base_ns + asked, false);
    done_ns.store(asked, std::memory_order_release);
    return true;
  }
};

// The thread that simulates the SERVO-clocked buses of one cia402_sim, in
// step with the servo thread: it brings every bus to the time update()
// asked for, then sleeps until the next request is due (the servo thread's
// grid, from the last request) and looks again, every kPollNs for up to one
// more period. The servo thread only writes atomics: it makes a system call
// (a futex wake) only when the stepper has given up polling and sleeps
// (after a stall of the servo thread, or before its first cycle), counted
// in wakes(), and simulates only periods the stepper has not started in
// time (SimBus::update). SCHED_FIFO just below the servo thread when permitted, so
// that the drives answer each SYNC before the next cycle reads. Its own
// execution time is published apart from the servo thread's.
class Stepper {
 public:
  static constexpr int64_t kPollNs = 20'000;

  explicit Stepper(std::vector<SimBus*> buses) : buses_(std::move(buses)) {
    thread_ = std::thread([this] { run(); });
  }
  ~Stepper() {
    stop_.store(true);
    seq_.fetch_add(1);
    futex_wake(&seq_);
    thread_.join();
  }
  // Servo thread: a bus was asked for more time; the next request is
  // expected at `next_ns` (CLOCK_MONOTONIC). Never blocks.
  void notify(int64_t next_ns, int64_t period_ns) noexcept {
    next_request_ns_.store(next_ns, std::memory_order_relaxed);
    period_ns_.store(period_ns, std::memory_order_relaxed);
    seq_.fetch_add(1);
    if (sleeping_.exchange(false)) {
      wakes_.fetch_add(1, std::memory_order_relaxed);
      futex_wake(&seq_);
    }
  }
  // Fault injection (`cnc inject "stepper hold" 1`): the stepper simulates
  // nothing, as when a loaded host does not schedule it. Returns once the
  // stepper has stopped (at most 1 s; false if it did not).
  bool hold(bool on) {
    hold_.store(on);
    if (!on) return true;
    seq_.fetch_add(1);
    futex_wake(&seq_);
    for (int i = 0; i < 10'000 && !held_.load(); ++i) std::this_thread::sleep_for(std::chrono::microseconds(100));
    return held_.load();
  }
  uint64_t steps() const noexcept { return steps_.load(std::memory_order_relaxed); }
  uint64_t wakes() const noexcept { return wakes_.load(std::memory_order_relaxed); }
  int64_t exec_last_ns() const noexcept { return exec_last_ns_.load(std::memory_order_relaxed); }
  int64_t exec_max_ns() const noexcept { return exec_max_ns_.load(std::memory_order_relaxed); }

 private:
  void run() {
    pthread_setname_np(pthread_self(), "cia402-sim");
    if (rt::prepare_process().fifo_scheduling) {
      sched_param p{};
      p.sched_priority = sched_get_priority_max(SCHED_FIFO) - 2;  // the servo thread runs at max - 1
      pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
    }
    while (!stop_.load()) {
      const uint32_t seen = seq_.load();
      if (hold_.load()) {
        held_.store(true);
        futex_wait(&seq_, seen, 1'000'000);
        continue;
      }
      held_.store(false);
      bool real_time = false, worked = false;
      const int64_t t0 = monotonic_ns();
      for (SimBus* b : buses_) {
        switch (b->mode.load(std::memory_order_acquire)) {
          case SimBus::kRealTime: b->real_time_pass(); real_time = true; break;
          case SimBus::kStepper: worked = b->try_catch_up() || worked; break;
          default: break;  // stepped inline by the caller of update()
        }
      }
      if (worked) {
        const int64_t dt = monotonic_ns() - t0;
        exec_last_ns_.store(dt, std::memory_order_relaxed);
        if (dt > exec_max_ns_.load(std::memory_order_relaxed)) exec_max_ns_.store(dt, std::memory_order_relaxed);
        steps_.fetch_add(1, std::memory_order_relaxed);
        continue;  // more may have been asked for meanwhile
      }
      if (real_time) {
        futex_wait(&seq_, seen, 200'000);  // the boot's real-time clock: a pass every 200 us
        continue;
      }
      wait_for_request(seen);
    }
  }
  // Until seq_ moves past `seen`: polls around the expected request, then
  // sleeps until the servo thread wakes it.
  void wait_for_request(uint32_t seen) noexcept {
    const int64_t next = next_request_ns_.load(std::memory_order_relaxed);
    const int64_t give_up = next + period_ns_.load(std::memory_order_relaxed);
    while (seq_.load() == seen && !stop_.load()) {
      const int64_t now = monotonic_ns();
      if (next == 0 || now >= give_up) break;
      const timespec ts = to_timespec(std::max(next, now + kPollNs));
      clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    }
    if (seq_.load() != seen || stop_.load()) return;
    sleeping_.store(true);
    // A request between the check above and here finds sleeping_ set and
    // wakes the futex, or has moved seq_ so that the wait returns at once.
    if (seq_.load() == seen && !stop_.load()) futex_wait(&seq_, seen, 100'000'000);
    sleeping_.store(false);
  }

  std::vector<SimBus*> buses_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint32_t> seq_{0};     // bumped by every request (the futex word)
  std::atomic<bool> sleeping_{false};
  std::atomic<bool> hold_{false}, held_{false};  // injected: asked to stop, stopped
  std::atomic<int64_t> next_request_ns_{0}, period_ns_{0};
  std::atomic<uint64_t> steps_{0}, wakes_{0};
  std::atomic<int64_t> exec_last_ns_{0}, exec_max_ns_{0};
};

// The first call decides who simulates: the stepper thread when the servo
// thread runs on its own clock (this call helps only when the stepper has
// not started the previous period), this call itself when the thread is
// stepped by hand (deterministic tests). Either way one period of bus time
// per call.
void SimBus::update(const rt::CycleInfo& info) noexcept {
  int m = mode.load(std::memory_order_relaxed);
  if (m == kRealTime) {
    m = info.periodic && stepper_when_periodic ? kStepper : kInline;
    mode.store(m, std::memory_order_release);
    if (m == kInline) {
      // Take the bus over from the stepper's real-time clock: its pass ends
      // within one bus step now that the mode is set. A thread stepped by
      // hand is no real-time one: waiting here, once, costs nothing.
      while (busy.test_and_set(std::memory_order_acquire)) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));
      }
      busy.clear(std::memory_order_release);
    }
  }
  const int64_t asked = requested_ns.load(std::memory_order_relaxed);
  if (m == kInline) {
    requested_ns.store(asked + info.period_ns, std::memory_order_relaxed);
    catch_up();
    return;
  }
  requested_ns.store(asked + info.period_ns, std::memory_order_release);
  if (done_ns.load(std::memory_order_acquire) < asked) {
    // The previous period's answers missed this cycle's read. If the
    // stepper has not even started it (not scheduled: a loaded host
    // without SCHED_FIFO), simulate it and this one here, so that the next
    // read is on time again and the drives' feedback never lags more than
    // a cycle; if it is at it, leave it (never wait).
    late.fetch_add(1, std::memory_order_relaxed);
    if (try_catch_up()) helped.fetch_add(1, std::memory_order_relaxed);
  }
  // The next cycle's request: one period after this one on the thread's
  // grid (this cycle's wake-up latency taken out).
  stepper->notify(monotonic_ns() - info.wake_latency_ns + info.period_ns, info.period_ns);
}

bool is_virtual(const std::string& interface) { return starts_with_icase(trim(interface), "virtual:"); }

class SimComponent : public hal::Component, public ipc::ControllerService {
 public:
  SimComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "cia402-sim") {
    mark_as_simulation();
    args.allow_only({"sections"});
    if (!ctx.ini) throw hal::HalError("cia402_sim: needs the INI file (its [CIA402_SIM] sections describe the drives)");
    const auto sections = split(args.get_string("sections", "CIA402_SIM"), ',', true);
    for (std::size_t g = 0; g < sections.size(); ++g) {
      const std::string section(trim(sections[g]));
      const SimBusConfig cfg = load_sim_config(*ctx.ini, section);
      const std::string clock = to_upper(ctx.ini->get_string(section, "CLOCK", is_virtual(cfg.interface) ? "SERVO" : "REALTIME"));
      auto bus = std::make_unique<SimBus>();
      if (clock == "SERVO") {
        if (!is_virtual(cfg.interface)) {
          ctx.ini->fail(ctx.ini->find_entry(section, "CLOCK"), "CLOCK = SERVO needs a virtual:<bus> INTERFACE");
        }
        open_servo_clocked(*bus, cfg, section);
        // The stepper only helps when it is scheduled at once: with
        // SCHED_FIFO (one below the servo thread). Under normal scheduling a
        // stepper preempted half-way through a period leaves the drives'
        // feedback cycles behind (following errors on a loaded host); the
        // servo thread then simulates inline, as a stall it shares.
        const std::string stepper = to_upper(ctx.ini->get_string(section, "STEPPER", "AUTO"));
        if (stepper == "AUTO") {
          bus->stepper_when_periodic = rt::prepare_process().fifo_scheduling;
        } else if (stepper == "THREAD" || stepper == "INLINE") {
          bus->stepper_when_periodic = stepper == "THREAD";
        } else {
          ctx.ini->fail(ctx.ini->find_entry(section, "STEPPER"), "expected AUTO, THREAD or INLINE");
        }
      } else if (clock == "REALTIME") {
        try {
          bus->transport = can::open_transport(cfg.interface);
        } catch (const std::exception& e) {
          throw hal::HalError("cia402_sim: [" + section + "]INTERFACE: " + e.what());
        }
        bus->host = std::make_unique<SimHost>(*bus->transport);
      } else {
        ctx.ini->fail(ctx.ini->find_entry(section, "CLOCK"), "expected SERVO or REALTIME");
      }
      const std::string prefix = "cia402-sim." + std::to_string(g);
      for (const SimNodeConfig& n : cfg.nodes) {
        // On the in-process bus each drive is a controller of its own, as
        // separate devices are: their frames meet in arbitration.
        if (bus->vbus) {
          auto port = bus->vbus->open_port("cia402-sim.node-" + std::to_string(n.node_id));
          port->set_tx_order(cfg.tx_fifo ? can::VirtualPort::TxOrder::Fifo : can::VirtualPort::TxOrder::Priority);
          bus->host->add(n, std::move(port));
        } else {
          bus->host->add(n);
        }
        char p[48];
        std::snprintf(p, sizeof p, "%s.node.%02u.", prefix.c_str(), n.node_id);
        const std::string s = p;
        NodePins np;
        np.table_position = make_pin<double>(s + "table-position", PinDir::Out);
        np.ferror = make_pin<double>(s + "following-error", PinDir::Out);
        np.temperature = make_pin<double>(s + "temperature", PinDir::Out);
        np.state = make_pin<int32_t>(s + "state", PinDir::Out);
        np.probe_in = make_pin<bool>(s + "probe-in", PinDir::In);
        np.probe_level = make_pin<bool>(s + "probe-level", PinDir::Out);
        bus->pins.push_back(np);
      }
      SimBus* b = bus.get();
      b->host->after_pass = [b] { b->publish(); };
      // Running from now on: the master loaded next boots these drives.
      if (b->vbus) {
        b->host->power_on(b->vbus->now_ns());
        b->host->set_stepped_elsewhere(true);
        b->origin_ns = monotonic_ns() - b->vbus->now_ns();
        hal().export_function(this, prefix + ".update",
                              [](void* a, const rt::CycleInfo& i) { static_cast<SimBus*>(a)->update(i); }, b);
      } else {
        b->host->start();
      }
      buses_.push_back(std::move(bus));
    }
    std::vector<SimBus*> stepped;
    for (auto& b : buses_) {
      if (b->vbus) stepped.push_back(b.get());
    }
    if (!stepped.empty()) {
      stepper_ = std::make_unique<Stepper>(stepped);  // the boot's real-time clock from now on
      for (SimBus* b : stepped) b->stepper = stepper_.get();
    }
  }
  ~SimComponent() override {
    stepper_.reset();
    for (auto& b : buses_) b->host->stop();
  }

  // The stepper's time, apart from the servo thread's (which shows only
  // the update functions: a request and a wake-up).
  void contribute_status(ipc::Status& status) override {
    if (!stepper_) return;
    for (ipc::SimulatorStatus& s : status.simulators) {
      if (!s.name.empty() && s.name.view() != name()) continue;
      s.name.assign(name());
      s.steps = stepper_->steps();
      s.wakes = stepper_->wakes();
      s.late_steps = 0;
      s.helped_steps = 0;
      for (const auto& b : buses_) {
        s.late_steps += b->late.load(std::memory_order_relaxed);
        s.helped_steps += b->helped.load(std::memory_order_relaxed);
      }
      s.exec_last_ns = stepper_->exec_last_ns();
      s.exec_max_ns = stepper_->exec_max_ns();
      return;
    }
  }

  bool is_simulator() const override { return true; }

  bool handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) override {
    if (cmd.type != ipc::CommandType::SimInject) return false;
    const std::string text(cmd.text.view());
    const auto words = split_blanks(text);
    if (words.size() == 2 && iequals(words[0], "stepper") && iequals(words[1], "hold")) {
      if (!stepper_) {
        reporter.report(cmd, ipc::CommandState::Rejected, "no bus of cia402_sim has CLOCK = SERVO");
      } else if (!stepper_->hold(cmd.d[0] != 0)) {
        reporter.report(cmd, ipc::CommandState::Rejected, "the stepper did not stop within 1 s");
      } else {
        reporter.report(cmd, ipc::CommandState::Done);
      }
      return true;
    }
    if (words.empty() || !iequals(words[0], "drive")) return false;  // another simulator's
    std::string why = "no simulated drive answers \"" + text + "\"";
    const int64_t node = words.size() > 1 ? parse_int(words[1]).value_or(0) : 0;
    for (auto& b : buses_) {
      if (node < 1 || node > 127 || !b->host->find(static_cast<uint8_t>(node))) continue;
      why = b->host->inject(text, cmd.d[0], cmd.d[0] != 0);
      break;
    }
    if (why.empty()) reporter.report(cmd, ipc::CommandState::Done);
    else reporter.report(cmd, ipc::CommandState::Rejected, why);
    return true;
  }

 private:
  void open_servo_clocked(SimBus& bus, const SimBusConfig& cfg, const std::string& section) {
    // virtual:<name>[,bitrate=N][,stuffing=...]: the bus must not exist yet
    // (load cia402_sim before the master), so that it gets a manual clock.
    const auto parts = split(std::string(trim(cfg.interface)).substr(8), ',');
    std::vector<std::string> options;
    for (std::size_t i = 1; i < parts.size(); ++i) options.emplace_back(trim(parts[i]));
    can::VirtualBusOptions o;
    try {
      o = can::parse_virtual_options(cfg.interface, options);
    } catch (const std::exception& e) {
      throw hal::HalError("cia402_sim: [" + section + "]INTERFACE: " + e.what());
    }
    o.manual_clock = true;
    const std::string name(trim(parts[0]));
    bus.vbus = can::VirtualBus::named(name, o);
    if (!bus.vbus->options().manual_clock) {
      throw hal::HalError("cia402_sim: [" + section + "]: the virtual bus \"" + name +
                          "\" already runs on the wall clock: load cia402_sim before the master (or CLOCK = REALTIME)");
    }
    if (o.share) {
      try {
        can::share_virtual_bus(bus.vbus, name, o.share_path.empty() ? can::default_share_path(name) : o.share_path);
      } catch (const std::exception& e) {
        throw hal::HalError("cia402_sim: [" + section + "]INTERFACE: " + e.what());
      }
    }
    bus.transport = bus.vbus->open_port("cia402-sim");
    bus.host = std::make_unique<SimHost>(*bus.transport);
  }

  std::vector<std::unique_ptr<SimBus>> buses_;
  std::unique_ptr<Stepper> stepper_;
};

}  // namespace

void register_sim_component(hal::ComponentRegistry& registry) {
  can::register_virtual_transport();  // INTERFACE = virtual:<bus> with CLOCK = REALTIME
  registry.add("cia402_sim",
               "simulated CiA 402 drives per INI section: sections=CIA402_SIM[,...] (in-process or on a CAN interface; "
               "function cia402-sim.N.update after the bus's write when CLOCK = SERVO)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimComponent>(ctx, args);
               });
}

}  // namespace cnc::cia402::sim
