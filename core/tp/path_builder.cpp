#include "core/tp/path_builder.hpp"

#include "core/tp/smoothing.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace cnc::tp {
namespace {

// Moves one merged chord may take: the builder holds back up to about
// 5 x span chords, and what it holds counts against the queue, so chords
// of kMaxMergedMoves moves would fill a short queue with moves nobody may
// execute yet (the queue full, nothing published: a dead stop). A quarter
// of the queue over the worst hold-back: on a straight run (held back
// span + 2 chords, the merge's open chord and the vertex smoothing's
// three) 0.01 mm moves at the default 1000 moves of look-ahead keep about
// 8.5 mm of path published (chords of 12 moves held 1.5 mm more back and
// capped the speed at 89-93 % of F6000).
int merge_cap(const PlannerConfig& c, int span) noexcept {
  return std::clamp(c.lookahead_segments / (4 * (5 * span + 1)), 1, kMaxMergedMoves - 1);
}

constexpr double kTangentEps = 1e-9;
// Windows are first sized for this share of the tolerance (the rest is room
// for the neighbours' windows that reach the same points), then verified.
constexpr double kTolShare = 0.9;
// A corner whose widest window is slower than this share of A T_f is a
// stop (window_slower_than_stop).
constexpr double kStopBelowShare = 0.33;
// Largest rate at which the half widths of neighbouring windows may change
// along the path: slowly varying windows give slowly varying curvature.
constexpr double kWidthSlope = 0.5;
// Naive-CAM merging (G64 Q) uses at most this share of G64 P: the rest is
// for the corner smoothing (the total stays within P). Small: the merge
// only joins nearly collinear moves; a chord that cuts across a curve
// leaves sharper corners and less tolerance for the windows (circle as
// 0.05 mm lines: 2.38 s with half of P, 1.84 s with 5 %; the vertex
// smoothing stage and the windows follow such a band better).
constexpr double kMergeShare = 0.05;
// Pieces a move may become (see emit_pieces).
constexpr std::size_t kMaxPiecesPerMove = 40;

double norm(const AxisVec& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s);
}

// Positive root of c1 d + c2 d^2 = budget.
double solve_half(double c1, double c2, double budget) {
  if (!(budget < kInf)) return kInf;
  if (c2 > 1e-300) return (-c1 + std::sqrt(c1 * c1 + 4 * c2 * budget)) / (2 * c2);
  if (c1 > 1e-300) return budget / c1;
  return kInf;
}

// Samples of a piece between lines (no window curved): at x_i = a + i step
// (i = 0..n) the line's direction plus the kink derivatives of the windows
// `win` (the corners win_seq, `m` the piece's move); the maxima of their
// absolute values on the axes `axes` go into m1..m3 and that of the squared
// speed in the curve's group into speed2. Window by window, two samples at
// a time (add_kink_derivative_rows): each sample's sums add the same terms
// in the same order as sample by sample, so the maxima are the same.
template <class HeldT>
void sample_kinks(const Curve& curve, double s0, double a, double step, int n, const HeldT* const* win,
                  const uint64_t* win_seq, int nwin, uint64_t m, const uint8_t* axes, int n_axes, AxisVec& m1,
                  AxisVec& m2, AxisVec& m3, double& speed2) noexcept {
  constexpr int kRow = 50;  // n <= 48: n + 1 samples, padded to an even count
  const int count = (n + 2) & ~1;
  double xg[kRow];
  for (int i = 0; i < count; ++i) xg[i] = s0 + (a + step * i);
  double rows[3][kNumAxes][kRow];
  double* r1[kNumAxes];
  double* r2[kNumAxes];
  double* r3[kNumAxes];
  for (int j = 0; j < n_axes; ++j) {
    const std::size_t k = axes[j];
    r1[k] = rows[0][j];
    r2[k] = rows[1][j];
    r3[k] = rows[2][j];
    std::fill(r1[k], r1[k] + count, curve.rate[k]);
    std::fill(r2[k], r2[k] + count, 0.0);
    std::fill(r3[k], r3[k] + count, 0.0);
  }
  for (int w = 0; w < nwin; ++w) add_kink_derivative_rows(win[w]->vx, m > win_seq[w], xg, count, r1, r2, r3);
  for (int j = 0; j < n_axes; ++j) {
    const std::size_t k = axes[j];
    for (int i = 0; i <= n; ++i) {
      m1[k] = std::max(m1[k], std::fabs(r1[k][i]));
      m2[k] = std::max(m2[k], std::fabs(r2[k][i]));
      m3[k] = std::max(m3[k], std::fabs(r3[k][i]));
    }
  }
  // The group's axes that are not sampled keep the line's (zero) rate.
  const auto o = static_cast<std::size_t>(curve.group) * 3;
  const double* g[3];
  double idle[3][kRow];
  for (std::size_t c = 0; c < 3; ++c) {
    bool sampled = false;
    for (int j = 0; j < n_axes; ++j) sampled = sampled || axes[j] == o + c;
    if (sampled) {
      g[c] = r1[o + c];
    } else {
      std::fill(idle[c], idle[c] + n + 1, curve.rate[o + c]);
      g[c] = idle[c];
    }
  }
  for (int i = 0; i <= n; ++i) {
    speed2 = std::max(speed2, g[0][i] * g[0][i] + g[1][i] * g[1][i] + g[2][i] * g[2][i]);
  }
}

}  // namespace

// The smallest of the rows' velocity, square-root and cube-root terms. The
// roots are taken only of the arguments that may give the smallest one
// (issue 20: a cube root a row was a tenth of the builder's time on arcs):
// the square root is correctly rounded, so the root of the smallest
// argument is the smallest root; the cube root is within an ulp, so only
// arguments within 1e-9 of the smallest may give the smallest root, and
// those are all taken. The value is the same as taking every root.
double ceiling_of(const PieceBounds& b, const PlannerConfig& cfg) noexcept {
  constexpr int kRows = kNumAxes + 1;
  double v = kInf;
  double q2 = kInf;  // smallest square-root argument
  double q3[kRows];  // cube-root arguments
  int n3 = 0;
  double q3_min = kInf;
  auto row = [&](double c1, double c2, double c3, double vmax, double amax, double jmax) {
    const double keep = 1 - kCeilingReserve;
    if (c1 > 1e-12) v = std::min(v, vmax * kLimitMargin / c1);
    if (c2 > 1e-300) q2 = std::min(q2, keep * amax * kLimitMargin / c2);
    if (c3 > 1e-300) {
      q3[n3] = keep * jmax * kLimitMargin / c3;
      q3_min = std::min(q3_min, q3[n3++]);
    }
  };
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(cfg.axis_mask & (1u << i))) continue;
    const auto k = static_cast<std::size_t>(i);
    const AxisLimits& l = cfg.axes[k];
    row(b.c1[k], b.c2[k], b.c3[k], l.max_velocity, l.max_acceleration, l.max_jerk);
  }
  row(b.lin1, b.lin2, b.lin3, cfg.max_linear_velocity > 0 ? cfg.max_linear_velocity : kInf,
      cfg.max_linear_acceleration > 0 ? cfg.max_linear_acceleration : kInf,
      cfg.max_linear_jerk > 0 ? cfg.max_linear_jerk : kInf);
  if (q2 < kInf) v = std::min(v, std::sqrt(q2));
  const double near3 = q3_min * (1 + 1e-9);
  for (int i = 0; i < n3; ++i) {
    if (q3[i] <= near3) v = std::min(v, std::cbrt(q3[i]));
  }
  return std::isfinite(v) ? v : 1e12;
}

