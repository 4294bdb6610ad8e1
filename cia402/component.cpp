// The HAL component `cia402`: one drive group per INI section, on the
// fieldbus master the section names (loaded before it), with pins named
// cia402.<g>.drive.<nn>.<pin> and the functions cia402.<g>.read (after the
// bus's read, before motion) and cia402.<g>.write (after motion, before
// the bus's write). See docs/cia402.md for pins and INI keys.
#include <memory>
#include <vector>

#include "cia402/link.hpp"
#include "cia402/components.hpp"
#include "cia402/drive_group.hpp"
#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"
#include "core/util/seqlock.hpp"
#include "core/util/strings.hpp"

namespace cnc::cia402 {
namespace {

using hal::PinDir;

struct DriveSnapshot {
  State state = State::NotReadyToSwitchOn;
  int8_t mode = 0;
  uint16_t statusword = 0, controlword = 0, error_code = 0;
  double ferror = 0, torque = 0, velocity = 0;
  FixedString<96> fault_text;
};

struct DrivePins {
  hal::BitPin enable, quick_stop, fault_reset, home_start, index_enable;
  hal::FloatPin pos_cmd, vel_cmd, torque_cmd;
  hal::S32Pin mode_request;
  hal::FloatPin pos_fb, vel_fb, ferror, torque, index_position, probe_position;
  hal::BitPin enabled, fault, amp_fault, warning, link_ok, home_busy, home_done, home_error, home_sw, pos_lim_sw,
      neg_lim_sw, probe_input;
  hal::U32Pin statusword, controlword, error_code, digital_inputs, probe_count;
  hal::S32Pin state, mode_display;
  SeqLock<DriveSnapshot> snapshot;
};

struct Group {
  std::unique_ptr<DriveLink> link;
  std::unique_ptr<DriveGroup> drives;
  std::vector<std::unique_ptr<DrivePins>> pins;
  hal::BitPin watchdog, watchdog_enabled, watchdog_ok;

  void read(const rt::CycleInfo& info) noexcept {
    for (std::size_t i = 0; i < pins.size(); ++i) {
      DrivePins& p = *pins[i];
      DriveCommand& c = drives->command(i);
      c.enable = p.enable.get();
      c.quick_stop = p.quick_stop.get();
      c.index_enable = p.index_enable.get();
    }
    drives->read(info.now_ns);
    for (std::size_t i = 0; i < pins.size(); ++i) {
      DrivePins& p = *pins[i];
      const DriveFeedback& f = drives->feedback(i);
      p.pos_fb.set(f.pos_fb);
      p.vel_fb.set(f.vel_fb);
      p.ferror.set(f.ferror);
      p.torque.set(f.torque);
      p.fault.set(f.fault);
      p.amp_fault.set(f.amp_fault);
      p.warning.set(f.warning);
      p.link_ok.set(f.link_ok);
      p.home_sw.set(f.home_sw);
      p.pos_lim_sw.set(f.pos_lim_sw);
      p.neg_lim_sw.set(f.neg_lim_sw);
      p.digital_inputs.set(f.digital_inputs);
      if (f.index_found) {
        p.index_position.set(f.index_position);
        p.index_enable.set(false);  // motion's convention: the device clears it at the index
      }
      p.probe_input.set(f.probe_input);
      p.probe_position.set(f.probe_position);
      p.probe_count.set(f.probe_count);
      p.statusword.set(f.statusword);
      p.state.set(static_cast<int32_t>(f.state));
      p.mode_display.set(static_cast<int32_t>(f.mode_display));
      p.error_code.set(f.error_code);
      // Homing flags are decided in write(): publish last cycle's for motion.
      p.home_busy.set(f.home_busy);
      p.home_done.set(f.home_done);
      p.home_error.set(f.home_error);
    }
  }

