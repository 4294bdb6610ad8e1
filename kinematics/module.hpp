// What every kinematics module shares: the joint-to-letter map of
// `coordinates=`, geometry numbers read from HAL pins at each call, and a base
// class that adds identity switching (LinuxCNC's switchkins types 0 and 1).
// Set-up (parsing, binding pins) is non-realtime and may throw; forward and
// inverse are realtime: no allocation, no exceptions.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/hal/pin.hpp"
#include "kinematics/kinematics.hpp"

namespace cnc::kin {

// `coordinates=XYYZ`: joint j is named after the letter coordinates[j].
class JointMap {
 public:
  JointMap() = default;
  // Throws hal::HalError naming `who` (the module) and what was expected:
  // letters from XYZABCUVW, at most kMaxJoints of them, each of `required`
  // present, a letter twice only with `allow_duplicates`.
  static JointMap parse(std::string_view coordinates, const std::string& who, bool allow_duplicates,
                        std::string_view required = "");
  // One joint per letter of `letters`, in order; for fixed-layout modules.
  static JointMap identity(std::string_view letters);

  int num_joints() const noexcept { return n_; }
  int axis_of(int joint) const noexcept { return joint >= 0 && joint < n_ ? axis_[static_cast<std::size_t>(joint)] : -1; }
  // The first joint named after an axis (the one forward kinematics read), or -1.
  int first_joint(int axis) const noexcept { return axis >= 0 && axis < kNumAxes ? first_[static_cast<std::size_t>(axis)] : -1; }
  bool has_axis(int axis) const noexcept { return first_joint(axis) >= 0; }
  uint32_t axis_mask() const noexcept;
  std::string letters() const;  // "XYYZ"

  // joints[j] = pose[axis_of(j)] for every joint.
  void pose_to_joints(const Pose& pose, double* joints) const noexcept;
  // pose[a] = joints[first_joint(a)] for the axes present; the others 0.
  void joints_to_pose(const double* joints, Pose& pose) const noexcept;

 private:
  std::array<int8_t, kMaxJoints> axis_{};
  std::array<int8_t, kNumAxes> first_{-1, -1, -1, -1, -1, -1, -1, -1, -1};
  int n_ = 0;
};

// A geometry number (pivot, link length, matrix entry) a module reads at
// every call: from its HAL pin once bound, a plain value before (tests,
// benchmarks, tools).
class KinParam {
 public:
  explicit KinParam(double initial = 0.0) noexcept : value_(initial) {}
  double get() const noexcept { return pin_.valid() ? pin_.get() : value_; }
  // Sets the plain value, or the pin once bound (only for an unconnected pin:
  // a connected one belongs to its signal's writer).
  void set(double v) noexcept {
    if (pin_.valid()) pin_.set(v);
    else value_ = v;
  }
  void bind(hal::FloatPin pin) noexcept { pin_ = pin; }

 private:
  hal::FloatPin pin_;
  double value_;
};

// What a module may declare on the HAL component it is loaded as.
class HalBinder {
 public:
  virtual ~HalBinder() = default;
  // The component's name, the prefix of its pins ("xyzac-trt-kins").
  virtual const std::string& prefix() const = 0;
  // An IN float pin `<prefix>.<name>`, starting at the loadrt argument
  // `<name>=` when given, else at the parameter's current value.
  virtual void param(const std::string& name, KinParam& p) = 0;
  // OUT pins, full names (LinuxCNC's `kinstype.is-0` has no prefix).
  virtual hal::BitPin out_bit(const std::string& full_name, bool initial) = 0;
  virtual hal::U32Pin out_u32(const std::string& full_name) = 0;
};

// Base of the modules: joint map, type, result conventions (no new output
// unless Ok) and, when `switchable`, type 1 = identity over the joint map.
class KinematicsModule : public Kinematics {
 public:
  KinematicsModule(const char* name, JointMap map, KinematicsType type, bool coupled, bool switchable) noexcept
      : name_(name), map_(map), type_(type), coupled_(coupled), switchable_(switchable) {}

  const char* name() const noexcept override { return name_; }
  KinematicsType type() const noexcept override { return type_; }
  // Non-trivial kinematics need homed joints before world coordinates mean
  // anything (the manual: home first, then coord or teleop).
  bool requires_homing() const noexcept override { return type_ != KinematicsType::Identity; }
  int num_joints() const noexcept override { return map_.num_joints(); }
  uint32_t axis_mask() const noexcept override { return map_.axis_mask(); }
  int joint_axis(int joint) const noexcept override {
    return coupled_ && active_switch() == 0 ? -1 : map_.axis_of(joint);
  }
  int joint_coordinate(int joint) const noexcept override { return map_.axis_of(joint); }

  KinResult forward(const double* joints, Pose& pose) const noexcept final;
  KinResult inverse(const Pose& pose, const double* hint, double* joints) const noexcept final;

  bool switch_to(int kins_type) noexcept override;
  int active_switch() const noexcept override { return active_.load(std::memory_order_relaxed); }
  bool is_switchable() const noexcept { return switchable_; }

  const JointMap& joint_map() const noexcept { return map_; }
  // Non-realtime: declares the module's pins (the base adds kinstype.is-N
  // for switchable modules). Called once by the component.
  virtual void bind(HalBinder& binder);

 protected:
  // The module's own kinematics (type 0). `pose`/`joints` may be written
  // even on failure: the base discards them.
  virtual KinResult forward_own(const double* joints, Pose& pose) const noexcept = 0;
  virtual KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept = 0;

 private:
  const char* name_;
  JointMap map_;
  KinematicsType type_;
  bool coupled_;
  bool switchable_;
  std::atomic<int> active_{0};
  hal::BitPin is_type_[2];
};

}  // namespace cnc::kin