// The fields the corner loops scan (junction, widths, the corner's size
// and position) come first, in the first cache line of the record: those
// loops walk up to 4 span records per corner, and the records are large
// (the curve and the parameters follow).
struct alignas(64) PathBuilder::Held {
  Junction junction = Junction::Unknown;
  bool final = false;       // vx.half is final
  double tent = -1;         // tentative half width: an upper bound of the final one
  double dt_norm = 0;       // |tangent jump| at the corner
  double m2 = 0;            // curved neighbours: bound of their second derivatives
  double merge_err = 0;     // distance of the merged-away points from this chord
  Vertex vx;                // with Junction::Window
  SegmentRecord rec;
  SegmentParams params;
  uint32_t inputs = 1;
  double dwell = 0;         // with Junction::Stop: dwell at the stop
  uint32_t dwell_inputs = 0;
  bool spindle_wait = false;  // with Junction::Stop: also wait there for the spindles to be at speed
};

// A corner near the one being sized or checked: its position (or offset),
// half width, |tangent jump| and curvature bound (scratch of tentative_half
// and final_half, so their inner loops skip the corners out of reach).
struct PathBuilder::Near {
  double s, d, dt_norm, m2;
};

// The vertex smoothing stage (smoothing.hpp): the newest lines of a band,
// held until the vertices around them are known.
struct PathBuilder::Fit {
  struct Item {
    Pose end;  // programmed end (the merged chord's, with G64 Q)
    SegmentParams params;
    uint32_t inputs = 0;
    double err = 0;  // the merge's error of this chord
  };
  static constexpr int kItems = 3;
  Item items[kItems];
  int count = 0;
  Pose start;      // where the first held line starts (its vertex already placed)
  Pose raw_start;  // programmed start of the first held line
  Pose before;     // programmed point before raw_start (valid if has_before)
  bool has_before = false;
  uint32_t carry = 0;  // inputs of a line that smoothing left without length
};

struct PathBuilder::Merge {
  bool active = false;
  Pose start;
  Pose end;
  SegmentParams params;
  Pose points[kMaxMergedMoves];
  int count = 0;
  uint32_t inputs = 0;
  double err = 0;  // largest distance of the points from the chord start-end
};

PathBuilder::PathBuilder(const PlannerConfig& config, PathStore& store)
    : cfg_(config), store_(store), merge_(std::make_unique<Merge>()), fit_(std::make_unique<Fit>()) {
  span_ = std::clamp(cfg_.blend_span_segments, 1, 32);
  std::size_t c = 2;
  while (c < static_cast<std::size_t>(8 * span_ + 64)) c *= 2;
  held_ = std::make_unique<Held[]>(c);
  held_mask_ = c - 1;
  near_ = std::make_unique<Near[]>(c);
}

PathBuilder::~PathBuilder() = default;

// Inline: called a few hundred times per move from the inner loops.
inline PathBuilder::Held& PathBuilder::held(uint64_t seq) noexcept { return held_[seq & held_mask_]; }
inline const PathBuilder::Held& PathBuilder::held(uint64_t seq) const noexcept { return held_[seq & held_mask_]; }

// What the smoothing may use on segment `seq`: its G64 P less the error of
// its naive-CAM chord (infinite for G64 without P).
inline double PathBuilder::tolerance_of(uint64_t seq) const noexcept {
  const Held& h = held(seq);
  const double t = h.params.tolerance;
  if (!(t > 0)) return kInf;
  return std::max(0.0, t - h.merge_err);
}

void PathBuilder::set_config(const PlannerConfig& config) noexcept {
  const int span = span_;
  cfg_ = config;
  span_ = span;  // the holdback geometry is fixed at construction
}

void PathBuilder::set_position(const Pose& pose) noexcept {
  flush();
  position_ = pose;
}

bool PathBuilder::can_accept() const noexcept {
  return next_seq_ - first_seq_ + 4 + Fit::kItems < held_mask_ + 1 && store_.segs.has_room(2 + Fit::kItems);
}

bool PathBuilder::has_held() const noexcept {
  return merge_->active || fit_->count > 0 || first_unfinal_ < next_seq_;
}

void PathBuilder::reset(uint32_t epoch) noexcept {
  merge_->active = false;
  fit_->count = 0;
  fit_->carry = 0;
  epoch_ = epoch;
  first_seq_ = first_unfinal_ = next_seq_ = next_tent_ = next_final_ = store_.segs.head();
  // The vertex ring stays aligned with the segment ring.
  while (vertices_out_ < next_seq_) {
    Vertex& v = store_.verts.push_slot();
    v = Vertex{};
    v.epoch = epoch_ - 1;
    ++vertices_out_;
  }
  store_.verts.publish();
}

Result PathBuilder::add_line(const Pose& end, const SegmentParams& params) noexcept {
  if (params.type == MotionType::Arc || params.type == MotionType::Dwell) return Result::InvalidSegment;
  if (params.type != MotionType::Traverse && !(params.feed > 0)) return Result::InvalidSegment;
  Curve probe_curve;
  const bool moves = make_line(position_, end, cfg_.max_blend_half_width, probe_curve);
  for (double x : end.v) {
    if (!std::isfinite(x)) return Result::InvalidSegment;
  }
  if (!moves) return Result::Ok;  // nothing moves: nothing to do (LinuxCNC drops it too)
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(cfg_.axis_mask & (1u << i)) && probe_curve.rate[static_cast<std::size_t>(i)] != 0) {
      return Result::InvalidSegment;
    }
  }
  if (!can_accept()) return Result::QueueFull;
  if (try_merge(end, params)) return Result::Ok;
  flush_merge();
  if (params.type == MotionType::Feed && params.term == TermCond::Blend && params.naive_cam_tolerance > 0) {
    Merge& m = *merge_;
    m.active = true;
    m.start = position_;
    m.end = end;
    m.params = params;
    m.count = 0;
    m.inputs = 1;
    m.err = 0;
    position_ = end;
    return Result::Ok;
  }
  push_line(position_, end, params, 1, 0);
  position_ = end;
  return Result::Ok;
}

