// sim_toolchanger: a tool changer for simulated machines. It answers
// iocontrol's tool-prepare and tool-change after configurable delays, and
// can be told to hang (to test timeouts).
#include "core/hal/component.hpp"
#include "sim/machine/components.hpp"

namespace cnc::sim {
namespace {

class SimToolchanger : public hal::Component {
 public:
  SimToolchanger(hal::ComponentContext& ctx, const hal::LoadArgs& args) : hal::Component(ctx.hal, "sim_toolchanger") {
    mark_as_simulation();
    args.allow_only({});
    const std::string n = "sim-toolchanger.";
    prepare_ = make_pin<bool>(n + "prepare", hal::PinDir::In);
    prepared_ = make_pin<bool>(n + "prepared", hal::PinDir::Out);
    change_ = make_pin<bool>(n + "change", hal::PinDir::In);
    changed_ = make_pin<bool>(n + "changed", hal::PinDir::Out);
    prepare_time_ = make_pin<double>(n + "prepare-time", hal::PinDir::In, 0.2);
    change_time_ = make_pin<double>(n + "change-time", hal::PinDir::In, 1.0);
    hang_ = make_pin<bool>(n + "hang", hal::PinDir::In);
    changes_ = make_pin<int32_t>(n + "changes", hal::PinDir::Out);
    export_method<&SimToolchanger::update>("sim-toolchanger", this);
  }

  void update(const rt::CycleInfo& info) noexcept {
    const double dt = static_cast<double>(info.period_ns) * 1e-9;
    prep_t_ = prepare_.get() ? prep_t_ + dt : 0;
    change_t_ = change_.get() ? change_t_ + dt : 0;
    const bool hang = hang_.get();
    prepared_.set(!hang && prepare_.get() && prep_t_ >= prepare_time_.get());
    const bool done = !hang && change_.get() && change_t_ >= change_time_.get();
    if (done && !changed_.get()) changes_.set(changes_.get() + 1);
    changed_.set(done);
  }

 private:
  hal::BitPin prepare_, prepared_, change_, changed_, hang_;
  hal::FloatPin prepare_time_, change_time_;
  hal::S32Pin changes_;
  double prep_t_ = 0, change_t_ = 0;
};

}  // namespace

void register_sim_toolchanger(hal::ComponentRegistry& registry) {
  registry.add("sim_toolchanger", "sim_toolchanger: a simulated tool changer answering iocontrol's handshake after delays",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimToolchanger>(ctx, args);
               });
}

}  // namespace cnc::sim
