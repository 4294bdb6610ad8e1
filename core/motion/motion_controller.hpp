// The motion controller (the manual's chapter 3): commands, the free,
// teleop and coord modes, homing, limits, following error, the seven
// position forms, backlash and compensation, watchdog. It runs in the servo
// thread: handle() and update() never allocate, block or throw. Inputs and
// outputs are plain structs (io.hpp); the HAL component maps them to pins.
#pragma once

#include <array>

#include "core/motion/command.hpp"
#include "core/motion/compensation.hpp"
#include "core/motion/config.hpp"
#include "core/motion/free_planner.hpp"
#include "core/motion/io.hpp"
#include "core/motion/motion_status.hpp"
#include "core/tp/planner.hpp"
#include "kinematics/kinematics.hpp"

namespace cnc {
class MessageQueue;
}

namespace cnc::motion {

enum class HomeState : uint8_t {
  Idle = 0,
  Start,
  UnlockWait,
  InitialBackoff,
  InitialSearch,
  FinalBackoff,
  RiseSearch,
  FallSearch,
  IndexSearch,
  StopAfterLatch,
  WaitGroup,
  FinalMove,
  LockWait,
  DriveHoming,
  Finished,
};
const char* to_string(HomeState s) noexcept;

// The planner configuration a motion configuration implies, with the
// [AXIS_L] limits alone (the motion controller narrows them by the joints',
// MotionController::apply_limits).
tp::PlannerConfig planner_config(const MotionConfig& config, uint32_t axis_mask);

// The speed sent to a spindle for a commanded `rpm` (command x override),
// kept within its [SPINDLE_n] limits (LinuxCNC's clamp): 0 stays 0.
double limit_spindle_speed(double rpm, const SpindleConfig& limits) noexcept;

class MotionController {
 public:
  // Non-realtime construction. `config` is also the machine's limits:
  // run-time changes (SET_xxx) may only be stricter than it. `messages`
  // may be null (tests).
  MotionController(const MotionConfig& config, kin::Kinematics& kinematics, tp::TrajectoryPlanner& planner,
                   MessageQueue* messages);

  // Screw compensation for a joint (before the servo thread starts).
  void set_compensation(int joint, JointCompensation* comp) noexcept;

  // --- servo thread ---
  // Handles one command. Returns false when it cannot be taken now (the
  // planner queue is full): the caller offers it again next cycle.
  bool handle(const MotionCommand& cmd, MotionResult& result) noexcept;
  // One servo period: reads in(), writes out().
  void update(double dt) noexcept;
  void fill_status(MotionStatus& s) const noexcept;

  MotionInputs& in() noexcept { return in_; }
  const MotionOutputs& out() const noexcept { return out_; }
  // The parameters in force (the INI's, as changed at run time).
  const MotionConfig& config() const noexcept { return cfg_; }
  // What an axis moves under in coordinated and teleop motion.
  const FreeLimits& axis_limits(int axis) const noexcept { return axis_lim_[static_cast<std::size_t>(axis)]; }
  ipc::MotionMode mode() const noexcept { return mode_; }
  bool enabled() const noexcept { return enabled_; }
  bool estop_latched() const noexcept { return estop_latched_; }
  // The E-stop request word last acted on (the segment's acknowledgement).
  uint64_t estop_request_seen() const noexcept { return estop_seen_; }
  bool all_homed() const noexcept;
  bool in_position() const noexcept;
  const Pose& carte_pos_cmd() const noexcept { return carte_cmd_; }

 private:
  struct Joint {
    bool active = true;
    bool amp_enabled = false;
    bool homed = false;
    HomeState home_state = HomeState::Idle;
    bool jogging = false;
    bool jog_override_limits = false;
    double coarse_pos = 0, pos_cmd = 0, pos_fb = 0, vel_cmd = 0, acc_cmd = 0;
    double motor_offset = 0;
    // backlash_corr: the correction asked for (+-BACKLASH/2 or the screw
    // table's); backlash_filt: the one applied, ramped within the limits.
    double backlash_corr = 0, backlash_filt = 0, backlash_vel = 0;
    CompensationRamp comp_ramp;
    double screw_comp = 0;  // stays 0: the ramped total is in backlash_filt
    double ferror = 0, ferror_limit = 0, ferror_high = 0;
    bool ferror_fault = false, amp_fault = false;
    bool on_pos_limit = false, on_neg_limit = false;
    bool soft_min = false, soft_max = false;
    FreePlanner free;
    // homing scratch
    bool stopping = false;          // waiting for the planner to stop before next_state
    HomeState next_state = HomeState::Idle;
    bool index_armed = false;
    bool drive_home_request = false;
    bool unlock_request = false;
    int32_t prev_jog_counts = 0;
    bool jog_counts_valid = false;
  };

