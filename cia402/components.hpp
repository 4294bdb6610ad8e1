// The drive profile's HAL components:
//   loadrt cia402 [sections=CIA402[,CIA402_1]]      master-side drive control
//   loadrt cia402_sim [sections=CIA402_SIM[,...]]   simulated drives (in-process)
// The daemon registers them with register_components(); see docs/cia402.md.
#pragma once

#include <cstddef>

namespace cnc::hal {
class ComponentRegistry;
class Hal;
}  // namespace cnc::hal

namespace cnc::cia402 {

class DriveGroup;

void register_components(hal::ComponentRegistry& registry);
void register_master_component(hal::ComponentRegistry& registry);

// The drive group of `loadrt cia402` by section order (0 = cia402.0); null if none.
DriveGroup* find_group(hal::Hal& hal, std::size_t index);

}  // namespace cnc::cia402
