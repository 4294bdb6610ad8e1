// Forward and inverse kinematics as the motion controller uses them (the
// manual's sections 3.3, 3.6, 3.25). forward/inverse run in the servo thread:
// they never allocate (fixed-size Eigen types only), never throw, and report
// unreachable or singular poses as results instead of jumping.
#pragma once

#include <cstdint>
#include <string>

#include "core/hal/component.hpp"
#include "core/util/pose.hpp"

namespace cnc::kin {

// LinuxCNC's KINEMATICS_IDENTITY / BOTH / FORWARD_ONLY / INVERSE_ONLY.
enum class KinematicsType : uint8_t { Identity, Both, ForwardOnly, InverseOnly };

enum class KinResult : uint8_t { Ok, Unreachable, Singular, JointLimit, NotConverged };
const char* to_string(KinResult r) noexcept;

class Kinematics {
 public:
  virtual ~Kinematics() = default;

  virtual const char* name() const noexcept = 0;
  virtual KinematicsType type() const noexcept = 0;
  // True when the forward kinematics cannot be trusted until the joints are
  // homed (the manual: carte_pos_fb is then unknown, not invented).
  virtual bool requires_homing() const noexcept { return false; }
  virtual int num_joints() const noexcept = 0;
  // Bit i set: axis i (X=0 ... W=8) is used.
  virtual uint32_t axis_mask() const noexcept = 0;
  // Axis a joint moves (trivkins and gantries), or -1 when joints and axes
  // are coupled (5-axis, SCARA, arms) under the active kinematics.
  virtual int joint_axis(int joint) const noexcept = 0;
  // Axis letter a joint is named after by `coordinates=` (X=0 ... W=8), or
  // -1: for labels, and for gantries (two joints, one letter) even when the
  // kinematics couple the joints.
  virtual int joint_coordinate(int joint) const noexcept { return joint_axis(joint); }

  // Linear joints and axes in machine units, rotary ones in degrees. On a
  // result other than Ok the output holds no new position: forward leaves
  // `pose` as it was, inverse copies `hint` (when given) to `joints`.
  // joints[0..num_joints) -> pose.
  virtual KinResult forward(const double* joints, Pose& pose) const noexcept = 0;
  // pose -> joints[0..num_joints); `hint` holds the previous joints (may be
  // null: then the module's home configuration is the start).
  virtual KinResult inverse(const Pose& pose, const double* hint, double* joints) const noexcept = 0;

  // Switchable kinematics (identity for setup, full for machining): the
  // motion controller calls this only while stopped. Type 0 is the module's
  // own kinematics, 1 identity (LinuxCNC's switchkins numbering). Returns
  // false, and keeps the active type, when the module has no such type.
  virtual bool switch_to(int kins_type) noexcept { return kins_type == 0; }
  virtual int active_switch() const noexcept { return 0; }
};

// The HAL component a kinematics module is loaded as (`loadrt trivkins
// coordinates=XYZ`). The motion controller finds the one loaded.
class KinematicsComponent : public hal::Component {
 public:
  using hal::Component::Component;
  virtual Kinematics& kinematics() noexcept = 0;
};

// The kinematics module loaded into `hal` (at most one is), or null.
KinematicsComponent* find_kinematics(hal::Hal& hal);

// Registers every kinematics module (trivkins, matrixkins, 5-axis, SCARA,
// serial arms) with the HAL component registry.
void register_kinematics_components(hal::ComponentRegistry& registry);

}  // namespace cnc::kin
