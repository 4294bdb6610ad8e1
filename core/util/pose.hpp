// A position in the machine's nine coordinates X Y Z A B C U V W (LinuxCNC's
// EmcPose), used by the interpreter, planner, motion and kinematics alike.
// Plain data: cheap to copy, safe in the servo thread and shared memory.
#pragma once

#include <array>
#include <cstddef>

namespace cnc {

enum class Axis : int { X = 0, Y, Z, A, B, C, U, V, W };
inline constexpr int kNumAxes = 9;
inline constexpr const char kAxisLetters[kNumAxes + 1] = "XYZABCUVW";
// Up to 16 joints, as LinuxCNC's EMCMOT_MAX_JOINTS.
inline constexpr int kMaxJoints = 16;

struct Pose {
  std::array<double, kNumAxes> v{};

  double& operator[](int i) noexcept { return v[static_cast<std::size_t>(i)]; }
  double operator[](int i) const noexcept { return v[static_cast<std::size_t>(i)]; }
  double& operator[](Axis a) noexcept { return v[static_cast<std::size_t>(a)]; }
  double operator[](Axis a) const noexcept { return v[static_cast<std::size_t>(a)]; }
  double x() const noexcept { return v[0]; }
  double y() const noexcept { return v[1]; }
  double z() const noexcept { return v[2]; }
  bool operator==(const Pose&) const = default;
};

using JointArray = std::array<double, kMaxJoints>;

// Index of an axis letter (either case), or -1.
constexpr int axis_index(char letter) noexcept {
  for (int i = 0; i < kNumAxes; ++i) {
    if (kAxisLetters[i] == letter || kAxisLetters[i] + ('a' - 'A') == letter) return i;
  }
  return -1;
}

}  // namespace cnc
