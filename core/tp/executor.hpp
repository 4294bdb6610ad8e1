// The servo-thread side of the planner: follows the published pieces with a
// jerk-limited motion along the path parameter, one servo period at a time.
//
// Each cycle it takes the motion that speeds up toward the current piece's
// ceiling unless that would leave a state from which some later ceiling
// (within the braking horizon) can no longer be met; then it switches, at
// the latest instant inside the cycle, to the shortest jerk-limited brake
// for the binding ceiling and follows it exactly. The end of what has been
// published is always a ceiling of zero, so the machine can always stop
// within the planned distance. Ceilings of "barrier" pieces (tight corners,
// passed at nearly constant speed) already include what lies beyond them
// (a backward pass, bounded work per cycle), so the look-ahead walk stops at
// the first barrier. Never allocates, never blocks, never throws.
#pragma once

#include <cstdint>
#include <memory>

#include "core/tp/jerk_profile.hpp"
#include "core/tp/limit_tree.hpp"
#include "core/tp/path_builder.hpp"
#include "core/tp/path_records.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

class Executor {
 public:
  Executor(const PlannerConfig& config, PathStore& store);

  void set_config(const PlannerConfig& config) noexcept;
  void set_position(const Pose& pose) noexcept;
  void run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept;

  void pause() noexcept;
  void resume() noexcept;
  void step() noexcept;
  void abort() noexcept;
  // Drop everything at once and stand still at `pose` (motion disabled).
  void reset(const Pose& pose) noexcept;
  void clear_probe() noexcept { probe_tripped_ = false; }

  bool is_paused() const noexcept { return hold_ && !aborting_; }
  // At rest with nothing published left to execute.
  bool is_idle() const noexcept;
  bool is_aborting() const noexcept { return aborting_; }
  uint64_t inputs_completed() const noexcept { return completed_; }
  // Set when an abort finished: everything queued was dropped; the owner
  // resets the builder to this epoch.
  bool take_abort_done(uint32_t& epoch) noexcept;

  // For the builder's flush policy and for tests.
  bool is_moving() const noexcept { return v_ > 0 || a_ != 0; }
  double path_position() const noexcept;
  double path_velocity() const noexcept { return v_; }
  double path_acceleration() const noexcept { return a_; }
  double distance_to_tail() const noexcept;
  double stop_distance(bool* crosses_barrier = nullptr) const noexcept;
  uint64_t overruns() const noexcept { return overruns_; }

  // Position on the smoothed path at global position s (tests: dense
  // evaluation of the path that is being executed). Only for s within the
  // ingested pieces; false otherwise.
  bool evaluate_at(double s, Pose& out) const noexcept;

 private:
  struct Constraint {
    double dist;   // from the current position to where the ceiling starts
    double value;  // ceiling
    double accel;  // tangential limits on the way there
    double jerk;
    uint64_t piece;
    double jerk_after;  // jerk available just past the point (an arrival
                        // still accelerating must level off with it)
    bool tight;         // the value assumes braking may have to go on right
                        // after the point: arrive no longer accelerating
  };
  struct Motion {
    JerkProfile first;
    double switch_t = 1e300;  // when `second` takes over
    JerkProfile second;
    PathState at(double t) const noexcept;
  };

  void ingest() noexcept;
  void backward_pass(int budget) noexcept;
  double barrier_ceiling(uint64_t b) const noexcept;
  int collect(double x, const LimitTree::Query& q, Constraint* out, int max, double& boundary) const noexcept;
  double approach_distance(const PathState& m, double moved, const Constraint& k) const noexcept;
  double brake_target(const PathState& m, const Constraint& k) const noexcept;
  bool brake_valid(const JerkProfile& p, double moved, int j, const Constraint* c, int n, double tol) const noexcept;
  int find_brake(const PathState& m, double moved, const Constraint* c, int n, int prefer, double tol,
                 JerkProfile& out) const noexcept;
  JerkProfile choose_brake(const PathState& sw, const Constraint* c, int n, int binding, double& target_dist,
                           double& target_value) const noexcept;
  bool feasible(const PathState& m, double moved, const Constraint* c, int n, int* worst, double tol) const noexcept;
  bool motion_ok(const Motion& mo, const Constraint* c, int n, double T, double tol) const noexcept;
  void plan_cycle(const CycleInputs& in) noexcept;
  double plan_step(const CycleInputs& in, double dt, bool split) noexcept;
  void advance(const PathState& end) noexcept;
  void handle_rest() noexcept;
  void finish_abort() noexcept;
  void limits_between(uint64_t from, uint64_t to, double& accel, double& jerk) const noexcept;
  uint64_t piece_at(double s) const noexcept;
  void eval(uint64_t piece, double offset, Pose& p, double* speed) const noexcept;
  double current_ceiling(const LimitTree::Query& q) const noexcept;
  const Piece& piece(uint64_t seq) const noexcept { return store_.pieces.at(seq); }
  std::size_t slot(uint64_t seq) const noexcept { return seq & (tree_.size() - 1); }

  PlannerConfig cfg_;
  LimitFloors floors_;
  PathStore& store_;
  LimitTree tree_;

  uint64_t cur_ = 0;    // executing piece
  uint64_t tail_ = 0;   // one past the last ingested piece
  double off_ = 0;      // position inside the executing piece
  double v_ = 0;
  double a_ = 0;
  double tail_s_ = 0;   // global end of the ingested path
  uint32_t epoch_ = 0;

  bool active_ = false;  // following a brake profile
  JerkProfile brake_;
  double brake_t_ = 0;
  double brake_target_s_ = 0;  // where the ceiling it brakes for starts
  double brake_target_v_ = 0;  // and its value
  double jerk_now_ = 0;        // jerk available over this step

  bool hold_ = false;
  bool step_active_ = false;
  double step_s_ = 0;
  bool aborting_ = false;
  bool abort_done_ = false;
  bool probe_tripped_ = false;
  Pose probed_;
  bool dwelling_ = false;
  double dwell_left_ = 0;

  bool bp_dirty_ = false;
  int64_t bp_cursor_ = -1;
  uint64_t completed_ = 0;
  uint64_t overruns_ = 0;
  Pose pose_;
  double speed_ = 0;
  LimitTree::Query last_query_;
};

}  // namespace cnc::tp
