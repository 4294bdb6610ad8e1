#include "fieldbus/ethercat/components.hpp"

#include <cstdio>
#include <memory>

#include "core/hal/component.hpp"
#include "core/hal/hal.hpp"
#include "core/hal/thread.hpp"
#include "core/util/strings.hpp"
#include "fieldbus/ethercat/cia402_binding.hpp"
#include "fieldbus/ethercat/config.hpp"
#include "fieldbus/ethercat/master.hpp"

namespace cnc::ethercat {
namespace {

struct SlavePins {
  unsigned position = 0;
  hal::BitPin operational;
  hal::U32Pin al_state, al_code, emcy_code;
  std::array<hal::U32Pin, 4> port_rx_errors, port_lost_links;
};

struct Bus {
  std::unique_ptr<Master> master;
  std::string thread_name;
  std::string cycle_key;  // where the INI gives CYCLE_US, empty: the thread's period
  hal::Thread* thread = nullptr;
  hal::BitPin enable, ready, fault, dc_locked, restart;
  bool last_restart = false;
  hal::U32Pin cycles, wkc, frames_lost, frames_late, wkc_errors, sync_diff;
  hal::S32Pin dc_offset, dc_offset_max;
  hal::FloatPin dc_offset_mean, dc_offset_stddev;
  hal::Param<int32_t> expected_wkc;
  std::vector<SlavePins> slaves;

  void read(const rt::CycleInfo& info) noexcept {
    master->cyclic_read(info.now_ns);
    const CyclicCounters& c = master->counters();
    cycles.set(static_cast<uint32_t>(c.cycles.load(std::memory_order_relaxed)));
    wkc.set(c.last_wkc.load(std::memory_order_relaxed));
    frames_lost.set(static_cast<uint32_t>(c.frames_lost.load(std::memory_order_relaxed)));
    frames_late.set(static_cast<uint32_t>(c.frames_late.load(std::memory_order_relaxed)));
    wkc_errors.set(static_cast<uint32_t>(c.wkc_errors.load(std::memory_order_relaxed)));
    sync_diff.set(c.dc_sync_diff_ns.load(std::memory_order_relaxed));
    const PhaseLock& l = master->phase_lock();
    dc_locked.set(l.is_locked());
    dc_offset.set(static_cast<int32_t>(l.offset_ns()));
    dc_offset_max.set(static_cast<int32_t>(l.stats_all().max_abs));
    dc_offset_mean.set(l.stats_all().mean);
    dc_offset_stddev.set(l.stats_all().stddev());
    for (SlavePins& s : slaves) {
      const uint8_t st = master->slave_al_state(s.position);
      s.al_state.set(st);
      s.operational.set(master->is_operational() && st == static_cast<uint8_t>(AlState::Op));
      s.al_code.set(master->slave_al_code(s.position));
      s.emcy_code.set(master->slave_emcy_code(s.position));
      for (unsigned p = 0; p < 4; ++p) {
        s.port_rx_errors[p].set(master->slave_port_rx_errors(s.position, p));
        s.port_lost_links[p].set(master->slave_port_lost_links(s.position, p));
      }
    }
    ready.set(master->is_operational());
    fault.set(master->has_fault());
    const bool r = restart.get();
    if (r && !last_restart) master->request_restart();
    last_restart = r;
  }

  void write(const rt::CycleInfo& info) noexcept {
    if (enable.get()) master->cyclic_write(info.now_ns);
    const int64_t adjust = master->take_phase_adjust();
    if (thread && adjust != 0) thread->task().adjust_phase_ns(adjust);
  }
};

class EthercatComponent : public hal::Component {
 public:
  EthercatComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "ethercat") {
    args.allow_only({"buses"});
    if (!ctx.ini) throw hal::HalError("ethercat: needs the INI file (its [ETHERCAT] section describes the bus)");
    const auto sections = split(args.get_string("buses", "ETHERCAT"), ',', true);
    if (sections.empty()) throw hal::HalError("ethercat: buses= is empty");
    for (std::size_t i = 0; i < sections.size(); ++i) {
      const std::string name = "ethercat." + std::to_string(i);
      // Until on_ready says which thread runs the bus: its THREAD's period.
      BusSettings s = load_bus_settings(*ctx.ini, std::string(trim(sections[i])), name, [&](const std::string& t) {
        const hal::Thread* th = ctx.hal.find_thread(t);
        return th ? th->period_ns() : int64_t{0};
      });
      auto bus = std::make_unique<Bus>();
      bus->thread_name = s.thread;
      bus->cycle_key = s.cycle_key;
      bus->master = std::make_unique<Master>(std::move(s.master), ctx.messages);
      // Scan now, so that drives loaded after the bus find their process data.
      try {
        bus->master->plan();
      } catch (const std::exception& e) {
        throw hal::HalError(e.what());
      }
      make_pins(*bus, name);
      hal().export_function(
          this, name + ".read", [](void* b, const rt::CycleInfo& info) { static_cast<Bus*>(b)->read(info); }, bus.get());
      hal().export_function(
          this, name + ".write", [](void* b, const rt::CycleInfo& info) { static_cast<Bus*>(b)->write(info); }, bus.get());
      buses_.push_back(std::move(bus));
    }
  }
  ~EthercatComponent() override {
    for (auto& b : buses_) b->master->release();  // threads are stopped by now: slaves to INIT
  }