  void write(const rt::CycleInfo& info) noexcept {
    for (std::size_t i = 0; i < pins.size(); ++i) {
      DrivePins& p = *pins[i];
      DriveCommand& c = drives->command(i);
      c.enable = p.enable.get();
      c.quick_stop = p.quick_stop.get();
      c.fault_reset = p.fault_reset.get();
      c.pos_cmd = p.pos_cmd.get();
      c.vel_cmd = p.vel_cmd.get();
      c.torque_cmd = p.torque_cmd.get();
      c.mode_request = p.mode_request.get();
      c.home_start = p.home_start.get();
      c.index_enable = p.index_enable.get();
    }
    drives->set_watchdog(watchdog.get(), watchdog_enabled.get());
    drives->write(info.now_ns);
    watchdog_ok.set(drives->watchdog_ok());
    for (std::size_t i = 0; i < pins.size(); ++i) {
      DrivePins& p = *pins[i];
      const DriveFeedback& f = drives->feedback(i);
      p.controlword.set(f.controlword);
      p.enabled.set(f.enabled);
      p.home_busy.set(f.home_busy);
      p.home_done.set(f.home_done);
      p.home_error.set(f.home_error);
      DriveSnapshot s;
      s.state = f.state;
      s.mode = static_cast<int8_t>(f.mode_display);
      s.statusword = f.statusword;
      s.controlword = f.controlword;
      s.error_code = f.error_code;
      s.ferror = f.ferror;
      s.torque = f.torque;
      s.velocity = f.vel_fb;
      s.fault_text.assign(drives->drive(i).fault_text());
      p.snapshot.write(s);
    }
  }
};

class Cia402Component : public hal::Component, public ipc::ControllerService {
 public:
  Cia402Component(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "cia402") {
    args.allow_only({"sections"});
    if (!ctx.ini) throw hal::HalError("cia402: needs the INI file (its [CIA402] sections describe the drives)");
    const auto sections = split(args.get_string("sections", "CIA402"), ',', true);
    for (std::size_t g = 0; g < sections.size(); ++g) {
      const std::string name = "cia402." + std::to_string(g);
      GroupConfig cfg = load_group_config(*ctx.ini, std::string(trim(sections[g])), name);
      auto group = std::make_unique<Group>();
      try {
        group->link = find_link(ctx.hal, cfg.bus);
        group->drives = std::make_unique<DriveGroup>(cfg, *group->link, ctx.messages);
      } catch (const std::exception& e) {
        throw hal::HalError(std::string("cia402: ") + e.what());
      }
      make_pins(*group, name);
      hal().export_function(this, name + ".read",
                            [](void* a, const rt::CycleInfo& i) { static_cast<Group*>(a)->read(i); }, group.get());
      hal().export_function(this, name + ".write",
                            [](void* a, const rt::CycleInfo& i) { static_cast<Group*>(a)->write(i); }, group.get());
      groups_.push_back(std::move(group));
    }
  }

  void on_ready() override {
    for (auto& g : groups_) g->drives->configure();  // throws: start-up stops with drive, object, reason
  }
  void on_shutdown() override {
    for (auto& g : groups_) g->drives->request_shutdown();
  }
  bool is_safe_to_stop() const override {
    for (const auto& g : groups_) {
      if (!g->drives->is_safe()) return false;
    }
    return true;
  }
  int service_order() const noexcept override { return 5; }
  void contribute_status(ipc::Status& status) override {
    std::size_t slot = 0;
    constexpr std::size_t kSlots = sizeof(status.drives) / sizeof(status.drives[0]);
    for (const auto& g : groups_) {
      for (std::size_t i = 0; i < g->pins.size() && slot < kSlots; ++i, ++slot) {
        DriveSnapshot s;
        if (!g->pins[i]->snapshot.try_read(s, 1'000'000)) continue;
        ipc::DriveStatus& d = status.drives[slot];
        const DriveConfig& c = g->drives->drive(i).config();
        d.present = true;
        d.joint = static_cast<int8_t>(c.joint);
        d.state = static_cast<uint8_t>(s.state);
        d.mode = static_cast<uint8_t>(s.mode);
        d.statusword = s.statusword;
        d.controlword = s.controlword;
        d.error_code = s.error_code;
        d.following_error = s.ferror;
        d.torque_percent = s.torque;
        d.velocity = s.velocity;
        d.name.assign(c.name);
        d.fault_text = s.fault_text;
      }
    }
  }

  DriveGroup* group(std::size_t i) const noexcept { return i < groups_.size() ? groups_[i]->drives.get() : nullptr; }

