#include "fieldbus/canopen/components.hpp"

#include <cstdio>
#include <memory>
#include <variant>

#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/messages.hpp"
#include "core/util/strings.hpp"
#include "fieldbus/canopen/cia402_binding.hpp"
#include "fieldbus/canopen/master.hpp"

namespace cnc::canopen {
namespace {

// A mapped object exported as a pin, converted each cycle.
struct ObjectPin {
  ValueKind kind = ValueKind::Unsigned;
  bool wide = false;  // 64-bit integer
  ProcessSlot slot;
  hal::BitPin bit;
  hal::S32Pin s32;
  hal::U32Pin u32;
  hal::S64Pin s64;
  hal::U64Pin u64;
  hal::FloatPin real;

  void to_pin() const noexcept {
    switch (kind) {
      case ValueKind::Bit: bit.set(read_slot<uint8_t>(slot) != 0); break;
      case ValueKind::Signed:
        if (wide) s64.set(read_slot<int64_t>(slot));
        else s32.set(read_slot<int32_t>(slot));
        break;
      case ValueKind::Unsigned:
        if (wide) u64.set(read_slot<uint64_t>(slot));
        else u32.set(read_slot<uint32_t>(slot));
        break;
      case ValueKind::Real: real.set(read_slot<double>(slot)); break;
    }
  }
  void from_pin() const noexcept {
    switch (kind) {
      case ValueKind::Bit: write_slot<uint8_t>(slot, bit.get() ? 1 : 0); break;
      case ValueKind::Signed:
        if (wide) write_slot<int64_t>(slot, s64.get());
        else write_slot<int32_t>(slot, s32.get());
        break;
      case ValueKind::Unsigned:
        if (wide) write_slot<uint64_t>(slot, u64.get());
        else write_slot<uint32_t>(slot, u32.get());
        break;
      case ValueKind::Real: write_slot<double>(slot, real.get()); break;
    }
  }
};

struct NodePins {
  uint8_t id = 0;
  hal::BitPin operational, fault, heartbeat_lost, reboot;
  hal::U32Pin nmt_state, emcy_code, error_register, pdo_missed;
  bool last_reboot = false;
};

class CanopenComponent;

struct Bus {
  std::unique_ptr<Master> master;
  hal::BitPin enable, ready, fault;
  hal::U32Pin sync_counter, send_errors, rx_overruns, pdo_missed;
  hal::S32Pin bus_state;
  hal::Param<int32_t> delay;
  hal::Param<double> planned_load;
  hal::Param<double> planned_cycle_load;
  std::vector<NodePins> nodes;
  std::vector<ObjectPin> inputs, outputs;

  void read(const rt::CycleInfo& info) noexcept {
    master->cyclic_read(info.now_ns);
    for (const ObjectPin& p : inputs) p.to_pin();
    const CyclicStatus& c = master->cyclic_status();
    sync_counter.set(static_cast<uint32_t>(c.sync_serial));
    send_errors.set(c.send_errors);
    rx_overruns.set(c.rx_overruns);
    pdo_missed.set(c.pdo_missed);
    bus_state.set(static_cast<int32_t>(c.bus_state));
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      NodePins& n = nodes[i];
      const NodeStatus s = master->node_status_at(i);
      n.operational.set(s.operational);
      n.fault.set(s.fault);
      n.heartbeat_lost.set(s.heartbeat_lost);
      n.nmt_state.set(static_cast<uint32_t>(s.state));
      n.emcy_code.set(s.emcy_code);
      n.error_register.set(s.error_register);
      n.pdo_missed.set(s.pdo_missed);
      const bool r = n.reboot.get();
      if (r && !n.last_reboot) master->request_reboot(n.id);
      n.last_reboot = r;
    }
    ready.set(master->is_ready());
    fault.set(master->has_fault());
  }

