#include "fieldbus/modbus/component.hpp"

#include <cmath>
#include <cstdio>
#include <memory>

#include "core/hal/component.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/service.hpp"
#include "core/util/error.hpp"
#include "core/util/messages.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/modbus/link.hpp"

namespace cnc::modbus {
namespace {

struct VfdPins {
  VfdPort* port = nullptr;
  // in (from motion's spindle.N.* pins)
  hal::BitPin on, forward, reverse, fault_reset;
  hal::FloatPin speed_cmd;
  // out
  hal::FloatPin speed_fb, speed_fb_rps, frequency, current, fb_age;
  hal::BitPin at_speed, fault, drive_fault, comm_ok, running;
  hal::U32Pin fault_code, timeouts, crc_errors, exceptions, last_exception, exchanges;
  hal::FloatPin latency;
  VfdFeedback fb;  // last consistent copy of the mailbox
  VfdCommand cmd;
  bool last_reset = false;
  bool commanded_run = false;
};

struct IoValuePin {
  hal::BitPin bit;
  hal::FloatPin real;
  hal::S32Pin s32;
  IoType type = IoType::Bit;
};

struct IoPins {
  IoPort* port = nullptr;
  std::vector<IoValuePin> values;  // in the module's value order
  hal::BitPin comm_ok;
  hal::FloatPin fb_age;
  hal::U32Pin timeouts, crc_errors, exceptions, exchanges;
  IoInputs in;
  IoOutputs out;
};

struct LinkPins {
  std::unique_ptr<Link> link;
  hal::BitPin connected;
  hal::U32Pin connects;
  std::vector<VfdPins> vfds;
  std::vector<IoPins> ios;

  // modbus.N.read: mailboxes -> pins. One non-waiting look at each mailbox;
  // a busy one keeps last cycle's copy, which its age then shows.
  void read(const rt::CycleInfo& info) noexcept {
    const int64_t now = info.now_ns;
    connected.set(link->counters().connected.load(std::memory_order_relaxed));
    connects.set(link->counters().connects.load(std::memory_order_relaxed));
    for (VfdPins& v : vfds) read_vfd(v, now);
    for (IoPins& io : ios) read_io(io, now);
  }

  static void read_counters(const DeviceCounters& c, hal::U32Pin& t, hal::U32Pin& crc, hal::U32Pin& ex, hal::U32Pin& n) {
    t.set(c.timeouts.load(std::memory_order_relaxed));
    crc.set(c.crc_errors.load(std::memory_order_relaxed));
    ex.set(c.exceptions.load(std::memory_order_relaxed));
    n.set(c.exchanges.load(std::memory_order_relaxed));
  }

  // The command from the input pins, as motion set them this cycle (read
  // runs before motion, so at-speed compares with the newest command).
  static void take_command(VfdPins& v) noexcept {
    const double s = v.speed_cmd.get();
    v.cmd.run = v.on.get();
    v.cmd.reverse = v.reverse.get() || (!v.forward.get() && s < 0);
    v.cmd.speed_rpm = std::fabs(s);
    v.commanded_run = v.cmd.run && v.cmd.speed_rpm > 0;
  }

  static void read_vfd(VfdPins& v, int64_t now) noexcept {
    const VfdConfig& c = v.port->config;
    take_command(v);
    v.port->feedback.try_read_once(v.fb);
    const bool ok = v.fb.ok_ns != 0 && now - v.fb.ok_ns <= c.stale_ns;
    const double age = v.fb.ok_ns != 0 ? static_cast<double>(now - v.fb.ok_ns) * 1e-9 : -1.0;
    const double rpm = v.fb.frequency_hz * c.rpm_per_hz * (v.fb.reverse ? -1.0 : 1.0);
    const double cmd = v.commanded_run ? v.cmd.speed_rpm : 0.0;
    const double tol = std::max(c.at_speed_tolerance * cmd, 1.0);
    const bool drive_fault = ok && v.fb.fault_code != 0;
    const bool lost = !ok && v.commanded_run && c.on_comm_loss == CommLossAction::Fault;
    v.comm_ok.set(ok);
    v.fb_age.set(age);
    v.speed_fb.set(rpm);
    v.speed_fb_rps.set(rpm / 60.0);
    v.frequency.set(v.fb.frequency_hz);
    v.current.set(v.fb.current_a);
    v.running.set(ok && v.fb.frequency_hz > 0);
    v.at_speed.set(ok && std::fabs(std::fabs(rpm) - cmd) <= tol && (!v.commanded_run || (rpm < 0) == v.cmd.reverse));
    v.fault_code.set(v.fb.fault_code);
    v.drive_fault.set(drive_fault);
    v.fault.set(drive_fault || lost);
    read_counters(v.port->counters, v.timeouts, v.crc_errors, v.exceptions, v.exchanges);
    v.last_exception.set(v.port->counters.last_exception.load(std::memory_order_relaxed));
    v.latency.set(static_cast<double>(v.port->counters.last_latency_ns.load(std::memory_order_relaxed)) * 1e-9);
  }

