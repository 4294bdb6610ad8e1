// The coordinated-mode trajectory planner as the motion controller sees it
// (the manual's SET_LINE / SET_CIRCLE / PROBE and PAUSE / RESUME / STEP /
// ABORT). The motion controller owns one planner and calls it from the servo
// thread only: every method here must be realtime-safe (no allocation, no
// lock shared with a non-realtime thread, no exception). An implementation
// may plan on a thread of its own, but the servo thread never waits for it.
#pragma once

#include <array>
#include <cstdint>

#include "core/util/pose.hpp"

namespace cnc::tp {

// How a segment ends (G61 exact path, G61.1 exact stop, G64 blending).
enum class TermCond : uint8_t { ExactStop, ExactPath, Blend };

enum class MotionType : uint8_t { Traverse, Feed, Arc, Probe, Dwell };

// Why the planner refused a segment or a command.
enum class Result : uint8_t {
  Ok,
  QueueFull,        // try again next cycle; nothing was added
  InvalidSegment,   // zero-length circle, non-finite numbers, bad normal...
  NotAllowed,       // e.g. a probe while another probe is queued
};
const char* to_string(Result r) noexcept;

struct AxisLimits {
  double max_velocity = 0;      // units/s
  double max_acceleration = 0;  // units/s^2
  double max_jerk = 0;          // units/s^3
};

struct PlannerConfig {
  double cycle_time_s = 0.001;
  int lookahead_segments = 1000;
  std::array<AxisLimits, kNumAxes> axes{};
  double max_linear_velocity = 0;      // [TRAJ]MAX_LINEAR_VELOCITY, units/s
  double max_linear_acceleration = 0;  // [TRAJ]MAX_LINEAR_ACCELERATION
  double max_linear_jerk = 0;          // [TRAJ]MAX_LINEAR_JERK
  uint32_t axis_mask = 0x7;            // bit i: axis i exists
  // Corner smoothing: a window reaches over at most this many moves on each
  // side of its corner and never more than max_blend_half_width units.
  int blend_span_segments = 8;
  double max_blend_half_width = 5.0;
  // Without new moves for this many cycles (and with room in the queue) the
  // planner plans to the end of what it has, ending with a stop.
  int flush_idle_cycles = 4;
};

// The modal state of the program line a move came from (LinuxCNC 2.9's
// state_tag_t): the task takes it from the interpreter when the line is
// executed (read ahead), it travels with the move through the queue, and
// the planner reports the executing move's tag, so that the status shows
// the codes, F and S of the line being cut, not of the read-ahead. Fixed
// size and plain: the servo thread only copies it.
struct StateTag {
  static constexpr int kGCodes = 17;
  static constexpr int kMCodes = 10;
  bool valid = false;          // false: no tag (jogs, homing, a move queued without one)
  int32_t line = 0;
  int16_t gcodes[kGCodes] = {};  // LinuxCNC's active_gcodes numbering (G1 = 10, G59.3 = 593), -1 unused
  int16_t mcodes[kMCodes] = {};  // -1 unused
  double feed = 0;             // F, program units per minute (as LinuxCNC's settings[1])
  double speed = 0;            // S of spindle 0, rpm as programmed
};

struct SegmentParams {
  MotionType type = MotionType::Feed;
  int32_t line = 0;            // program line it came from (status: motion_line)
  uint32_t id = 0;             // motion id (LinuxCNC's EMC_TRAJ_SET_MOTION_ID)
  double feed = 0;             // requested path velocity, units/s
  double max_velocity = 0;     // cap for this segment (ini maximum), units/s
  double max_acceleration = 0; // cap for this segment, units/s^2
  TermCond term = TermCond::Blend;
  double tolerance = 0;        // G64 P: largest allowed deviation at a blend (0: as fast as possible)
  double naive_cam_tolerance = 0;  // G64 Q: collinear-segment merge tolerance
  bool feed_override_allowed = true;  // M50/M51 off for this segment when false
  // On a dwell: the path stops there and holds, after the dwell time, until
  // CycleInputs::spindles_at_speed (LinuxCNC's wait for spindle.N.at-speed
  // before a feed move that follows a spindle start or speed change).
  bool wait_spindle_at_speed = false;
  StateTag tag;                // modal state of the source line (status only)
};

struct CycleInputs {
  double feed_scale = 1.0;   // feed override x adaptive feed; 0 stops along the path
  double rapid_scale = 1.0;  // rapid override, for Traverse segments
  double max_velocity = 1e300;  // max-velocity override, units/s
  bool probe_input = false;
  bool spindles_at_speed = true;  // every spindle's spindle.N.at-speed
};

struct CycleOutputs {
  Pose position;            // carte_pos_cmd
  double path_velocity = 0; // current speed along the path, units/s
  double path_acceleration = 0;  // along the path, units/s^2
  double distance_to_go = 0;     // to the end of the executing move
  Pose move_end;            // where the executing move ends (position when none): per-axis distance to go
  int32_t line = 0;         // line of the executing segment
  uint32_t id = 0;          // id of the executing segment
  StateTag tag;             // tag of the executing segment (of the last one once the queue ran empty)
  bool done = true;         // queue empty and at rest
  bool probe_tripped = false;
  Pose probed_position;     // valid when probe_tripped
  bool waiting_for_spindle = false;  // held at a wait_spindle_at_speed dwell for spindles_at_speed
};

class TrajectoryPlanner {
 public:
  virtual ~TrajectoryPlanner() = default;

  // Where the path starts: the current position when coord mode begins or
  // after an abort. Only while done().
  virtual void set_position(const Pose& pose) noexcept = 0;
  // Drops everything queued and stops at once at `pose`, ignoring the
  // limits: used only when motion is disabled (amplifiers off, the machine
  // is not following the command) or on an emergency stop.
  virtual void reset(const Pose& pose) noexcept = 0;

  virtual Result add_line(const Pose& end, const SegmentParams& params) noexcept = 0;
  // Arc or helix from the current end point to `end` around the axis
  // through `center` along unit `normal` (right-handed: counter-clockwise
  // seen from the normal's tip), with `turns` extra full turns.
  virtual Result add_circle(const Pose& end, const std::array<double, 3>& center,
                            const std::array<double, 3>& normal, int turns, const SegmentParams& params) noexcept = 0;
  // A pause in place (G4) that keeps its place in the queue.
  virtual Result add_dwell(double seconds, const SegmentParams& params) noexcept = 0;

  // One servo period: advance along the queued path.
  virtual void run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept = 0;

  // Decelerate along the path to a stop and hold; resume continues there.
  virtual void pause() noexcept = 0;
  virtual void resume() noexcept = 0;
  // While paused: run to the end of the current segment, then pause again.
  virtual void step() noexcept = 0;
  // Stop along the path within the limits, then drop everything queued.
  virtual void abort() noexcept = 0;

  virtual bool is_done() const noexcept = 0;
  virtual bool is_paused() const noexcept = 0;
  virtual int queue_depth() const noexcept = 0;
  virtual bool is_queue_full() const noexcept = 0;
  // Changes that apply to segments added from now on (SET_xxx commands).
  virtual void set_config(const PlannerConfig& config) noexcept = 0;
  // No more moves are coming for now (end of program, a queue buster): plan
  // to the end of the queue instead of waiting for the moves that would
  // shape its last corners. Optional: the planner also decides this itself
  // after config.flush_idle_cycles cycles without input.
  virtual void flush() noexcept {}
};

}  // namespace cnc::tp
