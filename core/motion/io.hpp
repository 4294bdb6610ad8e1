// What the motion controller reads and writes each servo cycle, as plain
// structs. The HAL component copies its pins into and out of these (so the
// controller itself can be run, tested and benchmarked without a HAL); the
// names match LinuxCNC's motion pins (joint.N.*, axis.L.*, motion.*,
// spindle.N.*).
#pragma once

#include <array>
#include <cstdint>

#include "core/util/pose.hpp"

namespace cnc::motion {

inline constexpr int kMaxDio = 64;
inline constexpr int kMaxAio = 16;
inline constexpr int kMaxSpindles = 8;

struct JointInputs {
  double motor_pos_fb = 0;    // joint.N.motor-pos-fb
  bool amp_fault = false;     // joint.N.amp-fault-in
  bool amp_ready = true;      // joint.N.amp-ready-in (unconnected: ready)
  bool home_sw = false;       // joint.N.home-sw-in
  bool pos_lim_sw = false;    // joint.N.pos-lim-sw-in
  bool neg_lim_sw = false;    // joint.N.neg-lim-sw-in
  bool index_enable = false;  // joint.N.index-enable (I/O: cleared by the feedback device at the index)
  double index_position = 0;  // joint.N.index-position: motor position latched at the index
  // joint.N.probe-position / probe-count: the motor position a drive's touch
  // probe latched at the probe input's edge and the number of latches so
  // far (cia402 drive.NN.probe-position/-count); unconnected: 0, unused.
  double probe_position = 0;
  uint32_t probe_count = 0;
  bool probe_latch_wired = false;  // probe-count is linked: a touch probe latches for this joint
  bool is_unlocked = false;   // joint.N.is-unlocked (locking indexer)
  bool drive_home_busy = false;   // joint.N.drive-home-busy
  bool drive_home_done = false;   // joint.N.drive-home-done
  bool drive_home_error = false;  // joint.N.drive-home-error
  int32_t jog_counts = 0;     // joint.N.jog-counts (MPG)
  bool jog_enable = false;    // joint.N.jog-enable
  double jog_scale = 0;       // joint.N.jog-scale
  bool jog_vel_mode = false;  // joint.N.jog-vel-mode
};

struct JointOutputs {
  double motor_pos_cmd = 0, pos_cmd = 0, pos_fb = 0, coarse_pos_cmd = 0;
  double vel_cmd = 0, acc_cmd = 0;
  double f_error = 0, f_error_lim = 0;
  double motor_offset = 0, backlash_corr = 0, backlash_filt = 0, backlash_vel = 0;
  double free_pos_cmd = 0, free_vel_lim = 0;
  bool amp_enable = false;
  int8_t index_enable_write = -1;  // -1: leave the pin alone, 0/1: write it
  bool active = true, homed = false, homing = false, faulted = false, f_errored = false;
  bool in_position = true, free_tp_enable = false;
  bool pos_hard_limit = false, neg_hard_limit = false;
  bool unlock = false;
  bool drive_home_start = false;
  int32_t home_state = 0;
};

struct AxisInputs {
  int32_t jog_counts = 0;
  bool jog_enable = false;
  double jog_scale = 0;
  bool jog_vel_mode = false;
};

struct AxisOutputs {
  double pos_cmd = 0;          // axis.L.pos-cmd
  double teleop_pos_cmd = 0;   // axis.L.teleop-pos-cmd
  double teleop_vel_cmd = 0;
  double teleop_vel_lim = 0;
  bool teleop_tp_enable = false;
};

struct SpindleInputs {
  bool at_speed = true;        // spindle.N.at-speed
  double speed_in = 0;         // spindle.N.speed-in (rps)
  bool is_oriented = false;
  int32_t orient_fault = 0;
  bool amp_fault = false;
};

struct SpindleOutputs {
  double speed_out = 0, speed_out_abs = 0, speed_out_rps = 0, speed_cmd_rps = 0;
  bool on = false, forward = false, reverse = false, brake = true;
  bool orient = false;
  double orient_angle = 0;
  int32_t orient_mode = 0;
};

struct MotionInputs {
  bool enable = true;          // motion.enable: false disables motion (an external stop)
  bool probe_input = false;    // motion.probe-input
  bool feed_hold = false;      // motion.feed-hold
  bool feed_inhibit = false;   // motion.feed-inhibit
  bool homing_inhibit = false; // motion.homing-inhibit
  bool jog_inhibit = false;    // motion.jog-inhibit
  bool jog_stop = false;       // motion.jog-stop
  bool jog_stop_immediate = false;
  double adaptive_feed = 1.0;  // motion.adaptive-feed
  // Not motion pins: the shared segment's E-stop request word and the
  // E-stop chain (iocontrol.0.emc-enable-in), wired by the daemon
  // (MotionComponent::set_estop_inputs) so that every configuration has them.
  uint64_t estop_request = 0;
  bool estop_chain_closed = true;
  // From the servo thread's rt::CycleInfo, not from pins: the thread is
  // late (OVERRUN_STREAK reached), with the streak and the slots just missed.
  bool servo_late = false;
  uint32_t overrun_streak = 0;
  int64_t missed_cycles = 0;
  std::array<bool, kMaxDio> digital_in{};
  std::array<double, kMaxAio> analog_in{};
  std::array<JointInputs, kMaxJoints> joints{};
  std::array<AxisInputs, kNumAxes> axes{};
  std::array<SpindleInputs, kMaxSpindles> spindles{};
};

struct MotionOutputs {
  bool motion_enabled = false, in_position = true, coord_mode = false, teleop_mode = false;
  bool coord_error = false, on_soft_limit = false, is_all_homed = false;
  bool jog_is_active = false, tp_reverse = false;
  bool watchdog = false;       // motion.watchdog: toggles every cycle while motion is enabled
  bool watchdog_enabled = false;  // motion.watchdog-enabled: motion is enabled
  int32_t program_line = 0, motion_type = 0;
  double current_vel = 0, requested_vel = 0, distance_to_go = 0;
  double servo_last_period_ns = 0;
  Pose tool_offset;
  std::array<bool, kMaxDio> digital_out{};
  std::array<double, kMaxAio> analog_out{};
  std::array<JointOutputs, kMaxJoints> joints{};
  std::array<AxisOutputs, kNumAxes> axes{};
  std::array<SpindleOutputs, kMaxSpindles> spindles{};
};

}  // namespace cnc::motion
