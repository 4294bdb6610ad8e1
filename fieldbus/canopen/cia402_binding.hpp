// The drive layer's link (cia402/link.hpp) over the CANopen master: process
// data slots from the master's PDO images, realtime SDO slots for unmapped
// objects, blocking SDO for start-up configuration, and node health from
// NMT, heartbeat and PDO reception. A drive's address is its node-ID.
// register_components() registers the finder that gives `loadrt cia402` the
// link of a CANopen bus ([CIA402] BUS = canopen.0).
#pragma once

#include <memory>

#include "cia402/link.hpp"

namespace cnc::canopen {

class Master;

std::unique_ptr<cia402::DriveLink> make_cia402_link(Master& master);

}  // namespace cnc::canopen
