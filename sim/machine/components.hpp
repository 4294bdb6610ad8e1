// Plant simulators for machines without drives and for tests, as HAL
// components (not part of the product; sim/register.hpp registers them):
//   loadrt sim_joint [count=N|names=a,b]   joints that follow their command
//       with a lag, with home and limit switches and index pulses
//   loadrt sim_toolchanger                 answers iocontrol's tool-prepare
//       and tool-change after configurable delays (or hangs, for timeouts)
#pragma once

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::sim {

void register_sim_joint(hal::ComponentRegistry& registry);
void register_sim_toolchanger(hal::ComponentRegistry& registry);

}  // namespace cnc::sim
