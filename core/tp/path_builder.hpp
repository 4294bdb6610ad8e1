// The planning work that is not per servo cycle: turns the moves the
// interpreter queues into segments, smoothing windows and limit-annotated
// pieces, and publishes them to the servo side (PathStore). Runs either
// inside add_line() on the servo thread or on a planner thread of its own;
// either way it never allocates after construction and never blocks.
//
// Stages: the G64 Q merge of nearly collinear moves, the vertex smoothing
// of bands of G64 P lines (smoothing.hpp), the corner windows (blend.hpp),
// the pieces. It holds back the newest moves until the windows that may
// reach into them are known (at most 5 x blend_span_segments moves, or up
// to the next exact stop; a straight run only blend_span_segments + 2), and
// plans to the end of the queue when flushed.
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "core/tp/path_records.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

// Most moves one chord of the G64 Q merge takes (fewer with a short queue).
constexpr int kMaxMergedMoves = 64;

// The velocity ceiling of a piece: the largest path velocity at which every
// axis keeps kCeilingReserve of its acceleration and jerk (and every axis
// and the [TRAJ] linear limits their velocity). Below it the servo side
// finds more; see executor.hpp.
double ceiling_of(const PieceBounds& b, const PlannerConfig& cfg) noexcept;

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
  // Work of the final window checks: (sample, window) terms evaluated, a
  // sample's deviation being the sum over the windows that may reach it.
  uint64_t check_terms() const noexcept { return check_terms_; }
  // Work of the tentative widths: corner terms summed by their bisection.
  uint64_t size_terms() const noexcept { return size_terms_; }

 private:
  struct Held;
  struct Merge;
  struct Fit;
  struct Near;
  enum class Junction : uint8_t { Unknown, Smooth, Window, Stop };

  Result append(const Curve& curve, const SegmentParams& params, uint32_t inputs, double merge_err) noexcept;
  Result append_point(const SegmentParams& params) noexcept;
  void flush_merge() noexcept;
  void push_line(const Pose& start, const Pose& end, const SegmentParams& params, uint32_t inputs,
                 double merge_err) noexcept;
  void fit_emit(int count) noexcept;
  void flush_fit() noexcept;
  bool try_merge(const Pose& end, const SegmentParams& params) noexcept;
  void finalize(bool flushing) noexcept;
  uint64_t horizon(uint64_t j, uint64_t n) const noexcept;
  void tentative_half(uint64_t j) noexcept;
  void final_half(uint64_t j) noexcept;
  double deviation_bound(double s, uint64_t lo, uint64_t hi, double* second) const noexcept;
  int dense_neighbours(uint64_t j, double d_max) const noexcept;
  bool dense_fits(int n, double d, double budget) noexcept;
  uint64_t segment_at(double s, uint64_t near, uint64_t from) const noexcept;
  bool emit_vertices_upto(uint64_t j) noexcept;
  bool emit_pieces(uint64_t m) noexcept;
  void compute_junction(uint64_t j) noexcept;
  bool window_slower_than_stop(uint64_t j, const AxisVec& dt, double ndt, double m2) const noexcept;
  Held& held(uint64_t seq) noexcept;
  const Held& held(uint64_t seq) const noexcept;
  double tolerance_of(uint64_t seq) const noexcept;

  PlannerConfig cfg_;
  PathStore& store_;
  std::unique_ptr<Held[]> held_;
  std::size_t held_mask_ = 0;
  std::unique_ptr<Near[]> near_;  // scratch, one per held segment
  std::unique_ptr<Merge> merge_;
  std::unique_ptr<Fit> fit_;
  Pose position_;
  uint64_t first_seq_ = 0;       // oldest segment still kept (history)
  uint64_t next_seq_ = 0;        // next segment number (== store_.segs.head())
  uint64_t first_unfinal_ = 0;   // first segment whose pieces are not yet out
  uint64_t next_tent_ = 0;       // first vertex without a tentative window
  uint64_t next_final_ = 0;      // first vertex whose window is not final
  uint64_t vertices_out_ = 0;    // vertex records published so far
  double s_end_ = 0;             // global path position of the end of the last segment
  uint32_t epoch_ = 0;
  uint64_t built_ = 0;
  uint64_t check_terms_ = 0;
  uint64_t size_terms_ = 0;
  int span_ = 8;
};

}  // namespace cnc::tp
