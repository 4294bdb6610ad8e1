// The servo-thread side of the planner: moves along the published pieces
// one servo period at a time.
//
// Two stages on the path parameter s:
//  - an *input* motion x_k with bounded acceleration (no jerk limit), chosen
//    each cycle greedily toward the velocity ceilings and kept safe by a
//    backward braking envelope (the machine can always stop inside what has
//    been planned);
//  - the *output* y_k = mean of the last N input positions, N T = T_f >=
//    A / J: the moving average turns every acceleration step of the input
//    into a ramp of jerk a / T_f, so the output is jerk-limited by
//    construction (an S-curve is exactly an averaged trapezoid).
// The output is what the machine follows. Its velocity, acceleration and
// jerk on every axis follow from bounds the input keeps: each input
// sample's acceleration is limited by what the path allows wherever the
// outputs it influences can be (within half the distance the window spans),
// and the velocity ceilings are spread ("eroded") over the same distance.
// The pieces are split into *spans* with constant input limits for that
// (exact at the erosion boundaries); the planner's own side splits them
// (prepare_published) and the servo thread takes the spans in.
//
// Never allocates after construction, never blocks, never throws.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

#include "core/tp/path_records.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

class Executor {
 public:
  // `split_ring_spans`: room of the ring through which the planner's side
  // hands the pieces' spans over (rounded up to a power of two, at least
  // two pieces' worth); 0: two spans per piece slot of `store`, which the
  // benchmark programs never fill. A full ring makes the planner's side
  // wait and run_cycle split the pieces it needs itself (CycleWork::split;
  // tests make the ring small to run that).
  Executor(const PlannerConfig& config, PathStore& store, std::size_t split_ring_spans = 0);
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  // `config_gen` numbers the configurations the owner hands out (the same
  // number to set_prepare_config for the same configuration).
  void set_config(const PlannerConfig& config, uint64_t config_gen) noexcept;
  void set_position(const Pose& pose) noexcept;
  void run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept;

  void pause() noexcept;
  void resume() noexcept;
  void step() noexcept;
  void abort() noexcept;
  // Drop everything at once and stand still at `pose` (motion disabled).
  void reset(const Pose& pose) noexcept;
  void clear_probe() noexcept { probe_tripped_ = false; }

  bool is_paused() const noexcept { return hold_ && !aborting_ && at_rest(); }
  // At rest with nothing published left to execute.
  bool is_idle() const noexcept;
  bool is_aborting() const noexcept { return aborting_; }
  uint64_t inputs_completed() const noexcept { return completed_; }
  // Set when an abort finished: everything queued was dropped; the owner
  // resets the builder to this epoch.
  bool take_abort_done(uint32_t& epoch) noexcept;

  // For the builder's flush policy and for tests.
  bool is_moving() const noexcept { return !at_rest(); }
  double path_position() const noexcept { return y_; }
  double path_velocity() const noexcept { return w_; }
  double path_acceleration() const noexcept { return b_; }
  // From the output position to the end of what may be executed.
  double distance_to_tail() const noexcept;
  // How far the output moves until it rests if the input brakes from now
  // on (the output comes to rest where the input does).
  double stop_distance() const noexcept;
  // Cycles in which no safe choice was left (never expected).
  uint64_t overruns() const noexcept { return overruns_; }
  int filter_length() const noexcept { return n_; }