  static void read_io(IoPins& io, int64_t now) noexcept {
    io.port->inputs.try_read_once(io.in);
    const IoConfig& c = io.port->config;
    int64_t oldest = -1;
    for (std::size_t m = 0; m < c.maps.size(); ++m) {
      const IoMap& map = c.maps[m];
      const int64_t t = io.in.map_ns[m];
      const int64_t age = t == 0 ? INT64_MAX : now - t;
      oldest = std::max(oldest, age);
      if (map.is_output()) continue;
      for (std::size_t i = 0; i < map.count; ++i) {
        IoValuePin& p = io.values[map.first_value + i];
        const double v = io.in.value[map.first_value + i];
        switch (p.type) {
          case IoType::Bit: p.bit.set(v != 0); break;
          case IoType::Float: p.real.set(v); break;
          case IoType::S32: p.s32.set(static_cast<int32_t>(std::clamp(v, -2147483648.0, 2147483647.0))); break;
        }
      }
    }
    io.comm_ok.set(oldest != INT64_MAX && oldest <= c.stale_ns + 2 * max_poll(c));
    io.fb_age.set(oldest == INT64_MAX ? -1.0 : static_cast<double>(oldest) * 1e-9);
    read_counters(io.port->counters, io.timeouts, io.crc_errors, io.exceptions, io.exchanges);
  }

  static int64_t max_poll(const IoConfig& c) noexcept {
    int64_t m = 0;
    for (const IoMap& map : c.maps) m = std::max(m, map.poll_ns);
    return m;
  }

  // modbus.N.write: pins -> mailboxes.
  void write(const rt::CycleInfo&) noexcept {
    for (VfdPins& v : vfds) {
      take_command(v);
      const bool r = v.fault_reset.get();
      if (r && !v.last_reset) ++v.cmd.reset_count;
      v.last_reset = r;
      v.port->command.write(v.cmd);
    }
    for (IoPins& io : ios) {
      for (const IoMap& map : io.port->config.maps) {
        if (!map.is_output()) continue;
        for (std::size_t i = 0; i < map.count; ++i) {
          const IoValuePin& p = io.values[map.first_value + i];
          double& o = io.out.value[map.first_value + i];
          switch (p.type) {
            case IoType::Bit: o = p.bit.get() ? 1 : 0; break;
            case IoType::Float: o = p.real.get(); break;
            case IoType::S32: o = p.s32.get(); break;
          }
        }
      }
      io.port->outputs.write(io.out);
    }
  }
};

const char* kind_prefix(IoKind k) {
  switch (k) {
    case IoKind::Coil: return "coil";
    case IoKind::DiscreteInput: return "di";
    case IoKind::InputRegister: return "ir";
    case IoKind::HoldingRegister: return "hr";
  }
  return "?";
}

class ModbusComponent : public hal::Component, public ipc::ControllerService {
 public:
  ModbusComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args)
      : Component(ctx.hal, "modbus"), messages_(ctx.messages) {
    args.allow_only({"links"});
    if (!ctx.ini) throw hal::HalError("modbus: needs the INI file (its [MODBUS] sections describe the links)");
    const auto sections = split(args.get_string("links", "MODBUS"), ',', true);
    if (sections.empty()) throw hal::HalError("modbus: links= is empty");
    for (std::size_t i = 0; i < sections.size(); ++i) {
      const std::string name = "modbus." + std::to_string(i);
      auto lp = std::make_unique<LinkPins>();
      lp->link = std::make_unique<Link>(load_link_config(*ctx.ini, std::string(trim(sections[i])), name), ctx.messages);
      make_pins(*lp, name);
      hal().export_function(
          this, name + ".read", [](void* p, const rt::CycleInfo& info) { static_cast<LinkPins*>(p)->read(info); },
          lp.get());
      hal().export_function(
          this, name + ".write", [](void* p, const rt::CycleInfo& info) { static_cast<LinkPins*>(p)->write(info); },
          lp.get());
      links_.push_back(std::move(lp));
    }
  }

