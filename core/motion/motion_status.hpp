// What the motion controller publishes each servo cycle for the task side
// and the status block: trajectory, joints, axes, spindles, plus the
// bookkeeping the task needs to synchronise (last command answered,
// planner queue depth). Written under a sequence lock; plain data.
#pragma once

#include <cstdint>

#include "core/ipc/status.hpp"
#include "core/tp/planner.hpp"
#include "core/util/fixed_string.hpp"

namespace cnc::motion {

struct MotionStatus {
  ipc::TrajStatus traj;
  ipc::JointStatus joints[kMaxJoints];
  ipc::AxisStatus axes[kNumAxes];
  ipc::SpindleStatus spindles[ipc::kMaxSpindles];
  uint64_t cycles = 0;
  uint64_t last_serial = 0;   // last command the servo thread answered
  bool all_homed = false;
  bool any_homing = false;
  bool tp_done = true;
  // The modal state of the executing move's line (of the last executed
  // move once the queue ran empty); see tp::StateTag.
  tp::StateTag tag;
  bool jogging = false;
  bool faulted = false;       // a fault disabled motion and is not cleared yet
  // Enabled, and every active joint's amplifier reported ready
  // (joint.N.amp-ready-in) since; until then motion takes no motion command.
  bool amps_ready = false;
  int32_t amp_waiting_joint = -1;  // the first joint whose amplifier is not ready yet, -1 none
  int32_t homing_sequence_active = -1;
  // The last fault that disabled motion (cleared by the next enable): its
  // text, and the joint or spindle whose amplifier faulted (-1 none).
  FixedString<200> fault_reason;
  int32_t fault_joint = -1;
  int32_t fault_spindle = -1;
  // Coordinated motion is paused because the servo thread was late
  // (OVERRUN_ACTION = HOLD); cleared by resume, step, abort or disable.
  bool overrun_hold = false;
  uint32_t overrun_holds = 0;  // such holds so far: the task pauses on each new one
  // A feed move waited longer than [SPINDLE_n]AT_SPEED_TIMEOUT for
  // spindle.N.at-speed: motion aborted the queued moves; the task aborts the
  // program on each new one, with the reason.
  uint32_t spindle_timeouts = 0;
  FixedString<200> spindle_timeout_reason;
  double servo_exec_ns = 0;
};

}  // namespace cnc::motion
