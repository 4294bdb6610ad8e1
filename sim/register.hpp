// The simulators: simulated CiA 402 drives on a CAN bus (cia402_sim), on an
// EtherCAT segment (ethercat_sim), simulated joints (sim_joint) and a tool
// changer (sim_toolchanger), with the simulated buses they need ("virtual:"
// CAN transports, "sim:" EtherCAT links). None of this is part of the
// product: product libraries never include or link sim/; a build chooses
// whether cncd gets them (CNC_BUILD_SIM, sim/cncd_plugin.cpp), as
// ros2_control keeps its mock hardware apart.
#pragma once

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::sim {

// Registers every simulator's HAL component and the simulated bus kinds
// with can::open_transport and ethercat::open_link. Non-realtime.
void register_components(hal::ComponentRegistry& registry);

}  // namespace cnc::sim
