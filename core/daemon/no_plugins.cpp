// cncd without plug-ins: a build without the simulators (CNC_BUILD_SIM=OFF).
#include "core/daemon/plugins.hpp"

namespace cnc::daemon {

std::vector<Registrar> plugin_registrars() { return {}; }

}  // namespace cnc::daemon