  void write(const rt::CycleInfo& info) noexcept {
    for (const ObjectPin& p : outputs) p.from_pin();
    if (enable.get()) master->cyclic_write(info.now_ns);
  }
};

std::string object_pin_name(const std::string& node_prefix, const PdoMapEntry& e) {
  char buf[16];
  std::snprintf(buf, sizeof buf, ".%04x-%02x", e.index, e.sub);
  return node_prefix + buf;
}

class CanopenComponent : public hal::Component {
 public:
  CanopenComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args)
      : Component(ctx.hal, "canopen"), messages_(ctx.messages) {
    args.allow_only({"buses"});
    if (!ctx.ini) throw hal::HalError("canopen: needs the INI file (its [CANOPEN] sections describe the bus)");
    const auto sections = split(args.get_string("buses", "CANOPEN"), ',', true);
    if (sections.empty()) throw hal::HalError("canopen: buses= is empty");
    // Until on_ready says which thread runs each bus: the servo thread's period.
    const hal::Thread* servo = ctx.hal.find_thread("servo-thread");
    for (std::size_t i = 0; i < sections.size(); ++i) {
      const std::string name = "canopen." + std::to_string(i);
      BusConfig cfg = load_bus_config(*ctx.ini, std::string(trim(sections[i])), name,
                                      servo ? servo->period_ns() : 1'000'000);
      auto bus = std::make_unique<Bus>();
      bus->master = std::make_unique<Master>(std::move(cfg), ctx.messages);
      make_pins(*bus, name);
      hal().export_function(
          this, name + ".read", [](void* b, const rt::CycleInfo& info) { static_cast<Bus*>(b)->read(info); }, bus.get());
      hal().export_function(
          this, name + ".write", [](void* b, const rt::CycleInfo& info) { static_cast<Bus*>(b)->write(info); }, bus.get());
      buses_.push_back(std::move(bus));
    }
  }

