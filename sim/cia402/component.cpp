#include "sim/cia402/component.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"
#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/service.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "sim/can/virtual_bus.hpp"

namespace cnc::cia402::sim {
namespace {

using hal::PinDir;
constexpr int64_t kBusStepNs = 20'000;

struct NodePins {
  hal::FloatPin table_position, ferror, temperature;
  hal::S32Pin state;
  hal::BitPin probe_in;
  bool last_probe = false;
};

// One section's drives. CLOCK = SERVO: they live on an in-process virtual
// bus whose clock this component advances, in real time until the servo
// thread calls update(), then exactly one servo period per servo cycle, in
// small steps (frames, arbitration and bit times as ever, but in a time
// that a loaded host cannot stretch). CLOCK = REALTIME: a thread of their
// own on any interface, in wall-clock time.
struct SimBus {
  std::shared_ptr<can::VirtualBus> vbus;  // SERVO clock only
  std::unique_ptr<can::Transport> transport;
  std::unique_ptr<SimHost> host;
  std::vector<NodePins> pins;
  std::thread clock;
  std::atomic<bool> stop{false}, servo_owns{false};
  std::atomic_flag busy = ATOMIC_FLAG_INIT;

  void publish() noexcept {
    for (std::size_t i = 0; i < pins.size(); ++i) {
      NodePins& p = pins[i];
      DriveModel& m = host->at(i).model();
      p.table_position.set(m.plant().table_position() * 1000.0);
      p.ferror.set(m.following_error());
      p.temperature.set(m.temperature());
      p.state.set(static_cast<int32_t>(m.state()));
      const bool probe = p.probe_in.get();
      if (probe != p.last_probe) m.plant().set_probe_override(probe);
      p.last_probe = probe;
    }
  }
  // `by_clock_thread`: stop as soon as the servo thread wants the clock.
  void advance_to(int64_t t, bool by_clock_thread) noexcept {
    while (vbus->now_ns() < t) {
      if (by_clock_thread && servo_owns.load(std::memory_order_acquire)) return;
      vbus->advance(std::min(kBusStepNs, t - vbus->now_ns()));
      host->step(vbus->now_ns());
    }
  }
  void run_clock() {
    const int64_t origin = monotonic_ns() - vbus->now_ns();
    while (!stop.load(std::memory_order_acquire) && !servo_owns.load(std::memory_order_acquire)) {
      if (!busy.test_and_set(std::memory_order_acquire)) {
        advance_to(monotonic_ns() - origin, true);
        busy.clear(std::memory_order_release);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  // Servo thread: one period of bus and drive time, every cycle. The first
  // call takes the clock over: the clock thread ends its pass within one bus
  // step once servo_owns is set, and this call waits for that, once (the
  // machine is idle then). Skipping cycles instead left the drives without
  // SYNC answers for as long as a preempted clock thread held the bus: 50
  // missed TPDOs in a row and a node fault, seen under load.
  void update(const rt::CycleInfo& info) noexcept {
    if (!servo_owns.load(std::memory_order_relaxed)) {
      servo_owns.store(true, std::memory_order_release);
      while (busy.test_and_set(std::memory_order_acquire)) {
        std::this_thread::sleep_for(std::chrono::microseconds(50));  // hand-over only: let the clock thread run
      }
      busy.clear(std::memory_order_release);
    }
    advance_to(vbus->now_ns() + info.period_ns, false);
  }
};

bool is_virtual(const std::string& interface) { return starts_with_icase(trim(interface), "virtual:"); }

class SimComponent : public hal::Component, public ipc::ControllerService {
 public:
  SimComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "cia402-sim") {
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
        if (bus->vbus) bus->host->add(n, bus->vbus->open_port("cia402-sim.node-" + std::to_string(n.node_id)));
        else bus->host->add(n);
        char p[48];
        std::snprintf(p, sizeof p, "%s.node.%02u.", prefix.c_str(), n.node_id);
        const std::string s = p;
        NodePins np;
        np.table_position = make_pin<double>(s + "table-position", PinDir::Out);
        np.ferror = make_pin<double>(s + "following-error", PinDir::Out);
        np.temperature = make_pin<double>(s + "temperature", PinDir::Out);
        np.state = make_pin<int32_t>(s + "state", PinDir::Out);
        np.probe_in = make_pin<bool>(s + "probe-in", PinDir::In);
        bus->pins.push_back(np);
      }
      SimBus* b = bus.get();
      b->host->after_pass = [b] { b->publish(); };
      // Running from now on: the master loaded next boots these drives.
      if (b->vbus) {
        b->host->power_on(b->vbus->now_ns());
        b->host->set_stepped_elsewhere(true);
        hal().export_function(this, prefix + ".update",
                              [](void* a, const rt::CycleInfo& i) { static_cast<SimBus*>(a)->update(i); }, b);
        b->clock = std::thread([b] { b->run_clock(); });
      } else {
        b->host->start();
      }
      buses_.push_back(std::move(bus));
    }
  }
  ~SimComponent() override {
    for (auto& b : buses_) {
      b->stop.store(true);
      if (b->clock.joinable()) b->clock.join();
      b->host->stop();
    }
  }

  bool is_simulator() const override { return true; }

  bool handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) override {
    if (cmd.type != ipc::CommandType::SimInject) return false;
    const std::string text(cmd.text.view());
    const auto words = split_blanks(text);
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
    bus.transport = bus.vbus->open_port("cia402-sim");
    bus.host = std::make_unique<SimHost>(*bus.transport);
  }

  std::vector<std::unique_ptr<SimBus>> buses_;
};

}  // namespace

void register_sim_component(hal::ComponentRegistry& registry) {
  registry.add("cia402_sim",
               "simulated CiA 402 drives per INI section: sections=CIA402_SIM[,...] (in-process or on a CAN interface; "
               "function cia402-sim.N.update after the bus's write when CLOCK = SERVO)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimComponent>(ctx, args);
               });
}

}  // namespace cnc::cia402::sim