// G64 Q (LinuxCNC's naive-CAM detector): collinear-enough feed moves become
// one chord while every merged end point stays within the tolerance of it.
// The chord's error is charged to the corner smoothing's budget, so that the
// path as a whole stays within G64 P.
bool PathBuilder::try_merge(const Pose& end, const SegmentParams& p) noexcept {
  Merge& m = *merge_;
  if (!m.active || m.count >= merge_cap(cfg_, span_)) return false;
  const SegmentParams& q = m.params;
  if (p.type != q.type || p.feed != q.feed || p.max_velocity != q.max_velocity ||
      p.max_acceleration != q.max_acceleration || p.term != q.term || p.tolerance != q.tolerance ||
      p.naive_cam_tolerance != q.naive_cam_tolerance || p.feed_override_allowed != q.feed_override_allowed) {
    return false;
  }
  double tol = q.naive_cam_tolerance;
  if (q.tolerance > 0) tol = std::min(tol, kMergeShare * q.tolerance);
  double err = distance_to_segment(m.end, m.start, end);
  if (err > tol) return false;
  for (int i = 0; i < m.count; ++i) {
    err = std::max(err, distance_to_segment(m.points[i], m.start, end));
    if (err > tol) return false;
  }
  // Must keep going forward along the chord.
  double dot = 0;
  for (int i = 0; i < kNumAxes; ++i) dot += (end[i] - m.end[i]) * (end[i] - m.start[i]);
  if (!(dot > 0)) return false;
  m.points[m.count++] = m.end;
  m.end = end;
  m.params.line = p.line;
  m.params.id = p.id;
  m.params.tag = p.tag;
  m.err = err;
  ++m.inputs;
  position_ = end;
  return true;
}

void PathBuilder::flush_merge() noexcept {
  Merge& m = *merge_;
  if (!m.active) return;
  m.active = false;
  push_line(m.start, m.end, m.params, m.inputs, m.err);
}

// A programmed line (or merged chord) from `start` to `end`: into the
// vertex smoothing stage when it belongs to a band (a G64 P feed line with
// the parameters of the band held), else straight to the segments.
void PathBuilder::push_line(const Pose& start, const Pose& end, const SegmentParams& p, uint32_t inputs,
                            double merge_err) noexcept {
  Fit& f = *fit_;
  const bool band = p.type == MotionType::Feed && p.term == TermCond::Blend && p.tolerance > 0;
  if (f.count > 0) {
    const SegmentParams& q = f.items[0].params;
    const bool same = band && p.feed == q.feed && p.max_velocity == q.max_velocity &&
                      p.max_acceleration == q.max_acceleration && p.tolerance == q.tolerance &&
                      p.naive_cam_tolerance == q.naive_cam_tolerance &&
                      p.feed_override_allowed == q.feed_override_allowed;
    if (!same) flush_fit();
  }
  if (!band) {
    Curve c;
    if (make_line(start, end, cfg_.max_blend_half_width, c)) append(c, p, inputs, merge_err);
    return;
  }
  if (f.count == 0) {
    // A new band starts where the path is: its first point stays.
    f.start = f.raw_start = start;
  }
  Fit::Item& it = f.items[f.count++];
  it.end = end;
  it.params = p;
  it.inputs = inputs;
  it.err = merge_err;
  if (f.count == Fit::kItems) fit_emit(1);
}

// Places the vertex at the end of the first held line (the last one of a
// band keeps its programmed end when `count` is what is held) and appends
// that line; `count` times.
void PathBuilder::fit_emit(int count) noexcept {
  Fit& f = *fit_;
  for (int n = 0; n < count && f.count > 0; ++n) {
    const Fit::Item& a = f.items[0];
    Pose q = a.end;
    if (f.count >= 2) {
      const Fit::Item& b = f.items[1];
      const double tol = a.params.tolerance;
      const double budget = kFitShare * tol - std::max(a.err, b.err);
      q = smooth_vertex(f.has_before ? &f.before : nullptr, f.raw_start, a.end, b.end,
                        f.count >= 3 ? &f.items[2].end : nullptr, budget, tol);
    }
    // The new line lies within its ends' larger distance from the
    // programmed one (convexity).
    const double e = std::max(distance_to_segment(f.start, f.raw_start, a.end), distance_to_segment(q, f.raw_start, a.end));
    Curve c;
    if (make_line(f.start, q, cfg_.max_blend_half_width, c)) {
      append(c, a.params, a.inputs + f.carry, a.err + e);
      f.carry = 0;
      f.start = q;
    } else {
      f.carry += a.inputs;  // counted with the next line
    }
    f.before = f.raw_start;
    f.has_before = true;
    f.raw_start = a.end;
    for (int i = 1; i < f.count; ++i) f.items[i - 1] = f.items[i];
    --f.count;
  }
  if (f.count == 0) {
    f.has_before = false;
    if (f.carry > 0) {
      // Moves left without length at the band's end still count as done
      // where the band ends (a stop point if that segment is already out).
      if (next_seq_ > first_unfinal_) {
        held(next_seq_ - 1).inputs += f.carry;
      } else {
        Curve pt;
        pt.start = pt.end = f.start;
        SegmentParams sp = f.items[0].params;
        sp.type = MotionType::Dwell;
        sp.term = TermCond::ExactStop;
        append(pt, sp, f.carry, 0);
      }
    }
    f.carry = 0;
  }
}

void PathBuilder::flush_fit() noexcept { fit_emit(Fit::kItems); }

Result PathBuilder::add_circle(const Pose& end, const std::array<double, 3>& center,
                               const std::array<double, 3>& normal, int turns, const SegmentParams& params) noexcept {
  if (params.type == MotionType::Dwell || params.type == MotionType::Traverse) return Result::InvalidSegment;
  if (!(params.feed > 0)) return Result::InvalidSegment;
  Curve c;
  if (!make_helix(position_, end, center, normal, turns, cfg_.max_blend_half_width, c)) return Result::InvalidSegment;
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const bool moves = c.rate[k] != 0 || (i < 3 && c.bound1[k] > 0);
    if (!(cfg_.axis_mask & (1u << i)) && moves) return Result::InvalidSegment;
  }
  if (!can_accept()) return Result::QueueFull;
  flush_merge();
  flush_fit();
  const Result r = append(c, params, 1, 0);
  if (r == Result::Ok) position_ = end;
  return r;
}

Result PathBuilder::add_dwell(double seconds, const SegmentParams& params) noexcept {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return Result::InvalidSegment;
  if (!can_accept()) return Result::QueueFull;
  flush_merge();
  flush_fit();
  if (next_seq_ > first_unfinal_ && held(next_seq_ - 1).junction == Junction::Unknown) {
    Held& h = held(next_seq_ - 1);
    h.junction = Junction::Stop;
    h.dwell = seconds;
    h.dwell_inputs = 1;
    h.spindle_wait = params.wait_spindle_at_speed;
    finalize(false);
    return Result::Ok;
  }
  const Result r = append_point(params);
  if (r != Result::Ok) return r;
  Held& h = held(next_seq_ - 1);
  h.junction = Junction::Stop;
  h.dwell = seconds;
  h.dwell_inputs = 1;
  h.spindle_wait = params.wait_spindle_at_speed;
  h.inputs = 0;
  finalize(false);
  return Result::Ok;
}

void PathBuilder::flush() noexcept {
  flush_merge();
  flush_fit();
  if (next_seq_ > first_unfinal_ && held(next_seq_ - 1).junction == Junction::Unknown) {
    held(next_seq_ - 1).junction = Junction::Stop;
  }
  finalize(true);
}

