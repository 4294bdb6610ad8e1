// Per-joint compensation as the motion controller applies it (the manual's
// 3.6: motor = joint + backlash + screw correction + home offset). The
// controller owns backlash itself; a screw-error table (comp/) plugs in
// here. Realtime: called once per cycle per joint, never allocates.
#pragma once

namespace cnc::motion {

class JointCompensation {
 public:
  virtual ~JointCompensation() = default;
  // Screw correction (motor units) for a joint at `pos_cmd` moving with
  // `vel_cmd` (its sign tells the direction; 0 keeps the last one).
  virtual double correction(double pos_cmd, double vel_cmd) noexcept = 0;
};

}  // namespace cnc::motion