  // commands
  const char* cmd_mode(ipc::MotionMode target) noexcept;
  const char* cmd_enable(bool enable) noexcept;
  const char* cmd_home(int joint) noexcept;
  const char* cmd_unhome(int joint) noexcept;
  const char* cmd_jog(const MotionCommand& c) noexcept;
  const char* cmd_jog_joint(const MotionCommand& c) noexcept;
  const char* cmd_jog_axis(const MotionCommand& c) noexcept;
  const char* cmd_segment(const MotionCommand& c, bool& retry) noexcept;
  void abort_all() noexcept;
  const char* cmd_estop_reset() noexcept;

  // cycle parts
  void read_feedback() noexcept;
  void resync_from_feedback() noexcept;
  void check_estop() noexcept;
  void latch_estop(ipc::EstopCause cause, int32_t pid) noexcept;
  void check_faults() noexcept;
  void apply_overrun_action() noexcept;
  void wait_for_amplifiers(double dt) noexcept;
  // Why a command that moves cannot run while an amplifier is not ready
  // yet (nullptr: all ready).
  const char* amps_not_ready(const char* what) noexcept;
  void run_free(double dt) noexcept;
  void run_teleop(double dt) noexcept;
  void run_coord(double dt) noexcept;
  // While the path waits for the spindles to be at speed: which one, and
  // the abort after its AT_SPEED_TIMEOUT.
  void watch_spindle_wait(double dt) noexcept;
  void run_homing(double dt) noexcept;
  void home_step(int j, double dt) noexcept;
  void start_home_sequence(int sequence) noexcept;
  void finish_joint_home(int j) noexcept;
  void abort_homing(int j, const char* why) noexcept;
  void latch_home(int j, double joint_pos_at_latch) noexcept;
  void update_jog_wheels() noexcept;
  void apply_inverse_kinematics() noexcept;
  void check_soft_limits() noexcept;
  void set_output(bool digital, int index, double value) noexcept;
  void compute_outputs(double dt) noexcept;
  void update_backlash(int j, double dt) noexcept;
  FreeLimits joint_limits(int j, double vel) const noexcept;
  // Nothing moves and nothing is queued: limits may change.
  bool at_rest() const noexcept;
  // After a change of the parameters in force (or of the kinematics, or
  // of the compensation attached): recomputes each axis's limits (its own
  // and those of every joint that moves it alone) and gives the planner
  // its new configuration, for the moves queued from now on.
  void apply_limits() noexcept;
  const char* cmd_set_parameter(const MotionCommand& c) noexcept;
  // Disables motion after a fault of a joint's or a spindle's amplifier
  // (-1: neither), says why on the error channel and keeps the reason for
  // the status.
  void fault(int joint, int spindle, const char* fmt, ...) noexcept __attribute__((format(printf, 4, 5)));
  const char* reason(const char* fmt, ...) noexcept __attribute__((format(printf, 2, 3)));
  // Distance to go of axis `a`: to the end of the executing move (coord),
  // to the jog target (teleop), 0 in free mode (joints move, not axes).
  double axis_dtg(int a) const noexcept;
  void begin_search(int j) noexcept;
  void enter_home_state(int j, HomeState state) noexcept;
  void stop_then(int j, HomeState state) noexcept;
  void on_latch_event(int j) noexcept;
  void start_final_move(int j) noexcept;
  void run_sync_groups(double dt) noexcept;
  void post_error(const char* fmt, ...) noexcept __attribute__((format(printf, 2, 3)));
  void post_text(const char* fmt, ...) noexcept __attribute__((format(printf, 2, 3)));
  bool joint_in_sync_group(int j) const noexcept;
  double search_span(int j) const noexcept;