Result PathBuilder::append_point(const SegmentParams& params) noexcept {
  if (!store_.segs.has_room()) return Result::QueueFull;
  Curve c;
  c.start = c.end = position_;
  c.length = 0;
  SegmentParams p = params;
  p.type = MotionType::Dwell;
  p.term = TermCond::ExactStop;
  return append(c, p, 0, 0);
}

Result PathBuilder::append(const Curve& curve, const SegmentParams& params, uint32_t inputs,
                           double merge_err) noexcept {
  if (!store_.segs.has_room()) return Result::QueueFull;
  const uint64_t seq = next_seq_;
  SegmentRecord& out = store_.segs.push_slot();
  out.curve = curve;
  out.s0 = s_end_;
  out.type = params.type;
  out.line = params.line;
  out.id = params.id;
  out.tag = params.tag;
  out.epoch = epoch_;
  store_.segs.publish();
  Held& h = *std::construct_at(&held(seq));
  h.rec = out;
  h.params = params;
  h.inputs = inputs;
  h.merge_err = merge_err;
  next_seq_ = seq + 1;
  s_end_ += curve.length;
  if (seq > first_unfinal_) {
    Held& prev = held(seq - 1);
    if (prev.junction == Junction::Unknown) compute_junction(seq - 1);
  }
  finalize(false);
  return Result::Ok;
}

// A sharp corner whose tolerance leaves only a tiny window is passed faster
// by stopping at it than by crawling through the window: inside a window
// the speed is bounded by its curvature and the rate of change of that
// curvature, and the executor's averaging (T_f = A / J) spreads the slowest
// sample's limit over T_f on either side. Next to a curved move only the
// kink's share of the window's derivatives is counted (the curvature blend
// adds to them), so the estimate stays an upper bound. Measured (bench_tp, 1 mm
// zig-zag with 90 degree corners, 100 mm/s, 1000 mm/s^2, 50 000 mm/s^3):
// the windows of G64 P0.01 took 25.3 s, stopping at every corner (G61)
// 17.8 s; the two were equal at P0.05, where the window allows about a
// third of A T_f. So a corner becomes a stop when even
// the widest window its tolerance allows (an upper bound of the final one:
// neighbours and move lengths only narrow it) is slower than
// kStopBelowShare A T_f, A and T_f of the axes that turn.
bool PathBuilder::window_slower_than_stop(uint64_t j, const AxisVec& dt, double ndt, double m2) const noexcept {
  const double tol = std::min(tolerance_of(j), tolerance_of(j + 1));
  if (!(tol < kInf) || !(ndt > 0)) return false;
  double d = solve_half(kernel::kDeviationPerHalfWidth * ndt, 0.25 * m2, kTolShare * tol);
  if (cfg_.max_blend_half_width > 0) d = std::min(d, cfg_.max_blend_half_width);
  if (!(d > 0) || !std::isfinite(d)) return false;
  // Largest speed through a window of half width d (the ceiling's rows for
  // the second and third derivatives of the smoothed kink, per axis).
  const double keep = (1 - kCeilingReserve) * kLimitMargin;
  double v = kInf, a_turn = kInf, tf = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!(cfg_.axis_mask & (1u << i)) || std::fabs(dt[k]) < 1e-9) continue;
    const AxisLimits& l = cfg_.axes[k];
    const double c2 = std::fabs(dt[k]) * kernel::kPdfMax / (2 * d);
    const double c3 = std::fabs(dt[k]) * kernel::kPdf1Max / (4 * d * d);
    v = std::min({v, std::sqrt(keep * l.max_acceleration / c2), std::cbrt(keep * l.max_jerk / c3)});
    a_turn = std::min(a_turn, l.max_acceleration);
    if (l.max_jerk > 0) tf = std::max(tf, l.max_acceleration / l.max_jerk);
  }
  if (!std::isfinite(v) || !std::isfinite(a_turn)) return false;
  return v < kStopBelowShare * a_turn * tf;
}

void PathBuilder::compute_junction(uint64_t j) noexcept {
  Held& a = held(j);
  const Held& b = held(j + 1);
  const SegmentParams& pa = a.params;
  const SegmentParams& pb = b.params;
  if (pa.type == MotionType::Probe || pb.type == MotionType::Probe || pa.type == MotionType::Dwell ||
      pb.type == MotionType::Dwell || pa.term == TermCond::ExactStop || a.rec.curve.length <= 0 ||
      b.rec.curve.length <= 0) {
    a.junction = Junction::Stop;
    return;
  }
  AxisVec pin, tin, kin, pout, tout, kout;
  a.rec.curve.eval(a.rec.curve.length, pin, &tin, &kin);
  b.rec.curve.eval(0, pout, &tout, &kout);
  AxisVec dt{}, dk{};
  for (std::size_t k = 0; k < dt.size(); ++k) {
    dt[k] = tout[k] - tin[k];
    dk[k] = kout[k] - kin[k];
  }
  const double ndt = norm(dt);
  const double ndk = norm(dk);
  if (ndt <= kTangentEps && ndk <= kTangentEps) {
    a.junction = Junction::Smooth;
    return;
  }
  if (pa.term != TermCond::Blend) {
    a.junction = Junction::Stop;
    return;
  }
  const bool curved = a.rec.curve.is_curved() || b.rec.curve.is_curved();
  double m2 = 0;
  if (curved) {
    AxisVec b2{};
    for (std::size_t k = 0; k < b2.size(); ++k) b2[k] = a.rec.curve.bound2[k] + b.rec.curve.bound2[k];
    m2 = norm(b2);
  }
  if (window_slower_than_stop(j, dt, ndt, m2)) {
    a.junction = Junction::Stop;
    return;
  }
  a.junction = Junction::Window;
  a.vx = Vertex{};
  a.vx.s = b.rec.s0;
  a.vx.dt = dt;
  for (std::size_t k = 0; k < dt.size(); ++k) {
    if (dt[k] != 0) a.vx.axes = static_cast<uint16_t>(a.vx.axes | (1u << k));
  }
  a.vx.curved = curved;
  a.vx.seg_in = j;
  a.vx.epoch = epoch_;
  a.dt_norm = ndt;
  a.m2 = m2;
  a.tent = -1;
  a.final = false;
}

// The vertex n after j, or the first stop before it: windows never cross a
// stop, so nothing beyond it interacts with j.
uint64_t PathBuilder::horizon(uint64_t j, uint64_t n) const noexcept {
  for (uint64_t k = j; k < j + n && k < next_seq_; ++k) {
    if (held(k).junction == Junction::Stop) return k;
  }
  return j + n;
}

