// The drive layer's HAL component:
//   loadrt cia402 [sections=CIA402[,CIA402_1]]      master-side drive control
// on a bus loaded before it (found through cia402/link.hpp's finders). The
// daemon registers it with register_components(); see docs/cia402.md. The
// simulated drives (cia402_sim) are not part of the product: sim/cia402.
#pragma once

#include <cstddef>

namespace cnc::hal {
class ComponentRegistry;
class Hal;
}  // namespace cnc::hal

namespace cnc::cia402 {

class DriveGroup;

void register_components(hal::ComponentRegistry& registry);

// The drive group of `loadrt cia402` by section order (0 = cia402.0); null if none.
DriveGroup* find_group(hal::Hal& hal, std::size_t index);

}  // namespace cnc::cia402
