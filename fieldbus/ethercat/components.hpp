// The EtherCAT HAL components:
//   loadrt ethercat [buses=ETHERCAT[,ETHERCAT_1]]   the master per INI section:
//       functions ethercat.N.read (first in the servo thread) and
//       ethercat.N.write (last); start-up in on_ready (throws with slave,
//       object and reason); the DC lock steers the thread named by THREAD.
// Registering also tells `loadrt cia402` how to find an EtherCAT bus
// ([CIA402] BUS = ethercat.0, drive ADDRESS = ring position).
#pragma once

#include <string>

namespace cnc::hal {
class ComponentRegistry;
class Hal;
}  // namespace cnc::hal

namespace cnc::ethercat {

class Master;

void register_components(hal::ComponentRegistry& registry);
// The master of bus `name` ("ethercat.0"); null if none is loaded.
Master* find_master(hal::Hal& hal, const std::string& name);

}  // namespace cnc::ethercat