// The segment holding path position s as seen from segment `near`: the
// last one up to `near` that starts at or before s, or else the first one
// after it whose end reaches s. `from` is the answer for a smaller s (or
// `near`): answers grow with s, so the walk goes on from there.
uint64_t PathBuilder::segment_at(double s, uint64_t near, uint64_t from) const noexcept {
  uint64_t k = near;
  if (from == near) {
    while (k > first_seq_ && held(k).rec.s0 > s) --k;
  } else if (held(near).rec.s0 > s) {
    k = from;
    while (k + 1 < near && held(k + 1).rec.s0 <= s) ++k;
    return k;
  } else {
    k = std::max(from, near);
  }
  while (k + 1 < next_seq_ && held(k).rec.s0 + held(k).rec.curve.length < s) ++k;
  return k;
}

// Sum over the windows that cover s (vertices [lo, hi)) of each corner's
// correction size: a bound of the distance between the smoothed and the
// programmed path at s (exact when the corrections point the same way, as
// on a curve given as a polyline). Final windows count with their final
// width, the others with their tentative one (an upper bound).
double PathBuilder::deviation_bound(double s, uint64_t lo, uint64_t hi, double* second) const noexcept {
  double sum = 0;
  double sec = 0;
  for (uint64_t k = lo; k < hi; ++k) {
    const Held& o = held(k);
    if (o.junction != Junction::Window) continue;
    const double d = o.final ? o.vx.half : o.tent;
    if (!(d > 0) || std::fabs(s - o.vx.s) >= d) continue;
    double sk = 0;
    sum += correction_norm_at(o.dt_norm, o.m2, d, s - o.vx.s, &sk);
    sec += sk;
  }
  if (second) *second = sec;
  return sum;
}

// The corners whose windows at half width d_max may reach vertex j (j
// itself first, then the later ones, then the earlier ones): their offsets
// from j into near_ (s), returns how many. dense_fits() sums over them.
int PathBuilder::dense_neighbours(uint64_t j, double d_max) const noexcept {
  const Held& h = held(j);
  Near* near = near_.get();
  int n = 0;
  near[n++] = {0, 0, h.dt_norm, h.m2};
  for (uint64_t k = j + 1; k < next_seq_; ++k) {
    const Held& o = held(k - 1);
    if (o.junction == Junction::Stop || o.junction == Junction::Unknown) break;
    if (held(k).junction == Junction::Unknown) break;
    if (held(k).junction != Junction::Window) {
      if (held(k).junction == Junction::Stop) break;
      continue;
    }
    const double x = held(k).vx.s - h.vx.s;
    if (x >= d_max) break;
    near[n++] = {x, 0, held(k).dt_norm, held(k).m2};
  }
  for (uint64_t k = j; k > first_seq_;) {
    --k;
    const Held& o = held(k);
    if (o.junction == Junction::Stop) break;
    if (o.junction != Junction::Window) continue;
    const double x = h.vx.s - o.vx.s;
    if (x >= d_max) break;
    near[n++] = {x, 0, o.dt_norm, o.m2};
  }
  return n;
}

// Whether the deviation at vertex j stays within `budget` if every corner
// near it had half width d <= d_max (the first estimate of how wide a
// window a dense run of corners allows), over the n corners
// dense_neighbours(j, d_max) found (the others are farther than d: they add
// nothing). The terms are never negative, so the sum stops as soon as it
// exceeds the budget: the answer is the full sum's (issue 20: about half of
// the bisection's terms).
bool PathBuilder::dense_fits(int n, double d, double budget) noexcept {
  const Near* near = near_.get();
  double sum = correction_norm_at(near[0].dt_norm, near[0].m2, d, 0);
  ++size_terms_;
  for (int i = 1; i < n && !(sum > budget); ++i) {
    if (near[i].s < d) {
      sum += correction_norm_at(near[i].dt_norm, near[i].m2, d, near[i].s);
      ++size_terms_;
    }
  }
  return !(sum > budget);
}

// First, tentative width of corner j's window: as wide as the room around
// it allows (at most `span` moves and max_blend_half_width each way, never
// across a stop nor over moves with a tighter tolerance), within the
// tolerance if the corners nearby were as wide, and varying slowly from
// one corner to the next. Later steps only ever make it narrower.
void PathBuilder::tentative_half(uint64_t j) noexcept {
  Held& h = held(j);
  h.tent = 0;
  if (h.junction != Junction::Window) return;
  const uint64_t span = static_cast<uint64_t>(span_);
  const double tol = std::min(tolerance_of(j), tolerance_of(j + 1));
  const double raw = held(j).params.tolerance > 0 ? held(j).params.tolerance : kInf;
  auto tighter = [&](uint64_t k) {
    const double t = held(k).params.tolerance;
    return (t > 0 ? t : kInf) < raw;
  };
  double back = 0;
  for (uint64_t k = j;; --k) {
    back += held(k).rec.curve.length;
    if (k == first_seq_ || k + span <= j + 1) break;
    const Held& prev = held(k - 1);
    if (prev.junction == Junction::Stop || prev.junction == Junction::Unknown) break;
    if (tighter(k - 1)) break;
  }
  double fwd = 0;
  for (uint64_t k = j + 1; k < next_seq_; ++k) {
    fwd += held(k).rec.curve.length;
    if (k >= j + span) break;
    const Junction jk = held(k).junction;
    if (jk == Junction::Stop || jk == Junction::Unknown) break;
    if (k + 1 < next_seq_ && tighter(k + 1)) break;
  }
  double d = std::min({back, fwd, cfg_.max_blend_half_width > 0 ? cfg_.max_blend_half_width : kInf});
  if (!(tol < kInf)) {
    // G64 without P: as large as the two moves allow, like LinuxCNC's blends.
    d = std::min({d, 0.5 * held(j).rec.curve.length, 0.5 * held(j + 1).rec.curve.length});
  } else {
    const double budget = kTolShare * tol;
    d = std::min(d, solve_half(kernel::kDeviationPerHalfWidth * h.dt_norm, 0.25 * h.m2, budget));
    const int n = d > 0 ? dense_neighbours(j, d) : 0;
    if (d > 0 && !dense_fits(n, d, budget)) {
      double lo = 0, hi = d;
      for (int it = 0; it < 14; ++it) {
        const double mid = 0.5 * (lo + hi);
        (dense_fits(n, mid, budget) ? lo : hi) = mid;
      }
      d = lo;
    }
  }
  if (!std::isfinite(d) || d < 0) d = 0;
  // Slowly varying widths: |d_j - d_k| <= kWidthSlope |s_j - s_k|, against
  // the nearest earlier corner; earlier tentative widths come down to match.
  for (uint64_t k = j; k > first_seq_;) {
    --k;
    const Held& o = held(k);
    if (o.junction == Junction::Stop) break;
    if (o.junction != Junction::Window) continue;
    const double dk = o.final ? o.vx.half : o.tent;
    d = std::min(d, dk + kWidthSlope * (h.vx.s - o.vx.s));
    break;
  }
  h.tent = d;
  for (uint64_t k = j; k > first_seq_;) {
    --k;
    Held& o = held(k);
    if (o.junction == Junction::Stop || o.final) break;
    if (o.junction != Junction::Window) continue;
    const double cap = d + kWidthSlope * (h.vx.s - o.vx.s);
    if (o.tent <= cap) break;
    o.tent = cap;
  }
}