  ~ModbusComponent() override {
    for (auto& l : links_) l->link->stop();
  }

  // Polling starts with the controller's first task cycle (never in a
  // configuration check).
  int service_order() const noexcept override { return 6; }
  void update(int64_t) override {
    if (started_) return;
    started_ = true;
    for (auto& l : links_) l->link->start();
  }

  // Motion has turned the spindles off by now; this makes sure the drives
  // were told, before the threads stop.
  void on_shutdown() override {
    for (auto& l : links_) {
      if (l->link->vfds().empty() || !started_) continue;
      if (!l->link->stop_drives(500'000'000) && messages_) {
        messages_->post(MessageKind::Error, l->link->name(), "could not tell every VFD to stop while shutting down");
      }
    }
  }

  // VFDs join the drive panel after the CiA 402 drives, as spindle drives.
  void contribute_status(ipc::Status& status) override {
    constexpr std::size_t kSlots = sizeof(status.drives) / sizeof(status.drives[0]);
    std::size_t slot = 0;
    for (auto& l : links_) {
      for (const VfdPins& v : l->vfds) {
        while (slot < kSlots && status.drives[slot].present) ++slot;
        if (slot >= kSlots) return;
        VfdFeedback fb;
        if (!v.port->feedback.try_read(fb, 1'000'000)) continue;
        FixedString<96> text;
        v.port->fault_text.try_read(text, 1'000'000);
        // The link thread may be starved rather than failing: the age says so.
        const int64_t age = monotonic_ns() - fb.ok_ns;
        if (text.view().empty() && (fb.ok_ns == 0 || age > v.port->config.stale_ns)) {
          text.format("no complete exchange for %.2f s (STALE_MS %lld)", fb.ok_ns == 0 ? 0.0 : static_cast<double>(age) * 1e-9,
                      static_cast<long long>(v.port->config.stale_ns / 1'000'000));
        }
        ipc::DriveStatus& d = status.drives[slot];
        d.present = true;
        d.joint = -1;
        d.error_code = fb.fault_code;
        d.velocity = fb.frequency_hz * v.port->config.rpm_per_hz / 60.0 * (fb.reverse ? -1 : 1);
        d.name.assign(v.port->config.name);
        d.fault_text.assign(text.view());
      }
    }
  }

  Link* link(const std::string& name) const {
    for (const auto& l : links_) {
      if (l->link->name() == name) return l->link.get();
    }
    return nullptr;
  }

