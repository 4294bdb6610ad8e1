// The Modbus links as a HAL component:
//   loadrt modbus [links=MODBUS[,MODBUS_1...]]
// creates one link per INI section (HAL prefix modbus.0, modbus.1, ...),
// each polled by its own non-realtime thread, with the realtime functions
// modbus.N.read (mailboxes -> pins) and modbus.N.write (pins -> mailboxes)
// for the servo thread: they never allocate, lock, block or throw. Pins per
// VFD in LinuxCNC's spindle shape (modbus.N.vfd.SS.*) and per mapped I/O
// value (modbus.N.io.SS.*); polling starts with the controller's first task
// cycle, so `cncd --check` opens no device.
#pragma once

#include <string>

namespace cnc::hal {
class ComponentRegistry;
class Hal;
}  // namespace cnc::hal

namespace cnc::modbus {

class Link;

void register_components(hal::ComponentRegistry& registry);

// The link `name` ("modbus.0") of a loaded `modbus` component; null if none.
Link* find_link(hal::Hal& hal, const std::string& name);

}  // namespace cnc::modbus
