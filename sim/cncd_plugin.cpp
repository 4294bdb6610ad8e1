// The simulators as cncd's build-time plug-in (core/daemon/plugins.hpp):
// linked into cncd when the build has them (CNC_BUILD_SIM).
#include "core/daemon/plugins.hpp"
#include "sim/register.hpp"

namespace cnc::daemon {

std::vector<Registrar> plugin_registrars() { return {&sim::register_components}; }

}  // namespace cnc::daemon