 private:
  void make_pins(LinkPins& lp, const std::string& name) {
    using hal::PinDir;
    lp.connected = make_pin<bool>(name + ".connected", PinDir::Out);
    lp.connects = make_pin<uint32_t>(name + ".connects", PinDir::Out);
    for (auto& port : lp.link->vfds()) {
      char prefix[48];
      std::snprintf(prefix, sizeof prefix, "%s.vfd.%02u.", name.c_str(), port->config.slave);
      const std::string p = prefix;
      VfdPins v;
      v.port = port.get();
      v.on = make_pin<bool>(p + "on", PinDir::In);
      v.forward = make_pin<bool>(p + "forward", PinDir::In);
      v.reverse = make_pin<bool>(p + "reverse", PinDir::In);
      v.fault_reset = make_pin<bool>(p + "fault-reset", PinDir::In);
      v.speed_cmd = make_pin<double>(p + "speed-cmd", PinDir::In);
      v.speed_fb = make_pin<double>(p + "speed-fb", PinDir::Out);
      v.speed_fb_rps = make_pin<double>(p + "speed-fb-rps", PinDir::Out);
      v.frequency = make_pin<double>(p + "frequency", PinDir::Out);
      v.current = make_pin<double>(p + "current", PinDir::Out);
      v.fb_age = make_pin<double>(p + "fb-age", PinDir::Out, -1.0);
      v.at_speed = make_pin<bool>(p + "at-speed", PinDir::Out);
      v.running = make_pin<bool>(p + "running", PinDir::Out);
      v.fault = make_pin<bool>(p + "fault", PinDir::Out);
      v.drive_fault = make_pin<bool>(p + "drive-fault", PinDir::Out);
      v.comm_ok = make_pin<bool>(p + "comm-ok", PinDir::Out);
      v.fault_code = make_pin<uint32_t>(p + "fault-code", PinDir::Out);
      v.timeouts = make_pin<uint32_t>(p + "timeouts", PinDir::Out);
      v.crc_errors = make_pin<uint32_t>(p + "crc-errors", PinDir::Out);
      v.exceptions = make_pin<uint32_t>(p + "exceptions", PinDir::Out);
      v.last_exception = make_pin<uint32_t>(p + "last-exception", PinDir::Out);
      v.exchanges = make_pin<uint32_t>(p + "exchanges", PinDir::Out);
      v.latency = make_pin<double>(p + "latency", PinDir::Out);
      lp.vfds.push_back(v);
    }
    for (auto& port : lp.link->ios()) {
      char prefix[48];
      std::snprintf(prefix, sizeof prefix, "%s.io.%02u.", name.c_str(), port->config.slave);
      const std::string p = prefix;
      IoPins io;
      io.port = port.get();
      io.values.resize(port->config.values);
      for (const IoMap& map : port->config.maps) {
        const PinDir dir = map.is_output() ? PinDir::In : PinDir::Out;
        for (uint16_t i = 0; i < map.count; ++i) {
          char pin[64];
          std::snprintf(pin, sizeof pin, "%s%s-%04u", p.c_str(), kind_prefix(map.kind), static_cast<unsigned>(map.start + i));
          IoValuePin& v = io.values[map.first_value + i];
          v.type = map.type;
          switch (map.type) {
            case IoType::Bit: v.bit = make_pin<bool>(pin, dir); break;
            case IoType::Float: v.real = make_pin<double>(pin, dir); break;
            case IoType::S32: v.s32 = make_pin<int32_t>(pin, dir); break;
          }
        }
      }
      io.comm_ok = make_pin<bool>(p + "comm-ok", PinDir::Out);
      io.fb_age = make_pin<double>(p + "fb-age", PinDir::Out, -1.0);
      io.timeouts = make_pin<uint32_t>(p + "timeouts", PinDir::Out);
      io.crc_errors = make_pin<uint32_t>(p + "crc-errors", PinDir::Out);
      io.exceptions = make_pin<uint32_t>(p + "exceptions", PinDir::Out);
      io.exchanges = make_pin<uint32_t>(p + "exchanges", PinDir::Out);
      lp.ios.push_back(std::move(io));
    }
  }

  std::vector<std::unique_ptr<LinkPins>> links_;
  MessageQueue* messages_ = nullptr;
  bool started_ = false;
};

}  // namespace

void register_components(hal::ComponentRegistry& registry) {
  registry.add("modbus",
               "Modbus links (VFD spindles, remote I/O) per INI section: links=MODBUS[,MODBUS_1] (functions "
               "modbus.N.read / modbus.N.write)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 try {
                   return std::make_unique<ModbusComponent>(ctx, args);
                 } catch (const ConfigError& e) {
                   throw hal::HalError(e.what());
                 }
               });
}

Link* find_link(hal::Hal& hal, const std::string& name) {
  for (hal::Component* c : hal.components()) {
    if (auto* m = dynamic_cast<ModbusComponent*>(c)) {
      if (Link* l = m->link(name)) return l;
    }
  }
  return nullptr;
}

}  // namespace cnc::modbus
