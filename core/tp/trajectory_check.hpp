// Offline checks of a commanded position stream against the programmed path
// and the machine limits: what the tests assert and the benchmarks print.
// Per-axis velocity, acceleration and jerk from finite differences of the
// samples (the field's definition), distance of every sample from the
// programmed path, time at programmed feed. Not realtime (allocates).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "core/tp/curve.hpp"
#include "core/tp/path_records.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

// One queued command, as the motion controller would send it.
struct ProgramMove {
  enum class Kind : uint8_t { Line, Circle, Dwell };
  Kind kind = Kind::Line;
  Pose end;
  std::array<double, 3> center{};
  std::array<double, 3> normal{0, 0, 1};
  int turns = 0;
  double seconds = 0;  // dwell
  SegmentParams params;
};

struct Program {
  Pose start;
  std::vector<ProgramMove> moves;
};

// Queues move `i` (params.id is set to i). Returns the planner's result.
Result queue_move(TrajectoryPlanner& planner, const Program& program, std::size_t i);

struct StreamStats {
  double time_s = 0;                // until done
  AxisVec max_v{}, max_a{}, max_j{};  // absolute, per axis
  double ratio_v = 0, ratio_a = 0, ratio_j = 0;  // worst axis, relative to its limit
  double max_deviation = 0;         // distance of a sample from the programmed path (XYZ)
  double deviation_ratio = 0;       // relative to the tolerance in force (G64 P)
  double at_feed_fraction = 0;      // share of moving time within 1% of the programmed feed
  double mean_feed_ratio = 0;       // mean speed / programmed feed over moving time
  double end_error = 0;             // final position vs the program's end point
  uint64_t samples = 0;
};

class StreamChecker {
 public:
  // `search_span`: moves either side of the executing one searched for the
  // nearest point (at least the planner's blend span + 2).
  StreamChecker(const PlannerConfig& config, const Program& program, int search_span = 12);
  // One call per servo cycle, in order.
  void add(const CycleOutputs& out, double feed_scale = 1.0);
  StreamStats finish() const;
  // Distance from p (XYZ) to move i's programmed geometry.
  double distance_to_move(const Pose& p, std::size_t i) const;

 private:
  PlannerConfig cfg_;
  const Program& program_;
  std::vector<Curve> curves_;  // per move; length 0 for dwells
  std::vector<double> tol_;    // tolerance that applies around move i
  // Per move: a box (XYZ) that holds its whole curve, to skip curves that
  // cannot be nearer than one already found.
  std::vector<std::array<double, 6>> box_;
  int span_;
  Pose hist_[3];
  int nhist_ = 0;
  StreamStats st_;
  double moving_time_ = 0;
  double at_feed_time_ = 0;
  double feed_ratio_sum_ = 0;
};

// Runs a program to completion the way the motion controller would: every
// cycle it queues moves while the planner has room (at most
// moves_per_cycle), then runs one servo cycle; and checks the stream.
struct RunOptions {
  int moves_per_cycle = 1 << 30;
  uint64_t max_cycles = 50'000'000;
  bool measure_cpu = false;
  // Call flush() once every move is queued (the motion controller does at
  // the end of a program or at a queue buster).
  bool flush_at_end = false;
  // From this cycle on nothing is queued until the machine has come to rest
  // (the interpreter starving): with a planner that does not flush on its
  // own, the machine must stop within what was planned.
  uint64_t starve_from_cycle = UINT64_MAX;
  // Called before each cycle: overrides, pause, probe input, ...
  std::function<void(uint64_t cycle, TrajectoryPlanner&, CycleInputs&)> before_cycle;
  // Called after each cycle with what it produced (bench_tp --profile).
  std::function<void(uint64_t cycle, const CycleOutputs&)> after_cycle;
};

struct RunResult {
  StreamStats stats;
  bool completed = false;  // every move queued and the planner done
  uint64_t cycles = 0;
  // LookaheadPlanner only: the path position never decreased, and the margin
  // between the distance left to the end of the planned path and the
  // distance needed to stop (negative: could not have stopped in time).
  bool monotone = true;
  double stop_margin = std::numeric_limits<double>::infinity();
  // With starve_from_cycle: the machine came to rest while starved, and
  // where (path position) relative to the end of what was planned.
  bool starve_stopped = false;
  double starve_stop_gap = 0;
  uint64_t overruns = 0;
  // LookaheadPlanner only: pieces whose spans the servo thread split
  // itself because the hand-over ring was full (Executor::CycleWork::split).
  uint64_t servo_split = 0;
  std::vector<double> cycle_ns;  // with measure_cpu: run_cycle durations
  std::vector<double> add_ns;    // with measure_cpu: durations of accepted add_* calls
  CycleOutputs last;
};

RunResult run_program(TrajectoryPlanner& planner, const PlannerConfig& config, const Program& program,
                      const RunOptions& options = {});

}  // namespace cnc::tp
