// sim_joint: a simulated joint for machines without drives yet and for
// tests. Feedback follows the command with a first-order lag (plus the
// cycle of delay a real loop has); a home switch, limit switches and index
// pulses sit at physical positions set by parameters. With index-enable set
// it clears index-enable at the next index and latches the exact position
// in index-position (the convention the motion controller's homing uses).
#include <cmath>

#include "core/hal/component.hpp"
#include "core/motion/motion_component.hpp"
#include "sim/machine/components.hpp"

namespace cnc::sim {
namespace {

using hal::PinDir;

struct SimJoint {
  hal::FloatPin pos_cmd, pos_fb, index_position, position;
  hal::BitPin enable, home_sw, pos_lim_sw, neg_lim_sw, index_enable, fault;
  hal::FloatPin home_sw_min, home_sw_max, pos_limit, neg_limit, index_spacing, index_offset, lag, start_position;
  double pos = 0;
  bool initialized = false;

  template <class C>
  void make(C& c, const std::string& n) {
    pos_cmd = c.template pin<double>(n + ".pos-cmd", PinDir::In);
    pos_fb = c.template pin<double>(n + ".pos-fb", PinDir::Out);
    position = c.template pin<double>(n + ".position", PinDir::Out);
    index_position = c.template pin<double>(n + ".index-position", PinDir::Out);
    enable = c.template pin<bool>(n + ".enable", PinDir::In);
    home_sw = c.template pin<bool>(n + ".home-sw", PinDir::Out);
    pos_lim_sw = c.template pin<bool>(n + ".pos-lim-sw", PinDir::Out);
    neg_lim_sw = c.template pin<bool>(n + ".neg-lim-sw", PinDir::Out);
    index_enable = c.template pin<bool>(n + ".index-enable", PinDir::IO);
    fault = c.template pin<bool>(n + ".fault", PinDir::In);
    home_sw_min = c.template pin<double>(n + ".home-sw-min", PinDir::In, 1e99);
    home_sw_max = c.template pin<double>(n + ".home-sw-max", PinDir::In, 1e99);
    pos_limit = c.template pin<double>(n + ".pos-limit", PinDir::In, 1e99);
    neg_limit = c.template pin<double>(n + ".neg-limit", PinDir::In, -1e99);
    index_spacing = c.template pin<double>(n + ".index-spacing", PinDir::In, 0.0);
    index_offset = c.template pin<double>(n + ".index-offset", PinDir::In, 0.0);
    lag = c.template pin<double>(n + ".lag", PinDir::In, 0.0);
    start_position = c.template pin<double>(n + ".start-position", PinDir::In, 0.0);
  }

  void update(const rt::CycleInfo& info) noexcept {
    if (!initialized) {
      pos = start_position.get();
      initialized = true;
    }
    const double before = pos;
    if (enable.get()) {
      const double tau = lag.get();
      const double dt = static_cast<double>(info.period_ns) * 1e-9;
      const double target = pos_cmd.get();
      pos = tau <= 0 ? target : pos + (target - pos) * (1 - std::exp(-dt / tau));
    }
    // The index pulses lie at offset + k * spacing.
    const double spacing = index_spacing.get();
    if (index_enable.get() && spacing > 0 && pos != before) {
      const double k0 = std::floor((before - index_offset.get()) / spacing);
      const double k1 = std::floor((pos - index_offset.get()) / spacing);
      if (k0 != k1) {
        const double k = pos > before ? k1 : k0;
        index_position.set(index_offset.get() + k * spacing);
        index_enable.set(false);
      }
    }
    pos_fb.set(pos);
    position.set(pos);
    home_sw.set(pos >= home_sw_min.get() && pos <= home_sw_max.get());
    pos_lim_sw.set(pos >= pos_limit.get());
    neg_lim_sw.set(pos <= neg_limit.get());
  }
};

class SimJointComponent : public hal::Component {
 public:
  SimJointComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args) : hal::Component(ctx.hal, args.component()) {
    mark_as_simulation();
    args.allow_only({"count", "names"});
    for (const auto& n : args.instance_names("sim-joint", 1, kMaxJoints)) {
      joints_.push_back(std::make_unique<SimJoint>());
      joints_.back()->make(*this, n);
      hal().export_function(
          this, n, [](void* arg, const rt::CycleInfo& info) { static_cast<SimJoint*>(arg)->update(info); },
          joints_.back().get());
    }
  }
  template <class T>
  hal::Pin<T> pin(const std::string& name, PinDir dir, T initial = T{}) { return make_pin<T>(name, dir, initial); }

 private:
  std::vector<std::unique_ptr<SimJoint>> joints_;
};

}  // namespace

void register_sim_joint(hal::ComponentRegistry& registry) {
  registry.add("sim_joint", "sim_joint [count=N|names=a,b]: simulated joints with switches and index pulses",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimJointComponent>(ctx, args);
               });
}

}  // namespace cnc::sim
