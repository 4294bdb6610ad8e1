#include "sim/register.hpp"

#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/component.hpp"
#include "sim/ethercat/component.hpp"
#include "sim/ethercat/segment.hpp"
#include "sim/machine/components.hpp"

namespace cnc::sim {

void register_components(hal::ComponentRegistry& registry) {
  can::register_virtual_transport();
  ethercat::sim::register_sim_link_kind();
  cia402::sim::register_sim_component(registry);
  ethercat::sim::register_sim_component(registry);
  register_sim_joint(registry);
  register_sim_toolchanger(registry);
  register_sim_part(registry);
}

}  // namespace cnc::sim
