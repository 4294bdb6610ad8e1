// Private to the motion controller: the helpers its parts share
// (motion_controller.cpp: construction, parameters and messages;
// motion_commands.cpp: the commands; motion_cycle.cpp: the servo cycle;
// motion_status.cpp: the status; homing.cpp: homing).
#pragma once

#include "core/motion/motion_controller.hpp"
#include "core/tp/planner.hpp"
#include "kinematics/kinematics.hpp"

namespace cnc::motion::detail {

inline constexpr double kFar = 1e9;  // a continuous jog's target when there is no soft limit

inline const char* tp_result_text(tp::Result r) noexcept {
  switch (r) {
    case tp::Result::Ok: return "ok";
    case tp::Result::QueueFull: return "queue full";
    case tp::Result::InvalidSegment: return "invalid segment";
    case tp::Result::NotAllowed: return "not allowed";
  }
  return "?";
}

inline bool usable_forward(const kin::Kinematics& k) noexcept { return k.type() != kin::KinematicsType::InverseOnly; }

}  // namespace cnc::motion::detail
