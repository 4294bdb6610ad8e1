// The drive layer's link over a CANopen master (fieldbus/canopen): process
// data slots from the master's PDO images, realtime SDO slots for unmapped
// objects, blocking SDO for start-up configuration, and node health from
// NMT, heartbeat and PDO reception. The only file of cia402/ that knows
// CANopen; the EtherCAT master provides its own DriveLink.
#pragma once

#include <memory>
#include <string>

#include "cia402/link.hpp"

namespace cnc::canopen {
class Master;
}
namespace cnc::hal {
class Hal;
}

namespace cnc::cia402 {

std::unique_ptr<DriveLink> make_canopen_link(canopen::Master& master);

// The link of a bus by its HAL prefix ("canopen.0"), found among the loaded
// components; throws std::runtime_error naming the bus when none is loaded.
std::unique_ptr<DriveLink> find_link(hal::Hal& hal, const std::string& bus);

// Other fieldbuses (EtherCAT) register how to find their links by bus name;
// a finder returns null for a bus that is not its own.
using LinkFinder = std::unique_ptr<DriveLink> (*)(hal::Hal& hal, const std::string& bus);
void register_link_finder(LinkFinder finder);

}  // namespace cnc::cia402
