// 5-axis mills whose rotary axes tilt the work (table-table: LinuxCNC's
// xyzac-trt-kins and xyzbc-trt-kins) or tilt the tool and turn the work
// (head-table). Both keep the tool tip on the programmed point while the
// rotary axes move (tool-centre-point behaviour), closed form both ways.
//
// Conventions (as LinuxCNC's trt modules, so their HAL settings carry over):
// - The pose is the controlled point in the workpiece frame, the frame that
//   turns with the table and equals the machine frame at A/B = C = 0. It
//   carries the active tool length along workpiece Z as the interpreter adds
//   it (G43); `tool-offset` must hold that same length (net it to the motion
//   controller's tool offset Z), so the kinematics find the tip.
// - Joints X Y Z are the machine's slides: the spindle gauge point, tool
//   length above the tip with the head upright. Rotary joints equal the pose
//   angles, in degrees. C turns the table positively about +Z, A and B turn
//   positively about +X and +Y (right hand).
// Switchable: type 1 is identity over `coordinates=`. Realtime: no allocation.
#pragma once

#include <cstdint>

#include "kinematics/module.hpp"

namespace cnc::kin {

// The axis a tilting table or head turns about: A about X, B about Y.
enum class TiltAxis : uint8_t { A, B };

// Tilting table (A or B) carrying a rotary table (C).
// Geometry pins (prefix = module name):
//   x-rot-point y-rot-point z-rot-point: a point of the C axis (its centre on
//     the table face); the C axis is the vertical line through it at A/B = 0.
//   x-offset y-offset z-offset: from that point to the tilt axis (the
//     component along the tilt axis is irrelevant).
//   tool-offset: the active tool length (see above).
class TableTableKins final : public KinematicsModule {
 public:
  struct Params {
    KinParam x_rot_point, y_rot_point, z_rot_point;
    KinParam x_offset, y_offset, z_offset;
    KinParam tool_offset;
  };
  // `map` must name X Y Z C and the tilt letter.
  TableTableKins(const char* name, TiltAxis tilt, JointMap map) noexcept
      : KinematicsModule(name, map, KinematicsType::Both, /*coupled=*/true, /*switchable=*/true), tilt_(tilt) {}

  Params& params() noexcept { return p_; }
  TiltAxis tilt() const noexcept { return tilt_; }
  void bind(HalBinder& binder) override;

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override;
  KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept override;

 private:
  TiltAxis tilt_;
  Params p_;
};

// Tilting head (A or B) over a rotary table (C).
// Geometry pins:
//   x-rot-point y-rot-point: where the vertical C axis crosses the XY plane.
//   pivot-length: from the head's tilt axis down to the spindle gauge point
//     along the tool axis.
//   tool-offset: the active tool length (see above).
class HeadTableKins final : public KinematicsModule {
 public:
  struct Params {
    KinParam x_rot_point, y_rot_point;
    KinParam pivot_length;
    KinParam tool_offset;
  };
  HeadTableKins(const char* name, TiltAxis head, JointMap map) noexcept
      : KinematicsModule(name, map, KinematicsType::Both, /*coupled=*/true, /*switchable=*/true), head_(head) {}

  Params& params() noexcept { return p_; }
  TiltAxis head() const noexcept { return head_; }
  void bind(HalBinder& binder) override;

 protected:
  KinResult forward_own(const double* joints, Pose& pose) const noexcept override;
  KinResult inverse_own(const Pose& pose, const double* hint, double* joints) const noexcept override;

 private:
  TiltAxis head_;
  Params p_;
};

}  // namespace cnc::kin
