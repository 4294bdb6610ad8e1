// Plant simulators for machines without drives and for tests, as HAL
// components (not part of the product; sim/register.hpp registers them):
//   loadrt sim_joint [count=N|names=a,b]   joints that follow their command
//       with a lag, with home and limit switches and index pulses
//   loadrt sim_toolchanger                 answers iocontrol's tool-prepare
//       and tool-change after configurable delays (or hangs, for timeouts)
//   loadrt sim_part [section=SIM_PART]     a block with a bore that trips
//       the probe input where the probe tip touches it (sim/machine/part.hpp)
#pragma once

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::sim {

void register_sim_joint(hal::ComponentRegistry& registry);
void register_sim_toolchanger(hal::ComponentRegistry& registry);
void register_sim_part(hal::ComponentRegistry& registry);

}  // namespace cnc::sim
