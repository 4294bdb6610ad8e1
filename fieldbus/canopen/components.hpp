// The CANopen master as a HAL component:
//   loadrt canopen [buses=CANOPEN[,CANOPEN_1...]]
// creates one master per INI section (HAL prefix canopen.0, canopen.1, ...)
// with the realtime functions canopen.N.read and canopen.N.write for the
// servo thread (addf: read first, write last), status pins per bus and per
// node, and optional pins for every mapped object. The boot of all nodes
// runs when the HAL files are done (on_ready); a failure stops the
// controller's start-up with the node, object and reason.
#pragma once

#include <string>

namespace cnc::hal {
class ComponentRegistry;
class Hal;
}  // namespace cnc::hal

namespace cnc::canopen {

class Master;

void register_components(hal::ComponentRegistry& registry);

// The master of bus `name` ("canopen.0") created by `loadrt canopen`, for
// components that drive devices through it (CiA 402); null if none.
Master* find_master(hal::Hal& hal, const std::string& name);

}  // namespace cnc::canopen
