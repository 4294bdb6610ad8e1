// The planning work that is not per servo cycle: turns the moves the
// interpreter queues into segments, smoothing windows and limit-annotated
// pieces, and publishes them to the servo side (PathStore). Runs either
// inside add_line() on the servo thread or on a planner thread of its own;
// either way it never allocates after construction and never blocks.
//
// It holds back the newest moves until the windows that may reach into them
// are known (at most 5 x blend_span_segments moves, or up to the next exact
// stop), and plans to the end of the queue when flushed.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "core/tp/path_records.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

// Tangential path limits for one span of the path, from per-axis bounds of
// the first three derivatives of the smoothed curve (see
// docs/trajectory-planner.md, "limits of a piece").
struct PieceLimits {
  double velocity = 0;
  double accel = 0;
  double jerk = 0;
  bool barrier = false;
};
PieceLimits derive_limits(const AxisVec& c1, const AxisVec& c2, const AxisVec& c3, const PlannerConfig& cfg) noexcept;

// Lower bounds every non-barrier piece keeps (what a brake may always use).
struct LimitFloors {
  double accel = 0;
  double jerk = 0;
};
LimitFloors limit_floors(const PlannerConfig& cfg) noexcept;

class PathBuilder {
 public:
  PathBuilder(const PlannerConfig& config, PathStore& store);
  ~PathBuilder();

  void set_config(const PlannerConfig& config) noexcept;
  void set_position(const Pose& pose) noexcept;
  Result add_line(const Pose& end, const SegmentParams& params) noexcept;
  Result add_circle(const Pose& end, const std::array<double, 3>& center, const std::array<double, 3>& normal,
                    int turns, const SegmentParams& params) noexcept;
  Result add_dwell(double seconds, const SegmentParams& params) noexcept;
  // Plan to the end of what is queued: the last move ends with a stop.
  void flush() noexcept;
  // Drop everything (abort); later output carries `epoch`.
  void reset(uint32_t epoch) noexcept;

  // Room for one more move (false only if the servo side stopped consuming).
  bool can_accept() const noexcept;
  // Moves received but not yet handed to the servo side.
  bool has_held() const noexcept;
  const Pose& position() const noexcept { return position_; }
  uint64_t segments_built() const noexcept { return built_; }

 private:
  struct Held;
  struct Merge;
  enum class Junction : uint8_t { Unknown, Smooth, Window, Stop };

  Result append(const Curve& curve, const SegmentParams& params, uint32_t inputs) noexcept;
  Result append_point(const SegmentParams& params) noexcept;
  void flush_merge() noexcept;
  bool try_merge(const Pose& end, const SegmentParams& params) noexcept;
  void finalize(bool flushing) noexcept;
  bool ready(uint64_t m) const noexcept;
  double initial_half(uint64_t j) noexcept;
  void final_half(uint64_t j) noexcept;
  bool emit_vertices_upto(uint64_t j) noexcept;
  bool emit_pieces(uint64_t m) noexcept;
  void compute_junction(uint64_t j) noexcept;
  Held& held(uint64_t seq) noexcept;
  const Held& held(uint64_t seq) const noexcept;
  bool same_run(uint64_t a, uint64_t b) const noexcept;
  double tolerance_of(uint64_t seq) const noexcept;

  PlannerConfig cfg_;
  PathStore& store_;
  std::unique_ptr<Held[]> held_;
  std::size_t held_mask_ = 0;
  std::unique_ptr<Merge> merge_;
  Pose position_;
  uint64_t first_seq_ = 0;       // oldest segment still kept (history)
  uint64_t next_seq_ = 0;        // next segment number (== store_.segs.head())
  uint64_t first_unfinal_ = 0;   // first segment whose pieces are not yet out
  uint64_t vertices_out_ = 0;    // vertex records published so far
  double s_end_ = 0;             // global path position of the end of the last segment
  uint32_t epoch_ = 0;
  uint64_t built_ = 0;
  int span_ = 8;
};

}  // namespace cnc::tp