  void on_ready() override {
    // The SYNC period is the period of the thread that runs the bus's write
    // function (it sends SYNC every cycle): known now that addf placed it.
    const std::vector<hal::ThreadView> threads = hal().thread_views();
    for (auto& b : buses_) {
      const std::string write = b->master->name() + ".write";
      const hal::ThreadView* runner = nullptr;
      for (const hal::ThreadView& t : threads) {
        for (const std::string& f : t.functions) {
          if (f == write) runner = &t;
        }
      }
      const BusConfig& c = b->master->config();
      if (!runner) {
        if (messages_) {
          messages_->post(MessageKind::Text, b->master->name(),
                          write + " runs in no HAL thread: the bus sends no SYNC and no PDO");
        }
      } else if (runner->period_ns != c.cycle_ns) {
        if (!c.cycle_key.empty()) {
          throw hal::HalError(c.cycle_key + " = " + std::to_string(c.cycle_ns / 1000) + " us, but " + write + " runs in " +
                              runner->name + " with a period of " + std::to_string(runner->period_ns / 1000) +
                              " us: SYNC is sent every cycle of that thread; make them equal (or leave SYNC_PERIOD_US out)");
        }
        try {
          b->master->set_cycle_ns(runner->period_ns);
        } catch (const std::exception& e) {
          throw hal::HalError(e.what());
        }
        b->planned_load.set(c.load().worst_case());
        b->planned_cycle_load.set(c.load().worst_cycle());
      }
    }
    for (auto& b : buses_) {
      b->master->start_thread();
      b->master->boot();  // throws with node, object and reason
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
    b.sync_counter = make_pin<uint32_t>(name + ".sync-count", PinDir::Out);
    b.send_errors = make_pin<uint32_t>(name + ".send-errors", PinDir::Out);
    b.rx_overruns = make_pin<uint32_t>(name + ".rx-overruns", PinDir::Out);
    b.pdo_missed = make_pin<uint32_t>(name + ".pdo-missed", PinDir::Out);
    b.bus_state = make_pin<int32_t>(name + ".bus-state", PinDir::Out);
    b.delay = make_param<int32_t>(name + ".transport-delay", hal::ParamDir::RO, Master::transport_delay_cycles());
    b.planned_load = make_param<double>(name + ".planned-load", hal::ParamDir::RO, b.master->config().load().worst_case());
    b.planned_cycle_load =
        make_param<double>(name + ".planned-cycle-load", hal::ParamDir::RO, b.master->config().load().worst_cycle());
    const Master& m = *b.master;
    for (std::size_t i = 0; i < m.node_count(); ++i) {
      const NodeConfig& c = m.config().nodes[i];
      char prefix[48];
      std::snprintf(prefix, sizeof prefix, "%s.node.%02u", name.c_str(), c.id);
      const std::string p = prefix;
      NodePins n;
      n.id = c.id;
      n.operational = make_pin<bool>(p + ".operational", PinDir::Out);
      n.fault = make_pin<bool>(p + ".fault", PinDir::Out);
      n.heartbeat_lost = make_pin<bool>(p + ".heartbeat-lost", PinDir::Out);
      n.reboot = make_pin<bool>(p + ".reboot", PinDir::In);
      n.nmt_state = make_pin<uint32_t>(p + ".nmt-state", PinDir::Out, 0xFF);
      n.emcy_code = make_pin<uint32_t>(p + ".emcy-code", PinDir::Out);
      n.error_register = make_pin<uint32_t>(p + ".error-register", PinDir::Out);
      n.pdo_missed = make_pin<uint32_t>(p + ".pdo-missed", PinDir::Out);
      b.nodes.push_back(n);
      if (!c.export_pins) continue;
      for (bool tpdo : {false, true}) {
        const auto& pdos = tpdo ? c.tpdos : c.rpdos;
        const auto& kinds = tpdo ? c.tpdo_kinds : c.rpdo_kinds;
        for (std::size_t k = 0; k < pdos.size(); ++k) {
          for (std::size_t e = 0; e < pdos[k].map.size(); ++e) {
            const PdoMapEntry& entry = pdos[k].map[e];
            if (entry.is_dummy()) continue;
            ObjectPin op;
            op.kind = e < kinds[k].size() ? kinds[k][e] : ValueKind::Unsigned;
            op.wide = entry.bits > 32;
            op.slot = tpdo ? m.input(c.id, entry.index, entry.sub) : m.output(c.id, entry.index, entry.sub);
            const std::string pin = object_pin_name(p, entry);
            const PinDir dir = tpdo ? PinDir::Out : PinDir::In;
            switch (op.kind) {
              case ValueKind::Bit: op.bit = make_pin<bool>(pin, dir); break;
              case ValueKind::Signed:
                if (op.wide) op.s64 = make_pin<int64_t>(pin, dir);
                else op.s32 = make_pin<int32_t>(pin, dir);
                break;
              case ValueKind::Unsigned:
                if (op.wide) op.u64 = make_pin<uint64_t>(pin, dir);
                else op.u32 = make_pin<uint32_t>(pin, dir);
                break;
              case ValueKind::Real: op.real = make_pin<double>(pin, dir); break;
            }
            (tpdo ? b.inputs : b.outputs).push_back(op);
          }
        }
      }
    }
  }

  std::vector<std::unique_ptr<Bus>> buses_;
  MessageQueue* messages_ = nullptr;
};

std::unique_ptr<cia402::DriveLink> find_link(hal::Hal& hal, const std::string& bus) {
  Master* m = find_master(hal, bus);
  return m ? make_cia402_link(*m) : nullptr;
}

}  // namespace

void register_components(hal::ComponentRegistry& registry) {
  registry.add("canopen",
               "CANopen master per INI section: buses=CANOPEN[,CANOPEN_1] (functions canopen.N.read / canopen.N.write)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<CanopenComponent>(ctx, args);
               });
  cia402::register_link_finder(&find_link);
}

Master* find_master(hal::Hal& hal, const std::string& name) {
  for (hal::Component* c : hal.components()) {
    if (auto* co = dynamic_cast<CanopenComponent*>(c)) {
      if (Master* m = co->master(name)) return m;
    }
  }
  return nullptr;
}

}  // namespace cnc::canopen