// Makes corner j's window final. Every point its window covers is checked
// (samples every d/8 plus a margin from the second-derivative bound)
// against the tolerance there, with the later windows at their tentative
// widths; where the bound exceeds it, this window and the later ones
// covering that point shrink. Widths only ever shrink and every correction
// grows with its width, so what was checked stays true; every point a
// window covers is checked when the last of the windows covering it
// becomes final.
void PathBuilder::final_half(uint64_t j) noexcept {
  Held& h = held(j);
  h.final = true;
  if (h.junction != Junction::Window || !(h.tent > 0)) {
    h.vx.half = 0;
    h.tent = 0;
    return;
  }
  const uint64_t span = static_cast<uint64_t>(span_);
  // Corners whose windows may share points with this one: the same run,
  // within 2 span moves.
  uint64_t lo = j;
  while (lo > first_seq_ && lo + 2 * span > j && held(lo - 1).junction != Junction::Stop) --lo;
  uint64_t hi = j + 1;
  while (hi < next_tent_ && hi <= j + 2 * span && held(hi - 1).junction != Junction::Stop) ++hi;
  const double s_j = h.vx.s;
  Near* near = near_.get();  // hi - lo <= 4 span + 1 entries
  double seg_lo = 0, seg_hi = 0, seg_tol = 0;  // the segment of the last sample: (s0, end), tolerance
  h.final = false;  // counts with h.tent while being checked
  for (int it = 0; it < 24; ++it) {
    const double d = h.tent;
    const double a = s_j - d;
    const double b = s_j + d;
    if (!(b > a) || !(d > 1e-12)) break;
    // The windows that reach [a, b] (the others add nothing to any point
    // of it), and one bound of the second derivative over [a, b]: their sum.
    double sec = 0;
    double d_max = 0;
    int nw = 0;
    for (uint64_t k = lo; k < hi; ++k) {
      const Held& o = held(k);
      if (o.junction != Junction::Window) continue;
      const double dk = o.final ? o.vx.half : o.tent;
      if (!(dk > 0) || o.vx.s + dk <= a || o.vx.s - dk >= b) continue;
      double sk = 0;
      correction_norm_at(o.dt_norm, o.m2, dk, dk, &sk);
      sec += sk;
      near[nw++] = {o.vx.s, dk, o.dt_norm, o.m2};
      d_max = std::max(d_max, dk);
    }
    // The windows come in the order of their corners; those from `end` on
    // start after the sample (further than the widest half width ahead of
    // it, with room for rounding): they add 0 there.
    const double ahead = d_max * (1 + 1e-9);
    const int n = std::clamp(static_cast<int>(std::ceil((b - a) / (d / 8))), 1, 64);
    const double step = (b - a) / n;
    const double margin = step * step / 8 * sec;
    double worst = 1;
    double s_worst = s_j;
    int first = 0;  // windows before it end before the sample (samples go forward)
    int end = 0;
    uint64_t seg_k = j;  // the segment of the last sample looked up in this pass
    // Each sample's sum over the windows, window by window (in the order
    // of the windows, so each sum adds the same terms in the same order;
    // those of windows that do not reach a sample are 0).
    double xs[65];
    double sums[65];
    for (int i = 0; i <= n; ++i) {
      xs[i] = a + step * i;
      sums[i] = 0;
    }
    for (int w = 0; w < nw; ++w) add_correction_norms(near[w].dt_norm, near[w].m2, near[w].d, near[w].s, xs, n + 1, sums);
    for (int i = 0; i <= n; ++i) {
      const double x = xs[i];
      // The tolerance of the segment holding x (segment_at(x, j, ...)): the
      // previous sample's while x lies strictly inside that segment.
      if (!(x > seg_lo && x < seg_hi)) {
        seg_k = segment_at(x, j, seg_k);
        const uint64_t k = seg_k;
        seg_lo = held(k).rec.s0;
        seg_hi = seg_lo + held(k).rec.curve.length;
        seg_tol = tolerance_of(k);
      }
      const double tol = seg_tol;
      if (!(tol < kInf)) continue;
      while (first < nw && x - near[first].s >= near[first].d) ++first;  // adds 0 from here on
      while (end < nw && near[end].s - x < ahead) ++end;
      check_terms_ += static_cast<uint64_t>(std::max(0, end - first));
      double dev = margin;
      dev += sums[i];
      const double ratio = tol > 0 ? dev / tol : kInf;
      if (ratio > worst) {
        worst = ratio;
        s_worst = x;
      }
    }
    if (worst <= 1) break;
    const double f = std::isfinite(worst) ? 0.97 / worst : 0.0;
    h.tent *= f;
    for (uint64_t k = j + 1; k < hi; ++k) {
      Held& o = held(k);
      if (o.junction == Junction::Window && !o.final && std::fabs(s_worst - o.vx.s) < o.tent) o.tent *= f;
    }
  }
  h.final = true;
  // Never sharp: a corner squeezed to nothing keeps a tiny window (passed
  // at a crawl, in a negligible time) rather than a kink.
  h.vx.half = std::max(h.tent, 1e-9);
  h.tent = h.vx.half;
}

bool PathBuilder::emit_vertices_upto(uint64_t j) noexcept {
  while (vertices_out_ <= j) {
    if (!store_.verts.has_room()) return false;
    const uint64_t k = vertices_out_;
    Vertex& out = store_.verts.push_slot();
    if (k >= first_seq_ && k < next_seq_ && held(k).junction == Junction::Window) {
      out = held(k).vx;
    } else {
      out = Vertex{};
      out.seg_in = k;
    }
    out.epoch = epoch_;
    ++vertices_out_;
  }
  return true;
}

// Three stages run as far as what is known allows: a corner gets its
// tentative window once `span` moves after it are known (or a stop), its
// final window once the tentative windows of the 2 span corners after it
// are known, and a move's pieces go out once the windows that may reach it
// are final.
void PathBuilder::finalize(bool flushing) noexcept {
  const uint64_t span = static_cast<uint64_t>(span_);
  auto room_known = [&](uint64_t j) {
    for (uint64_t k = j + 1; k <= j + span; ++k) {
      if (k >= next_seq_) return false;
      const Junction jk = held(k).junction;
      if (jk == Junction::Stop) return true;
      if (jk == Junction::Unknown) return false;
    }
    return true;
  };
  while (next_tent_ < next_seq_) {
    const uint64_t j = next_tent_;
    if (held(j).junction == Junction::Unknown) break;
    if (!flushing && held(j).junction == Junction::Window && !room_known(j)) break;
    tentative_half(j);
    ++next_tent_;
  }
  while (next_final_ < next_tent_) {
    const uint64_t j = next_final_;
    // A corner's window is checked against the corners after it; a junction
    // without a window (collinear, tangent, a stop) has nothing to check and
    // is final at once, so a straight run is not held back for them.
    if (held(j).junction == Junction::Window && horizon(j, 2 * span + 1) >= next_tent_) break;
    final_half(j);
    ++next_final_;
  }
  bool any = false;
  while (first_unfinal_ < next_final_) {
    const uint64_t m = first_unfinal_;
    if (horizon(m, span + 1) >= next_final_) break;
    if (!store_.pieces.has_room(kMaxPiecesPerMove)) break;
    if (!emit_vertices_upto(std::min(m + span, next_final_ - 1))) break;
    if (!emit_pieces(m)) break;
    ++first_unfinal_;
    ++built_;
    any = true;
    while (first_seq_ + 2 * span + 2 < first_unfinal_) ++first_seq_;
  }
  if (any) {
    store_.verts.publish();
    store_.pieces.publish();
  }
}

