// One place lists every module's components. A module that is not built
// (its library target does not exist) is left out by CMake definitions.
#include "core/daemon/controller.hpp"

#ifdef CNC_HAVE_KINEMATICS
#include "kinematics/kinematics.hpp"
#endif
#ifdef CNC_HAVE_MOTION
#include "core/motion/motion_component.hpp"
#endif
#ifdef CNC_HAVE_TP
#include "core/tp/lookahead_planner.hpp"
#endif
#ifdef CNC_HAVE_CANOPEN
#include "fieldbus/canopen/components.hpp"
#endif
#ifdef CNC_HAVE_ETHERCAT
#include "fieldbus/ethercat/components.hpp"
#endif
#ifdef CNC_HAVE_MODBUS
#include "fieldbus/modbus/component.hpp"
#endif
#ifdef CNC_HAVE_CIA402
#include "cia402/components.hpp"
#endif
#ifdef CNC_HAVE_COMP
#include "comp/screwcomp_component.hpp"
#endif
#ifdef CNC_HAVE_HALUI
#include "core/halui/halui.hpp"
#endif

namespace cnc::daemon {

void register_all_components(hal::ComponentRegistry& registry) {
  hal::register_core_components(registry);
#ifdef CNC_HAVE_HALUI
  halui::register_components(registry);
#endif
#ifdef CNC_HAVE_KINEMATICS
  kin::register_kinematics_components(registry);
#endif
#ifdef CNC_HAVE_MOTION
  motion::PlannerFactory planner;
#ifdef CNC_HAVE_TP
  planner = [](const tp::PlannerConfig& c) { return tp::make_planner(c); };
#else
  planner = [](const tp::PlannerConfig&) -> std::unique_ptr<tp::TrajectoryPlanner> {
    throw hal::HalError("motmod: this build has no trajectory planner (core/tp)");
  };
#endif
  motion::register_components(registry, planner);
#endif
#ifdef CNC_HAVE_CANOPEN
  canopen::register_components(registry);
#endif
#ifdef CNC_HAVE_ETHERCAT
  ethercat::register_components(registry);
#endif
#ifdef CNC_HAVE_MODBUS
  modbus::register_components(registry);
#endif
#ifdef CNC_HAVE_CIA402
  cia402::register_components(registry);
#endif
#ifdef CNC_HAVE_COMP
  comp::register_components(registry);
#endif
}

}  // namespace cnc::daemon
