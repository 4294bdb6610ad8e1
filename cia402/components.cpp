#include "cia402/components.hpp"

#include "cia402/sim/sim_component.hpp"

namespace cnc::cia402 {

void register_components(hal::ComponentRegistry& registry) {
  register_master_component(registry);
  sim::register_sim_component(registry);
}

}  // namespace cnc::cia402