bool PathBuilder::emit_pieces(uint64_t m) noexcept {
  const Held& h = held(m);
  const Curve& curve = h.rec.curve;
  const double len = curve.length;
  const uint64_t span = static_cast<uint64_t>(span_);
  // Windows that may touch this segment.
  const uint64_t vlo = m >= first_seq_ + span + 1 ? m - span - 1 : first_seq_;
  const uint64_t vhi = std::min(m + span + 1, next_seq_);
  // Pieces: the parts of the move that no window covers keep the move's
  // own limits; the covered parts are cut every half of the narrowest
  // window there, so that each piece's limits describe its own stretch.
  constexpr int kMaxCuts = static_cast<int>(kMaxPiecesPerMove) + 1;
  double pts[kMaxCuts];
  int np = 0;
  pts[np++] = 0;
  if (len > 0) {
    // The union of the windows on [0, len], as sorted disjoint intervals.
    struct Span {
      double a, b, d;
    };
    Span spans[4 * 32 + 8];
    int ns = 0;
    for (uint64_t i = vlo; i < vhi; ++i) {
      const Held& o = held(i);
      if (o.junction != Junction::Window || !(o.vx.half > 0)) continue;
      const double a = std::max(0.0, o.vx.s - o.vx.half - h.rec.s0);
      const double b = std::min(len, o.vx.s + o.vx.half - h.rec.s0);
      if (b > a && ns < static_cast<int>(std::size(spans))) spans[ns++] = {a, b, o.vx.half};
    }
    std::sort(spans, spans + ns, [](const Span& x, const Span& y) { return x.a < y.a; });
    int nm = 0;
    for (int i = 0; i < ns; ++i) {
      if (nm > 0 && spans[i].a <= spans[nm - 1].b) {
        spans[nm - 1].b = std::max(spans[nm - 1].b, spans[i].b);
        spans[nm - 1].d = std::min(spans[nm - 1].d, spans[i].d);
      } else {
        spans[nm++] = spans[i];
      }
    }
    // Cuts per covered stretch, within the budget of pieces per move.
    int budget = kMaxCuts - 2 - 2 * nm;
    for (int i = 0; i < nm; ++i) {
      const Span& sp = spans[i];
      pts[np++] = sp.a;
      const int want = static_cast<int>(std::ceil((sp.b - sp.a) / (0.5 * sp.d)));
      const int n = std::clamp(want, 1, std::max(1, budget / std::max(1, nm - i)));
      budget -= n - 1;
      for (int k = 1; k < n; ++k) pts[np++] = sp.a + (sp.b - sp.a) * k / n;
      pts[np++] = sp.b;
    }
    pts[np++] = len;
    std::sort(pts, pts + np);
    int w = 0;
    const double gap = 1e-9 * std::max(1.0, len);
    for (int i = 0; i < np; ++i) {
      const double c = std::clamp(pts[i], 0.0, len);
      if (w == 0 || c - pts[w - 1] > gap) pts[w++] = c;
    }
    np = w;
    if (np >= 2) pts[np - 1] = len;
  }
  const int pieces = len > 0 ? np - 1 : 0;
  // The windows that may reach the move (a margin far above rounding), so
  // that each piece looks only at them.
  uint64_t reach[2 * 32 + 2];
  int nreach = 0;
  {
    const double margin = 1e-9 * (1 + std::fabs(h.rec.s0) + len);
    for (uint64_t i = vlo; i < vhi; ++i) {
      const Held& o = held(i);
      if (o.junction != Junction::Window || !(o.vx.half > 0)) continue;
      if (o.vx.s + o.vx.half < h.rec.s0 - margin || o.vx.s - o.vx.half > h.rec.s0 + len + margin) continue;
      reach[nreach++] = i;
    }
  }
  for (int p = 0; p < pieces; ++p) {
    const double a = pts[p];
    const double b = pts[p + 1];
    const double ga = h.rec.s0 + a;
    const double gb = h.rec.s0 + b;
    // Made in its slot (published with the others at the end).
    Piece& pc = *std::construct_at(&store_.pieces.push_slot());
    pc.s0 = ga;
    pc.length = b - a;
    pc.seg = m;
    pc.epoch = epoch_;
    pc.probe = h.params.type == MotionType::Probe;
    AxisVec b1 = curve.bound1;
    AxisVec b2 = curve.bound2;
    AxisVec b3 = curve.bound3;
    AxisVec b4{};
    uint64_t tlo = m, thi = m;
    bool any = false;
    bool curved = curve.is_curved();
    double d_min = kInf;
    for (int r = 0; r < nreach; ++r) {
      const uint64_t i = reach[r];
      const Held& o = held(i);
      if (gb <= o.vx.s - o.vx.half || ga >= o.vx.s + o.vx.half) continue;
      if (!any) tlo = i;
      thi = i + 1;
      any = true;
      curved = curved || o.vx.curved;
      d_min = std::min(d_min, o.vx.half);
      add_correction_bounds(o.vx, ga - o.vx.s, gb - o.vx.s, held(i).rec.curve, held(i + 1).rec.curve, b1, b2, b3,
                            &b4);
    }
    pc.v_lo = tlo;
    pc.v_hi = thi;
    // Derivatives: a bare curve has exact bounds; inside corner windows the
    // corrections of neighbouring corners partly cancel (a polyline along a
    // curve, a zig-zag), so the sums are sampled densely and the next
    // derivative's bound covers what lies between samples.
    AxisVec c1 = curve.bound1;
    AxisVec c2 = b2;
    AxisVec c3 = b3;
    double speed_max = 1;
    if (curve.kind == CurveKind::Helix && !any) {
      // Bare helix (no corner window here): exact. dP/ds = dr e + rho w f +
      // dh n + rate with e, f, n orthonormal (e, f rotating in the plane),
      // so |dP/ds|^2 = dr^2 + (rho w)^2 + dh^2 (+ the linear axes of the
      // group), largest where |rho| is, at an end of [a, b] (rho is linear
      // and keeps its sign on the move). Per axis, |dr e_i + rho w f_i| <=
      // hypot(dr, rho w) hypot(u_i, v_i).
      const double rho = std::max(std::fabs(curve.r0 + curve.dr * a), std::fabs(curve.r0 + curve.dr * b));
      const double tang = std::hypot(curve.dr, rho * curve.omega);
      AxisVec d1{};
      for (std::size_t k = 0; k < d1.size(); ++k) {
        if (k < 3) {
          const double mk = std::hypot(curve.u[k], curve.v[k]);
          c1[k] = std::min(b1[k], tang * mk + std::fabs(curve.dh * curve.n[k]));
        }
        d1[k] = k < 3 ? 0.0 : curve.rate[k];
      }
      // The helix part always belongs to the XYZ group; other groups' rates
      // are constant.
      speed_max = curve.group == LengthGroup::Xyz ? std::hypot(tang, curve.dh) : group_norm(d1, curve.group);
    } else if (any) {
      const double step_max = curved ? 0.25 * (b - a) : d_min / 16;
      const int n = std::clamp(static_cast<int>(std::ceil((b - a) / step_max)), 2, 48);
      const double step = (b - a) / n;
      AxisVec m1{}, m2{}, m3{};
      double speed2 = 0;
      // The windows on this piece; a corner between two lines adds only
      // its kink's derivatives (no position, no neighbouring curves).
      const Held* win[2 * 32 + 2];
      uint64_t win_seq[2 * 32 + 2];
      unsigned win_axes[2 * 32 + 2];  // curved corners: curved_correction_axes
      int nwin = 0;
      for (uint64_t k = tlo; k < thi; ++k) {
        const Held& o = held(k);
        if (o.junction != Junction::Window || !(o.vx.half > 0)) continue;
        win_axes[nwin] = o.vx.curved ? curved_correction_axes(o.vx, o.rec.curve, held(k + 1).rec.curve) : 0;
        win_seq[nwin] = k;
        win[nwin++] = &o;
      }
      // Only the axes that move or turn get derivatives; the others stay
      // zero. Between lines (nothing curved) the base line adds its
      // constant direction without an evaluation.
      // With curved corners, the axes of their curvature blends too, and a
      // helix's own (the others' derivatives are zeros).
      unsigned moving = 0;
      for (int w = 0; w < nwin; ++w) moving |= win[w]->vx.axes | win_axes[w];
      uint8_t axes[kNumAxes];
      int n_axes = 0;
      unsigned evaluated = 7u << (static_cast<unsigned>(curve.group) * 3);  // and the speed's axes
      for (int k = 0; k < kNumAxes; ++k) {
        const bool active = (curve.is_curved() && k < 3) || curve.rate[static_cast<std::size_t>(k)] != 0 ||
                            (moving & (1u << k));
        if (!active) continue;
        axes[n_axes++] = static_cast<uint8_t>(k);
        evaluated |= 1u << k;
      }
      if (!curved) {
        sample_kinks(curve, h.rec.s0, a, step, n, win, win_seq, nwin, m, axes, n_axes, m1, m2, m3, speed2);
      }
      for (int i = 0; curved && i <= n; ++i) {
        const double x = a + step * i;
        AxisVec pos, d1, d2, d3;
        curve.eval_axes(x, evaluated, pos, d1, d2, d3);
        for (int w = 0; w < nwin; ++w) {
          const Vertex& vx = win[w]->vx;
          const uint64_t k = win_seq[w];
          const double dx = h.rec.s0 + x - vx.s;
          if (std::fabs(dx) >= vx.half) continue;
          if (vx.curved) {
            add_correction_derivatives(vx, dx, m > k, held(k).rec.curve, held(k + 1).rec.curve, win_axes[w], d1, d2,
                                       d3);
            continue;
          }
          add_kink_derivatives(vx, dx, m > k, d1, d2, d3);
        }
        for (int j = 0; j < n_axes; ++j) {
          const std::size_t k = axes[j];
          m1[k] = std::max(m1[k], std::fabs(d1[k]));
          m2[k] = std::max(m2[k], std::fabs(d2[k]));
          m3[k] = std::max(m3[k], std::fabs(d3[k]));
        }
        // The largest squared norm, its root once (the root is correctly
        // rounded, so the same value as the largest root).
        const auto o = static_cast<std::size_t>(curve.group) * 3;
        speed2 = std::max(speed2, d1[o] * d1[o] + d1[o + 1] * d1[o + 1] + d1[o + 2] * d1[o + 2]);
      }
      const double speed = std::sqrt(speed2);
      const double half_step = 0.5 * step;
      for (std::size_t k = 0; k < c1.size(); ++k) {
        c1[k] = std::min(b1[k], m1[k] + b2[k] * half_step);
        if (!curved) {
          c2[k] = std::min(b2[k], m2[k] + b3[k] * half_step);
          c3[k] = std::min(b3[k], m3[k] + b4[k] * half_step);
        }
      }
      speed_max = std::min(speed + group_norm(b2, curve.group) * half_step, group_norm(b1, curve.group));
    }
    pc.bounds.c1 = c1;
    pc.bounds.c2 = c2;
    pc.bounds.c3 = c3;
    pc.bounds.lin1 = std::sqrt(c1[0] * c1[0] + c1[1] * c1[1] + c1[2] * c1[2]);
    pc.bounds.lin2 = std::sqrt(c2[0] * c2[0] + c2[1] * c2[1] + c2[2] * c2[2]);
    pc.bounds.lin3 = std::sqrt(c3[0] * c3[0] + c3[1] * c3[1] + c3[2] * c3[2]);
    pc.v_hard = ceiling_of(pc.bounds, cfg_);
    speed_max = std::max(speed_max, 1e-9);
    pc.inv_speed = 1.0 / speed_max;
    // Feeds and caps of this move and of the moves whose corners reach here.
    auto apply = [&](const SegmentParams& sp) {
      if (sp.max_velocity > 0) pc.v_hard = std::min(pc.v_hard, sp.max_velocity / speed_max);
      if (sp.max_acceleration > 0) pc.a_cap = std::min(pc.a_cap, sp.max_acceleration / speed_max);
      if (!(sp.feed > 0)) return;
      const double v = sp.feed / speed_max;
      if (sp.type == MotionType::Traverse) {
        pc.v_rapid = std::min(pc.v_rapid, v);
      } else if (sp.feed_override_allowed) {
        pc.v_feed = std::min(pc.v_feed, v);
      } else {
        pc.v_hard = std::min(pc.v_hard, v);
      }
    };
    apply(h.params);
    for (uint64_t i = tlo; i < thi; ++i) {
      if (held(i).junction != Junction::Window) continue;
      apply(held(i).params);
      apply(held(i + 1).params);
    }
    pc.inputs_done = (p == pieces - 1) ? h.inputs : 0;
  }
  if (h.junction == Junction::Stop || pieces == 0) {
    Piece st;
    st.s0 = h.rec.s0 + len;
    st.length = 0;
    st.seg = m;
    st.v_lo = st.v_hi = m;
    st.v_hard = 0;
    st.v_feed = st.v_rapid = kInf;
    st.epoch = epoch_;
    st.stop = h.dwell_inputs > 0 ? StopKind::Dwell : StopKind::Stop;
    st.dwell_s = h.dwell;
    st.spindle_wait = h.spindle_wait;
    st.inputs_done = h.dwell_inputs + (pieces == 0 ? h.inputs : 0);
    store_.pieces.push_slot() = st;
  }
  return true;
}

}  // namespace cnc::tp