  MotionConfig cfg_;
  const MotionConfig ini_cfg_;        // as loaded: the machine's limits
  std::array<FreeLimits, kNumAxes> axis_lim_{};
  kin::Kinematics& kins_;
  tp::TrajectoryPlanner& tp_;
  MessageQueue* messages_;
  std::array<JointCompensation*, kMaxJoints> comp_{};
  MotionInputs in_;
  MotionOutputs out_;
  std::array<Joint, kMaxJoints> joints_{};
  ipc::MotionMode mode_ = ipc::MotionMode::Free;
  bool enabled_ = false;
  bool faulted_ = false;
  bool resync_ = true;                // take the command from fresh feedback on the next cycle
  bool amps_ready_ = false;           // since the enable, every amplifier said ready
  double amps_wait_s_ = 0;            // how long the enable has waited for them
  int amp_waiting_joint_ = -1;
  // E-stop latched in the servo thread (docs/motion.md, "E-stop").
  bool estop_latched_ = false;
  ipc::EstopCause estop_cause_ = ipc::EstopCause::None;
  int32_t estop_pid_ = 0;
  uint64_t estop_seen_ = 0;           // the request word last acted on
  FixedString<200> fault_reason_;
  int fault_joint_ = -1, fault_spindle_ = -1;
  std::array<bool, kMaxSpindles> spindle_fault_{};
  bool servo_was_late_ = false;       // in_.servo_late of the previous cycle
  bool overrun_hold_ = false;         // paused by OVERRUN_ACTION = HOLD, until resume
  uint32_t overrun_holds_ = 0;
  bool override_limits_ = false;      // armed by OVERRIDE_LIMITS, consumed by the next jog
  double feed_scale_ = 1, rapid_scale_ = 1, max_velocity_ = 1e99;
  bool feed_override_enabled_ = true, adaptive_enabled_ = false, feed_hold_enabled_ = true;
  Pose carte_cmd_, carte_fb_, tool_offset_;
  bool carte_fb_valid_ = false;
  // teleop: one planner per axis in Cartesian space
  std::array<FreePlanner, kNumAxes> axis_free_{};
  // coord
  tp::CycleOutputs tp_out_{};
  bool probing_ = false, probe_tripped_ = false;
  Pose probed_pos_;
  // Touch-probe latches of the drives (joint.N.probe-count/-position): the
  // counts before the trip, the joints whose latch of this probing was
  // taken and their joint positions, the planner's pose at the trip.
  std::array<uint32_t, kMaxJoints> probe_count_before_{};
  uint32_t probe_latched_mask_ = 0;
  std::array<double, kMaxJoints> probe_latched_joint_{};
  Pose probe_tp_pos_;
  void take_probe_latches() noexcept;
  // After a trip, the probe result waits (status probe_latch_pending) for
  // the latch of every joint whose probe-count is wired, at most
  // kProbeLatchWait: a latch's PDO may come after the move has stopped.
  static constexpr double kProbeLatchWait = 0.1;  // s
  bool probe_latch_pending_ = false;
  int probe_latch_cycles_ = 0;
  void wait_for_probe_latches() noexcept;
  uint64_t probe_serial_ = 0;
  // homing sequence
  int home_sequence_ = -1;            // |sequence| being homed by "home all", -1 none
  bool home_all_ = false;
  int max_sequence_ = 0;
  std::array<FreePlanner, kMaxJoints> group_planner_{};  // synchronised final moves, per |sequence|
  std::array<double, kMaxJoints> group_start_{};
  // spindles
  struct Spindle {
    double speed = 0;
    bool on = false, brake = true;
    double override_scale = 1;
    bool orient = false;
    double orient_angle = 0;
    int32_t orient_mode = 0;
  };
  std::array<Spindle, kMaxSpindles> spindles_{};
  uint32_t last_queued_id_ = 0;       // id of the last segment given to the planner
  // At-speed (LinuxCNC's atspeed_next_feed): a spindle was started or its
  // speed changed, so the next feed move waits for spindle.N.at-speed.
  bool atspeed_next_feed_ = false;
  // Cycles in which a spindle's at-speed is not believed yet after its
  // command changed: the pin still answers the old command until whatever
  // drives it has seen the new one (e.g. a stopped VFD is "at speed").
  std::array<int, kMaxSpindles> at_speed_stale_{};
  int spindle_wait_ = -1;             // the spindle the path waits for (-1: none)
  double spindle_wait_s_ = 0;         // how long it has waited
  uint32_t spindle_timeouts_ = 0;
  FixedString<200> spindle_timeout_reason_;
  // M62-M65/M67: set when the first move queued after the command starts.
  struct PendingOutput {
    bool pending = false;
    uint32_t after_id = 0;
    double value = 0;
  };
  std::array<PendingOutput, kMaxDio> dout_pending_{};
  std::array<PendingOutput, kMaxDio> aout_pending_{};
  FixedString<200> reason_;
  uint64_t cycles_ = 0;
  uint64_t last_serial_ = 0;
  double dt_ = 0.001;
};

}  // namespace cnc::motion
