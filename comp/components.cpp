// The compensation module's HAL components, by name.
#include "comp/measurement_logger.hpp"
#include "comp/screwcomp_component.hpp"

namespace cnc::comp {

void register_components(hal::ComponentRegistry& registry) {
  registry.add("screwcomp",
               "screwcomp [max_correction=1.0]: screw and backlash compensation tables ([JOINT_n]COMP_FILE) for "
               "motmod's joints; load after motmod",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<ScrewCompComponent>(ctx, args);
               });
  registry.add("complog",
               "complog file=<path> [axis=X] [scale=1000] [temperature=0|1]: records positioning deviations at each "
               "stop of a measurement cycle (ISO 230-2 measurement file)",
               [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<MeasurementLogger>(ctx, args);
               });
}

}  // namespace cnc::comp
