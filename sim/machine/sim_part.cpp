// sim_part: the simulated part for probing (sim/machine/part.hpp). Each
// servo cycle it takes the probe tip's physical position from its x, y, z
// pins (wired to the simulated drives' table-position pins) and sets
// `contact` while the ball touches the block. `probe` is contact ORed with
// `setter` (the tool setter's input, the Z drive's probe-level): the one
// probe signal, which configs/sim wires to every axis drive's probe-in, so
// each drive's touch probe latches its own encoder at the edge, as a probe
// wired to every drive's input does. The drives see a change two servo
// cycles after the tip crossed the surface (this component reads the
// positions the drives published in the cycle before, the drive takes
// probe-in at its next step): the latch lags by two periods of travel.
//   loadrt sim_part [section=SIM_PART]
// Pins sim-part.*: x, y, z (in, mm), setter (in), enable (in, default TRUE:
// FALSE takes the part away), contact, probe (out), gap (out: from the
// tip's surface to the material, mm; negative pressed in).
#include "core/hal/component.hpp"
#include "core/hal/hal.hpp"
#include "core/ini/ini_file.hpp"
#include "sim/machine/components.hpp"
#include "sim/machine/part.hpp"

namespace cnc::sim {
namespace {

class SimPart : public hal::Component {
 public:
  SimPart(hal::ComponentContext& ctx, const hal::LoadArgs& args) : hal::Component(ctx.hal, "sim_part") {
    mark_as_simulation();
    args.allow_only({"section"});
    const std::string section = args.get_string("section", "SIM_PART");
    if (!ctx.ini) throw hal::HalError("sim_part: needs the INI file (its [" + section + "] describes the part)");
    if (!ctx.ini->has_section(section)) {
      throw hal::HalError("sim_part: " + ctx.ini->path().string() + " has no [" + section + "] section");
    }
    part_ = Part::from_ini(*ctx.ini, section.c_str());
    const std::string n = "sim-part.";
    x_ = make_pin<double>(n + "x", hal::PinDir::In);
    y_ = make_pin<double>(n + "y", hal::PinDir::In);
    z_ = make_pin<double>(n + "z", hal::PinDir::In);
    enable_ = make_pin<bool>(n + "enable", hal::PinDir::In, true);
    setter_ = make_pin<bool>(n + "setter", hal::PinDir::In);
    contact_ = make_pin<bool>(n + "contact", hal::PinDir::Out);
    probe_ = make_pin<bool>(n + "probe", hal::PinDir::Out);
    gap_ = make_pin<double>(n + "gap", hal::PinDir::Out);
    export_method<&SimPart::update>("sim-part", this);
  }

  void update(const rt::CycleInfo&) noexcept {
    const double gap = part_.distance(x_.get(), y_.get(), z_.get()) - part_.tip_diameter / 2;
    gap_.set(gap);
    const bool contact = enable_.get() && gap <= 0;
    contact_.set(contact);
    probe_.set(contact || setter_.get());
  }

 private:
  Part part_;
  hal::FloatPin x_, y_, z_, gap_;
  hal::BitPin enable_, setter_, contact_, probe_;
};

}  // namespace

void register_sim_part(hal::ComponentRegistry& registry) {
  registry.add("sim_part", "sim_part [section=SIM_PART]: a simulated block with a bore that trips the probe input",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<SimPart>(ctx, args);
               });
}

}  // namespace cnc::sim