  // The servo-thread work of the last run_cycle() in its unbounded parts
  // (tests): pieces taken in, pieces whose spans were taken in (`split`
  // of them split by the servo thread itself, `taken` from the planner's
  // side) and envelope spans computed. Each is at most its per-cycle bound below whatever the
  // program, except the envelope of a merged span grown in place (one per
  // split piece at most). `queries`: range minima over the pieces (the
  // unit of the envelope's and the input limits' cost), `envelope_queries`
  // the walk's share: at most kQueriesUrgent plus one span's
  // (kSpanQueriesMax).
  struct CycleWork {
    int ingested = 0, split = 0, enveloped = 0, queries = 0, envelope_queries = 0;
    // Of `queries`, those that searched the pieces and asked the segment
    // tree: an envelope span's range minima that resolve to the same
    // pieces as one of the last two it asked of the same channel take
    // that answer (executor.cpp, RangeMemo); `queries` counts them all
    // and stays the walk's budget unit, so the walk's pace is unchanged.
    int searches = 0, envelope_searches = 0;
    // Pieces whose limit table the servo thread computed itself (only
    // after a change of limits while moving; prepare_published() does it).
    int limits = 0;
    int walks = 0;  // walks from the tail requested (new spans)
    // Pieces whose spans the planner's side had split (copied); `split`
    // counts those the servo thread split itself (only after a change of
    // limits while moving, or when the hand-over ring was full).
    int taken = 0;
    // Brake simulations of the input's step (safe(): one when the step it
    // wants is safe, up to 18 when it searches for the largest safe one).
    int brakes = 0;
  };
  const CycleWork& cycle_work() const noexcept { return work_; }
  static constexpr int kIngestPerCycle = 128;
  static constexpr int kSplitPerCycle = 64;
  // Envelope spans per cycle (6 away from the input before: a walk of
  // cheap spans then crawled, and the spans new meanwhile piled up at the
  // tail for the next one).
  static constexpr int kEnvelopePerCycle = 24;
  // Range minima per cycle after which the envelope's walk waits for the
  // next cycle (one span is always walked); kQueriesUrgent on spans the
  // input may need soon (executor.cpp, finalize).
  static constexpr int kQueriesPerCycle = 1000;
  static constexpr int kQueriesUrgent = 2400;
  // Most range minima one envelope span may take: 4 chunks, each at most
  // 14 velocity limits of at most 10 queries (executor.cpp).
  static constexpr int kSpanQueriesMax = 4 * 14 * 10;
  // New spans wait for the envelope's walk while the tail lies more than
  // kDeferNear "near" distances (about twice a stop from top speed) ahead
  // of the input, until kDeferBatch of them of path or kDeferIdle cycles
  // without new spans (executor.cpp, finalize).
  static constexpr double kDeferNear = 2.0;
  static constexpr double kDeferBatch = 0.25;
  static constexpr int kDeferIdle = 8;
  // At a start (the input on spans never walked), the first walk begins
  // at most kStartWalkSpans spans and kStartWalkNear of a stop from top
  // speed (v_bound_^2 / a_top_) ahead of the input, then one from the tail
  // (executor.cpp, envelope_request).
  static constexpr int kStartWalkSpans = 24;
  static constexpr double kStartWalkNear = 0.05;
  // The walk's urgent slice waits until the input's step has not searched
  // (braked against the envelope, CycleWork::brakes) for this many cycles.
  static constexpr int kSearchQuiet = 8;

  // Producer side: runs where the builder runs (the planner's own thread,
  // or inline after add_* and flush), never in the servo thread. Computes
  // the limit table of every newly published piece (its acceleration
  // limit at each grid velocity, its rounded ceiling) and splits every
  // piece into spans once the pieces that may spread data onto it are
  // published, and hands both over through counters (release / acquire):
  // run_cycle takes in only pieces whose table is ready, and copies it and
  // the spans. What was made for another configuration than the servo side
  // runs with (limits changed while moving) is made again in run_cycle
  // (CycleWork::limits, CycleWork::split).
  void set_prepare_config(const PlannerConfig& config, uint64_t config_gen) noexcept;
  void prepare_published() noexcept;

  // Position on the smoothed path at global position s (tests: dense
  // evaluation of the path that is being executed). Only for s within the
  // ingested pieces; false otherwise.
  bool evaluate_at(double s, Pose& out) const noexcept;

 private:
  struct PieceData;
  struct Span;
  struct SplitSpan;
  struct PieceSplit;
  struct Rows;
  struct Limits;
  struct PieceLimits;
  struct Tree;
  struct RangeStretch;
  struct RangeMemo;

