// genserkins: a general 6-joint serial arm from Denavit-Hartenberg
// parameters (LinuxCNC's genserkins: Craig's modified convention, pins
// a-N, alpha-N (radians), d-N). Forward is closed form; inverse iterates
// (damped Newton on the geometric Jacobian, Eigen fixed-size types) from the
// hint, so successive cycles stay on the hint's branch. Results: Singular
// when the solution's Jacobian is near rank loss (a jump would follow),
// Unreachable out of reach, JointLimit outside min/max-limit-N,
// NotConverged when the iteration budget runs out. Pose: X Y Z of the last
// frame, A B C its roll, pitch, yaw in degrees (R = Rz(C) Ry(B) Rx(A)).
// Switchable: type 1 is identity (joint N = axis N of XYZABC). Realtime: no
// allocation, bounded time (max-iterations).
#pragma once

#include <array>

#include "kinematics/module.hpp"

namespace cnc::kin {

class GenserKins final : public KinematicsModule {
 public:
  static constexpr int kJoints = 6;

  // Link i (0..5): Rx(alpha-i) Tx(a-i) Rz(joint i) Tz(d-i); a prismatic
  // joint adds to d-i instead of turning. Lengths in machine units.
  struct Params {
    std::array<KinParam, kJoints> a, alpha, d;
    // Joint limits (degrees, or length for prismatic joints); [JOINT_N]
    // MIN_LIMIT/MAX_LIMIT from the INI when the component is loaded.
    std::array<KinParam, kJoints> min_limit{KinParam{-1e9}, KinParam{-1e9}, KinParam{-1e9},
                                            KinParam{-1e9}, KinParam{-1e9}, KinParam{-1e9}};
    std::array<KinParam, kJoints> max_limit{KinParam{1e9}, KinParam{1e9}, KinParam{1e9},
                                            KinParam{1e9}, KinParam{1e9}, KinParam{1e9}};
    KinParam max_iterations{100};
    // Smallest singular value of the Jacobian (position rows divided by the
    // arm's length scale, rotation rows in radians) below which a pose is
    // Singular: 1e-3 is about 0.15 degrees from the wrist singularity of a
    // 6-axis arm of 1 m reach.
    KinParam singular_threshold{1e-3};
  };

  // `prismatic[i]`: joint i slides (LinuxCNC's genserkins has revolute only).
  explicit GenserKins(std::array<bool, kJoints> prismatic = {}) noexcept;

  Params& params() noexcept { return p_; }
  bool is_prismatic(int joint) const noexcept { return prismatic_[static_cast<std::size_t>(joint)]; }
  // Pins a-N alpha-N d-N min-limit-N max-limit-N max-iterations
  // singular-threshold, and OUT last-iterations.
  void bind(HalBinder& binder) override;

  // Smallest normalised singular value of the Jacobian at `joints` (see
  // singular_threshold). Realtime-safe; for tests and diagnostics.
  double singularity_measure(const double* joints) const noexcept;
  // Iterations the last inverse took (also on pin last-iterations).
  unsigned last_iterations() const noexcept { return last_iterations_.load(std::memory_order_relaxed); }

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override;
  KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept override;

 private:
  Params p_;
  std::array<bool, kJoints> prismatic_;
  hal::U32Pin last_iterations_pin_;
  mutable std::atomic<unsigned> last_iterations_{0};
};

}  // namespace cnc::kin