  void on_ready() override {
    // The bus cycle is the period of the thread that runs the bus's write
    // function (one frame per cycle): known now that addf placed it.
    const std::vector<hal::ThreadView> threads = hal().thread_views();
    for (auto& b : buses_) {
      const std::string write = b->master->name() + ".write";
      for (const hal::ThreadView& t : threads) {
        bool runs = false;
        for (const std::string& f : t.functions) runs = runs || f == write;
        const int64_t cycle = b->master->config().cycle_ns;
        if (!runs || t.period_ns == cycle) continue;
        if (!b->cycle_key.empty()) {
          throw hal::HalError(b->cycle_key + " = " + std::to_string(cycle / 1000) + " us, but " + write + " runs in " +
                              t.name + " with a period of " + std::to_string(t.period_ns / 1000) +
                              " us: one frame goes out each cycle of that thread; make them equal (or leave CYCLE_US out)");
        }
        try {
          b->master->set_cycle_ns(t.period_ns);
        } catch (const std::exception& e) {
          throw hal::HalError(e.what());
        }
      }
    }
    for (auto& b : buses_) {
      b->master->start_up();  // throws with slave, object and reason
      b->master->start_worker();
      if (b->master->config().dc_lock && b->master->uses_dc()) b->thread = hal().find_thread(b->thread_name);
    }
  }

  Master* master(const std::string& name) const {
    for (const auto& b : buses_) {
      if (b->master->name() == name) return b->master.get();
    }
    return nullptr;
  }

 private:
  void make_pins(Bus& b, const std::string& name) {
    using hal::PinDir;
    b.enable = make_pin<bool>(name + ".enable", PinDir::In, true);
    b.ready = make_pin<bool>(name + ".ready", PinDir::Out);
    b.fault = make_pin<bool>(name + ".fault", PinDir::Out);
    b.dc_locked = make_pin<bool>(name + ".dc-locked", PinDir::Out);
    b.restart = make_pin<bool>(name + ".restart", PinDir::In);
    b.cycles = make_pin<uint32_t>(name + ".cycles", PinDir::Out);
    b.wkc = make_pin<uint32_t>(name + ".working-counter", PinDir::Out);
    b.frames_lost = make_pin<uint32_t>(name + ".frames-lost", PinDir::Out);
    b.frames_late = make_pin<uint32_t>(name + ".frames-late", PinDir::Out);
    b.wkc_errors = make_pin<uint32_t>(name + ".wkc-errors", PinDir::Out);
    b.sync_diff = make_pin<uint32_t>(name + ".dc-sync-diff-ns", PinDir::Out);
    b.dc_offset = make_pin<int32_t>(name + ".dc-offset-ns", PinDir::Out);
    b.dc_offset_max = make_pin<int32_t>(name + ".dc-offset-max-ns", PinDir::Out);
    b.dc_offset_mean = make_pin<double>(name + ".dc-offset-mean-ns", PinDir::Out);
    b.dc_offset_stddev = make_pin<double>(name + ".dc-offset-stddev-ns", PinDir::Out);
    // Per-slave pins for the configured slaves (the scan happens later).
    for (const SlaveConfig& s : b.master->config().slaves) {
      char prefix[64];
      std::snprintf(prefix, sizeof prefix, "%s.slave.%02u", name.c_str(), s.position);
      const std::string p = prefix;
      SlavePins sp;
      sp.position = s.position;
      sp.operational = make_pin<bool>(p + ".operational", PinDir::Out);
      sp.al_state = make_pin<uint32_t>(p + ".al-state", PinDir::Out);
      sp.al_code = make_pin<uint32_t>(p + ".al-code", PinDir::Out);
      sp.emcy_code = make_pin<uint32_t>(p + ".emcy-code", PinDir::Out);
      for (unsigned port = 0; port < 4; ++port) {
        const std::string pp = p + ".port-" + std::to_string(port);
        sp.port_rx_errors[port] = make_pin<uint32_t>(pp + ".rx-errors", PinDir::Out);
        sp.port_lost_links[port] = make_pin<uint32_t>(pp + ".lost-links", PinDir::Out);
      }
      b.slaves.push_back(sp);
    }
  }

  std::vector<std::unique_ptr<Bus>> buses_;
};

std::unique_ptr<cia402::DriveLink> find_link(hal::Hal& hal, const std::string& bus) {
  Master* m = find_master(hal, bus);
  return m ? make_cia402_link(*m) : nullptr;
}

}  // namespace

void register_components(hal::ComponentRegistry& registry) {
  registry.add("ethercat",
               "EtherCAT master per INI section: buses=ETHERCAT[,ETHERCAT_1] (functions ethercat.N.read / "
               "ethercat.N.write)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<EthercatComponent>(ctx, args);
               });
  cia402::register_link_finder(&find_link);
}

Master* find_master(hal::Hal& hal, const std::string& name) {
  for (hal::Component* c : hal.components()) {
    if (auto* e = dynamic_cast<EthercatComponent*>(c)) {
      if (Master* m = e->master(name)) return m;
    }
  }
  return nullptr;
}

}  // namespace cnc::ethercat
