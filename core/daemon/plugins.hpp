// Components a build adds to cncd beyond the product's own
// (register_all_components): the simulators of sim/. They are chosen when
// the cncd program is linked, never by a product library: cncd links
// sim/cncd_plugin.cpp when the build has the simulators (CNC_BUILD_SIM, on
// by default), else no_plugins.cpp, and then `loadrt cia402_sim` answers
// that the component is unknown.
#pragma once

#include <vector>

namespace cnc::hal {
class ComponentRegistry;
}

namespace cnc::daemon {

using Registrar = void (*)(hal::ComponentRegistry& registry);

// The registrars of the plug-in linked into this program.
std::vector<Registrar> plugin_registrars();

}  // namespace cnc::daemon
