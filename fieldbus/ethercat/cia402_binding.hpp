// The drive layer's link (cia402/link.hpp) over the EtherCAT master: slots
// in the master's process image, realtime SDO requests done by the
// master's worker, blocking CoE SDO for start-up, and the slave's health
// from its AL state and the cyclic exchange. A drive's address is its ring
// position (1 = first slave after the master). register_components()
// registers the finder that gives `loadrt cia402` the link of an EtherCAT
// bus ([CIA402] BUS = ethercat.0).
#pragma once

#include <memory>

#include "cia402/link.hpp"

namespace cnc::ethercat {

class Master;

std::unique_ptr<cia402::DriveLink> make_cia402_link(Master& master);

}  // namespace cnc::ethercat