  void configure(const PlannerConfig& config) noexcept;
  void clear_history(double x) noexcept;
  void ingest() noexcept;
  void finalize() noexcept;
  void make_spans(uint64_t p) noexcept;
  void append_spans(uint64_t p, const SplitSpan* sub, int ns) noexcept;
  int split_piece(uint64_t p, const PieceData* pd, bool scan, uint64_t first_kept, uint64_t tail, uint32_t epoch,
                  double spread, double reach, SplitSpan* out) const noexcept;
  void split_published(uint64_t pub) noexcept;
  void envelope_request(bool full) noexcept;
  void envelope_work(double near, double reach) noexcept;
  bool idle_ingested() const noexcept;
  void envelope_span(uint64_t k, double w_end) noexcept;
  double accel_limit(uint64_t piece, double lo, double hi, double u) const noexcept;
  double accel_limit(RangeMemo& memo, double lo, double hi, double u) const noexcept;
  double range_min(uint64_t from, double lo, double hi, int channel) const noexcept;
  double range_min(RangeMemo& memo, double lo, double hi, int channel) const noexcept;
  double resolved_min(uint64_t from, double lo, double hi, int channel, RangeStretch& e) const noexcept;
  int grid_index(double v) const noexcept;
  double ceiling(const Span& sp) const noexcept;
  double envelope_at(uint64_t k, double x) const noexcept;
  double brake_curve(double w_end, double alpha, double d) const noexcept;
  double chunk_alpha(uint64_t span, double x) const noexcept;
  double brake_alpha(uint64_t& k, double x0, double x1) const noexcept;
  double min_envelope(double z0, double z1, uint64_t& k) const noexcept;
  bool above(double v, double w, bool loose) const noexcept;
  bool safe(double v_new, double a_new, bool loose = false) const noexcept;
  void plan_input(const CycleInputs& in) noexcept;
  void push_sample(double x, double v, double a, double commit, double alpha) noexcept;
  void prefix_max_alpha() const noexcept;
  void update_output() noexcept;
  void handle_stops() noexcept;
  void advance_output() noexcept;
  void release() noexcept;
  void finish_abort() noexcept;
  void eval(uint64_t piece, double offset, Pose& p, double* speed) const noexcept;
  bool at_rest() const noexcept;
  double final_end() const noexcept;
  int ring(int ago) const noexcept;
  const Piece& piece(uint64_t seq) const noexcept { return store_.pieces.at(seq); }
  const Curve* bare_helix(const Piece& p) const noexcept;
  PieceData& pdata(uint64_t seq) noexcept;
  const PieceData& pdata(uint64_t seq) const noexcept;
  Span& span(uint64_t seq) noexcept;
  const Span& span(uint64_t seq) const noexcept;

  PlannerConfig cfg_;  // the configuration given last (applied, or pending while moving)
  bool config_pending_ = false;
  uint64_t pending_gen_ = 0;
  void apply_pending_config() noexcept;
  PathStore& store_;
  std::unique_ptr<PieceData[]> pdata_;
  std::size_t pmask_ = 0;
  std::unique_ptr<Span[]> spans_;
  std::size_t smask_ = 0;
  std::unique_ptr<Limits> lim_;        // what the servo side runs with
  std::unique_ptr<Limits> prep_lim_;   // producer side's
  std::unique_ptr<PieceLimits[]> plim_;  // per piece slot, like pdata_
  uint64_t prep_next_ = 0;             // producer only: next piece to prepare
  alignas(64) std::atomic<uint64_t> prepared_{0};  // pieces [.., prepared_) have tables
  // Spans split on the producer side: per piece slot where its spans lie
  // in the ring of split spans; producer-only copies of the pieces'
  // compact data and of where the published path ends.
  std::unique_ptr<PieceData[]> prep_pdata_;
  std::unique_ptr<PieceSplit[]> psplit_;
  std::unique_ptr<SplitSpan[]> split_ring_;
  std::size_t rmask_ = 0;
  uint64_t prep_split_next_ = 0;  // producer only: next piece to split
  uint64_t prep_rec_head_ = 0;    // producer only: next slot of split_ring_
  double prep_tail_s_ = 0;        // producer only: end of the published pieces
  uint64_t prep_last_stop_ = UINT64_MAX;  // producer only: newest stop published
  // Pieces [.., split_ready_) are split (stored before prepared_); the
  // servo side has taken in the spans of pieces [.., spans_taken_) and no
  // longer reads their split spans.
  alignas(64) std::atomic<uint64_t> split_ready_{0};
  alignas(64) std::atomic<uint64_t> spans_taken_{0};
  std::unique_ptr<Tree> tree_;
  std::unique_ptr<uint64_t[]> stops_;  // ring of stop pieces, in order
  uint64_t stop_head_ = 0, stop_tail_ = 0;
  std::array<double, 16> grid_{};      // velocities of the tabulated limits

