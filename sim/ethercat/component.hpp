// Simulated EtherCAT drives as a HAL component, for simulated machines:
//   loadrt ethercat_sim [name=sim] [drives=3]
// a segment of simulated CiA 402 drives in-process, for a master whose
// INTERFACE is sim:<name> (load it before the master). The slaves keep
// their own time on a thread of their own: watchdogs expire and drives
// coast while no frame arrives, as on real hardware.
#pragma once

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::ethercat::sim {

void register_sim_component(hal::ComponentRegistry& registry);

}  // namespace cnc::ethercat::sim
