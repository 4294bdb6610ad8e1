// The motion module's HAL component, for the daemon's registry.
#include "core/hal/component.hpp"
#include "core/motion/motion_component.hpp"

namespace cnc::motion {

void register_components(hal::ComponentRegistry& registry, PlannerFactory planner_factory) {
  registry.add("motmod",
               "motmod [servo_period_nsec=N] [num_joints=N] [num_dio=N] [num_aio=N] [num_spindles=N]: the motion "
               "controller",
               [planner_factory](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
                 return std::make_unique<MotionComponent>(ctx, args, planner_factory);
               });
}

}  // namespace cnc::motion