  double T_ = 0.001;    // servo period
  double tf_ = 0.02;    // averaging time T_f = N T
  int n_ = 20;          // samples averaged
  double v_bound_ = 0;  // largest path velocity any piece may have
  double a_top_ = 0;    // largest input acceleration
  double reach_ = 0;    // farthest a piece's data spreads
  double env_tol_ = 0;  // slack on the envelope (squared velocity)

  // Pieces: [out_, ptail_) ingested, [pfin_, ptail_) not yet split.
  uint64_t out_ = 0;    // piece holding the output position
  uint64_t pfin_ = 0;
  uint64_t ptail_ = 0;
  double tail_s_ = 0;   // end of the ingested path
  uint64_t last_stop_ = UINT64_MAX;  // newest stop piece ingested
  // Spans: [in_, stail_), the input is in span in_.
  uint64_t sfirst_ = 0;  // oldest span kept
  uint64_t in_ = 0;
  uint64_t stail_ = 0;
  uint32_t epoch_ = 0;
  // The envelope's backward walk under way: next span, and below which
  // it may stop where nothing changes.
  bool spans_added_ = false;       // make_spans added spans this cycle
  bool env_active_ = false;
  bool env_pending_ = false;       // another walk from the tail is due
  bool env_pending_full_ = false;  // and it must reach the input
  bool env_deferred_ = false;      // spans added that no walk was requested for yet
  int env_idle_ = 0;               // cycles since spans were last added, while deferred
  double env_walk_s_ = 0;          // end of the spans when the last walk was requested
  uint64_t env_k_ = 0;
  uint64_t env_floor_ = 0;
  bool merge_ok_ = false;  // the newest span is a whole short piece
  bool recovering_ = false;  // an override dropped; braking to meet it
  int since_search_ = kSearchQuiet + 1;  // steps since the input's step last searched

  // Input state and the last samples (ring, newest at hist_pos_).
  double x_ = 0, v_ = 0;
  std::unique_ptr<double[]> hx_, hv_, ha_, hcommit_, halpha_;
  std::unique_ptr<double[]> hmax_;  // prefix maxima of halpha_ (scratch)
  int hist_pos_ = 0;
  // Output.
  double y_ = 0, w_ = 0, b_ = 0;
  Pose pose_;
  double speed_ = 0;

  // Overrides the envelope was computed for.
  double env_feed_ = 1, env_rapid_ = 1;

  bool hold_ = false;
  bool step_active_ = false;
  double step_s_ = 0;
  bool aborting_ = false;
  bool abort_done_ = false;
  bool probe_tripped_ = false;
  Pose probed_;
  bool dwelling_ = false;
  double dwell_left_ = 0;
  bool spindles_at_speed_ = true;   // CycleInputs::spindles_at_speed of this cycle
  bool waiting_spindle_ = false;    // held at a spindle_wait stop this cycle
  uint64_t completed_ = 0;
  uint64_t overruns_ = 0;
  uint64_t cycles_ = 0;
  mutable CycleWork work_;  // counters only (range_min is const)
  // Where range_min's previous searches ended (start points of the next).
  mutable uint64_t hint_lo_ = 0, hint_hi_ = 0;
};

}  // namespace cnc::tp