 private:
  void make_pins(Group& g, const std::string& name) {
    g.watchdog = make_pin<bool>(name + ".watchdog", PinDir::In);
    g.watchdog_enabled = make_pin<bool>(name + ".watchdog-enabled", PinDir::In);
    g.watchdog_ok = make_pin<bool>(name + ".watchdog-ok", PinDir::Out, true);
    for (std::size_t i = 0; i < g.drives->size(); ++i) {
      const DriveConfig& c = g.drives->drive(i).config();
      const std::string n = c.source + ".";
      auto p = std::make_unique<DrivePins>();
      p->enable = make_pin<bool>(n + "enable", PinDir::In);
      p->quick_stop = make_pin<bool>(n + "quick-stop", PinDir::In);
      p->fault_reset = make_pin<bool>(n + "fault-reset", PinDir::In);
      p->home_start = make_pin<bool>(n + "home-start", PinDir::In);
      p->index_enable = make_pin<bool>(n + "index-enable", PinDir::IO);
      p->pos_cmd = make_pin<double>(n + "pos-cmd", PinDir::In);
      p->vel_cmd = make_pin<double>(n + "vel-cmd", PinDir::In);
      p->torque_cmd = make_pin<double>(n + "torque-cmd", PinDir::In);
      p->mode_request = make_pin<int32_t>(n + "mode-request", PinDir::In);
      p->pos_fb = make_pin<double>(n + "pos-fb", PinDir::Out);
      p->vel_fb = make_pin<double>(n + "vel-fb", PinDir::Out);
      p->ferror = make_pin<double>(n + "following-error", PinDir::Out);
      p->torque = make_pin<double>(n + "torque", PinDir::Out);
      p->index_position = make_pin<double>(n + "index-position", PinDir::Out);
      p->probe_position = make_pin<double>(n + "probe-position", PinDir::Out);
      p->enabled = make_pin<bool>(n + "enabled", PinDir::Out);
      p->fault = make_pin<bool>(n + "fault", PinDir::Out);
      p->amp_fault = make_pin<bool>(n + "amp-fault", PinDir::Out);
      p->warning = make_pin<bool>(n + "warning", PinDir::Out);
      p->link_ok = make_pin<bool>(n + "link-ok", PinDir::Out);
      p->home_busy = make_pin<bool>(n + "home-busy", PinDir::Out);
      p->home_done = make_pin<bool>(n + "home-done", PinDir::Out);
      p->home_error = make_pin<bool>(n + "home-error", PinDir::Out);
      p->home_sw = make_pin<bool>(n + "home-sw", PinDir::Out);
      p->pos_lim_sw = make_pin<bool>(n + "pos-lim-sw", PinDir::Out);
      p->neg_lim_sw = make_pin<bool>(n + "neg-lim-sw", PinDir::Out);
      p->probe_input = make_pin<bool>(n + "probe-input", PinDir::Out);
      p->statusword = make_pin<uint32_t>(n + "statusword", PinDir::Out);
      p->controlword = make_pin<uint32_t>(n + "controlword", PinDir::Out);
      p->error_code = make_pin<uint32_t>(n + "error-code", PinDir::Out);
      p->digital_inputs = make_pin<uint32_t>(n + "digital-inputs", PinDir::Out);
      p->probe_count = make_pin<uint32_t>(n + "probe-count", PinDir::Out);
      p->state = make_pin<int32_t>(n + "state", PinDir::Out);
      p->mode_display = make_pin<int32_t>(n + "mode-display", PinDir::Out);
      make_param<double>(n + "counts-per-unit", hal::ParamDir::RO, c.scaling.counts_per_unit * c.scaling.direction);
      g.pins.push_back(std::move(p));
    }
  }

  std::vector<std::unique_ptr<Group>> groups_;
};

}  // namespace

void register_components(hal::ComponentRegistry& registry) {
  registry.add("cia402",
               "CiA 402 drives per INI section on a loaded fieldbus: sections=CIA402[,CIA402_1] (functions "
               "cia402.N.read / cia402.N.write)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<Cia402Component>(ctx, args);
               });
}

DriveGroup* find_group(hal::Hal& hal, std::size_t index) {
  for (hal::Component* c : hal.components()) {
    if (auto* co = dynamic_cast<Cia402Component*>(c)) return co->group(index);
  }
  return nullptr;
}

}  // namespace cnc::cia402
