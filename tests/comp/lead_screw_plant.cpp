#include "tests/comp/lead_screw_plant.hpp"

#include <cmath>
#include <random>

namespace cnc::testing {

comp::SyntheticAxis lead_screw_truth() {
  comp::SyntheticAxis a;
  a.x_min = 0;
  a.x_max = 300;
  a.scale_ppm = 25;          // the screw is 25 um/m long
  a.bump_um = 4;
  a.bump_at_mm = 170;
  a.bump_width_mm = 45;
  a.lead_mm = 5;
  a.periodic_amplitude_um = 1.2;
  a.periodic_phase_deg = 40;
  a.backlash0_um = 9;        // lost motion between nut and table
  a.backlash1_um = 3;
  a.thermal_ppm_per_k = 0;   // no warm-up here: the fit tests cover it
  a.noise_um = 0.15;         // interferometer noise per servo sample
  a.outliers = 0;
  return a;
}

namespace {

class LeadScrewPlant final : public hal::Component {
 public:
  LeadScrewPlant(hal::ComponentContext& ctx, const hal::LoadArgs& args)
      : hal::Component(ctx.hal, "lead-screw"), truth_(lead_screw_truth()),
        rng_(static_cast<uint64_t>(args.get_int("seed", 1, 0, 1'000'000))) {
    args.allow_only({"seed"});
    motor_ = make_pin<double>("lead-screw.motor-pos", hal::PinDir::In);
    table_ = make_pin<double>("lead-screw.table-pos", hal::PinDir::Out);
    temperature_ = make_pin<double>("lead-screw.temperature", hal::PinDir::Out, 20.0);
    export_method<&LeadScrewPlant::update>("lead-screw", this);
  }

  void update(const rt::CycleInfo&) noexcept {
    const double motor = motor_.get();
    // The nut: the motor's position plus the screw's pitch error (mm).
    const double nut = motor + (truth_.geometric_um(motor) + truth_.periodic_um(motor)) * 1e-3;
    const double half = truth_.backlash_um(motor) * 0.5e-3;
    if (!started_) {
      table_x_ = nut;
      started_ = true;
    }
    // Lost motion: the table stays put until the nut takes it along.
    if (nut - table_x_ > half) table_x_ = nut - half;
    else if (table_x_ - nut > half) table_x_ = nut + half;
    table_.set(table_x_ + noise_(rng_) * truth_.noise_um * 1e-3);
    temperature_.set(truth_.reference_c);
  }

 private:
  comp::SyntheticAxis truth_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
  hal::FloatPin motor_, table_, temperature_;
  double table_x_ = 0;
  bool started_ = false;
};

}  // namespace

void register_lead_screw_plant(hal::ComponentRegistry& registry) {
  registry.add("lead_screw_plant", "lead_screw_plant [seed=N]: test plant: screw pitch error, backlash, interferometer",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<LeadScrewPlant>(ctx, args);
               });
}

}  // namespace cnc::testing
