#include "core/tp/path_builder.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::tp {
namespace {

// Limits are planned this far inside the configured ones: room for rounding
// and for the sampled bounds.
constexpr double kLimitMargin = 0.999;
// A piece reserves at least these shares of the smallest axis acceleration
// and jerk for speeding up and braking along the path...
constexpr double kRegularAccelShare = 0.5;
constexpr double kRegularJerkShare = 0.5;
// ...unless giving most of them to the curvature lets it go this much faster:
// then it becomes a "barrier", passed at nearly constant speed.
constexpr double kBarrierAccelShare = 0.05;
constexpr double kBarrierJerkShare = 0.1;
constexpr double kBarrierGain = 1.25;
constexpr int kMaxMerge = 32;
constexpr double kTangentEps = 1e-9;

struct Row {
  double c1, c2, c3, vmax, amax, jmax;
};

int build_rows(const AxisVec& c1, const AxisVec& c2, const AxisVec& c3, const PlannerConfig& cfg, Row* rows) {
  int n = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(cfg.axis_mask & (1u << i))) continue;
    const auto k = static_cast<std::size_t>(i);
    const AxisLimits& l = cfg.axes[k];
    rows[n++] = {c1[k], c2[k], c3[k], l.max_velocity * kLimitMargin, l.max_acceleration * kLimitMargin,
                 l.max_jerk * kLimitMargin};
  }
  auto xyz = [](const AxisVec& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); };
  const double lv = cfg.max_linear_velocity > 0 ? cfg.max_linear_velocity * kLimitMargin : kInf;
  const double la = cfg.max_linear_acceleration > 0 ? cfg.max_linear_acceleration * kLimitMargin : kInf;
  const double lj = cfg.max_linear_jerk > 0 ? cfg.max_linear_jerk * kLimitMargin : kInf;
  if (lv < kInf || la < kInf || lj < kInf) rows[n++] = {xyz(c1), xyz(c2), xyz(c3), lv, la, lj};
  return n;
}

struct Option {
  double v = 0, a = 0, j = 0;
};

// Largest velocity V with tangential accel >= a_floor and jerk >= j_floor
// available on every row for every speed up to V.
Option solve_option(const Row* rows, int n, double v_geo, double a_floor, double j_floor) {
  auto accel_at = [&](double v) {
    double a = kInf;
    for (int r = 0; r < n; ++r) {
      const Row& w = rows[r];
      const double rest = w.amax - w.c2 * v * v;
      if (w.c1 > 1e-12) {
        a = std::min(a, rest / w.c1);
      } else if (rest < 0) {
        a = -1;
      }
      if (w.c2 * v > 1e-300) a = std::min(a, (w.jmax - w.c3 * v * v * v - j_floor * w.c1) / (3 * w.c2 * v));
    }
    return a;
  };
  auto jerk_at = [&](double v, double a) {
    double j = kInf;
    for (int r = 0; r < n; ++r) {
      const Row& w = rows[r];
      const double rest = w.jmax - w.c3 * v * v * v - 3 * w.c2 * v * a;
      if (w.c1 > 1e-12) {
        j = std::min(j, rest / w.c1);
      } else if (rest < 0) {
        j = -1;
      }
    }
    return j;
  };
  auto feasible = [&](double v) {
    const double a = accel_at(v);
    return a >= a_floor && jerk_at(v, a) >= j_floor * (1 - 1e-9);
  };
  Option o;
  if (!feasible(0)) return o;
  double lo = 0;
  double hi = v_geo;
  if (!std::isfinite(hi)) hi = 1e9;
  if (feasible(hi)) {
    lo = hi;
  } else {
    for (int it = 0; it < 60 && hi - lo > 1e-9 * (1 + hi); ++it) {
      const double mid = 0.5 * (lo + hi);
      (feasible(mid) ? lo : hi) = mid;
    }
  }
  o.v = lo;
  o.a = accel_at(lo);
  o.j = jerk_at(lo, o.a);
  return o;
}

double dist_point_segment(const Pose& p, const Pose& a, const Pose& b) {
  double ab2 = 0, t = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    const double d = b[i] - a[i];
    ab2 += d * d;
    t += (p[i] - a[i]) * d;
  }
  t = ab2 > 0 ? std::clamp(t / ab2, 0.0, 1.0) : 0.0;
  double r = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    const double d = p[i] - (a[i] + t * (b[i] - a[i]));
    r += d * d;
  }
  return std::sqrt(r);
}

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

}  // namespace

PieceLimits derive_limits(const AxisVec& c1, const AxisVec& c2, const AxisVec& c3, const PlannerConfig& cfg) noexcept {
  Row rows[kNumAxes + 1];
  const int n = build_rows(c1, c2, c3, cfg, rows);
  double v_geo = kInf;
  for (int r = 0; r < n; ++r) {
    if (rows[r].c1 > 1e-12) v_geo = std::min(v_geo, rows[r].vmax / rows[r].c1);
  }
  const LimitFloors f = limit_floors(cfg);
  const Option reg = solve_option(rows, n, v_geo, f.accel, f.jerk);
  const Option bar = solve_option(rows, n, v_geo, f.accel * kBarrierAccelShare / kRegularAccelShare,
                                  f.jerk * kBarrierJerkShare / kRegularJerkShare);
  PieceLimits out;
  if (reg.v > 0 && bar.v <= kBarrierGain * reg.v) {
    out = {reg.v, reg.a, reg.j, false};
  } else {
    out = {bar.v, bar.a, bar.j, true};
  }
  // Never a dead end: keep something to crawl with.
  const double a_min = f.accel * kBarrierAccelShare / kRegularAccelShare;
  const double j_min = f.jerk * kBarrierJerkShare / kRegularJerkShare;
  if (!(out.velocity > 1e-9)) out.velocity = 1e-9;
  if (!(out.accel > 0)) out.accel = a_min;
  if (!(out.jerk > 0)) out.jerk = j_min;
  return out;
}

LimitFloors limit_floors(const PlannerConfig& cfg) noexcept {
  double a = kInf, j = kInf;
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(cfg.axis_mask & (1u << i))) continue;
    a = std::min(a, cfg.axes[static_cast<std::size_t>(i)].max_acceleration);
    j = std::min(j, cfg.axes[static_cast<std::size_t>(i)].max_jerk);
  }
  if (cfg.max_linear_acceleration > 0) a = std::min(a, cfg.max_linear_acceleration);
  if (cfg.max_linear_jerk > 0) j = std::min(j, cfg.max_linear_jerk);
  if (!std::isfinite(a)) a = 0;
  if (!std::isfinite(j)) j = 0;
  return {a * kLimitMargin * kRegularAccelShare, j * kLimitMargin * kRegularJerkShare};
}

struct PathBuilder::Held {
  SegmentRecord rec;
  SegmentParams params;
  uint32_t inputs = 1;
  Junction junction = Junction::Unknown;
  double dwell = 0;         // with Junction::Stop: dwell at the stop
  uint32_t dwell_inputs = 0;
  Vertex vx;                // with Junction::Window
  double c1 = 0, c2 = 0;    // deviation of the window: c1 d + c2 d^2
  double d0 = -1;           // first half width (-1: not computed)
  double w0 = 0;            // deviation with d0
  double tol = kInf;        // tolerance over what the d0 window covers
  bool final = false;
};

struct PathBuilder::Merge {
  bool active = false;
  Pose start;
  Pose end;
  SegmentParams params;
  Pose points[kMaxMerge];
  int count = 0;
  uint32_t inputs = 0;
};

PathBuilder::PathBuilder(const PlannerConfig& config, PathStore& store)
    : cfg_(config), store_(store), merge_(std::make_unique<Merge>()) {
  span_ = std::clamp(cfg_.blend_span_segments, 1, 32);
  std::size_t c = 2;
  while (c < static_cast<std::size_t>(8 * span_ + 64)) c *= 2;
  held_ = std::make_unique<Held[]>(c);
  held_mask_ = c - 1;
}

PathBuilder::~PathBuilder() = default;

PathBuilder::Held& PathBuilder::held(uint64_t seq) noexcept { return held_[seq & held_mask_]; }
const PathBuilder::Held& PathBuilder::held(uint64_t seq) const noexcept { return held_[seq & held_mask_]; }

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
  return next_seq_ - first_seq_ + 4 < held_mask_ + 1 && store_.segs.has_room(2);
}

bool PathBuilder::has_held() const noexcept { return merge_->active || first_unfinal_ < next_seq_; }

void PathBuilder::reset(uint32_t epoch) noexcept {
  merge_->active = false;
  epoch_ = epoch;
  first_seq_ = first_unfinal_ = next_seq_ = store_.segs.head();
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
    position_ = end;
    return Result::Ok;
  }
  const Result r = append(probe_curve, params, 1);
  if (r == Result::Ok) position_ = end;
  return r;
}

bool PathBuilder::try_merge(const Pose& end, const SegmentParams& p) noexcept {
  Merge& m = *merge_;
  if (!m.active || m.count >= kMaxMerge) return false;
  const SegmentParams& q = m.params;
  if (p.type != q.type || p.feed != q.feed || p.max_velocity != q.max_velocity ||
      p.max_acceleration != q.max_acceleration || p.term != q.term || p.tolerance != q.tolerance ||
      p.naive_cam_tolerance != q.naive_cam_tolerance || p.feed_override_allowed != q.feed_override_allowed) {
    return false;
  }
  const double tol = q.naive_cam_tolerance;
  if (dist_point_segment(m.end, m.start, end) > tol) return false;
  for (int i = 0; i < m.count; ++i) {
    if (dist_point_segment(m.points[i], m.start, end) > tol) return false;
  }
  // Must keep going forward along the chord.
  double dot = 0;
  for (int i = 0; i < kNumAxes; ++i) dot += (end[i] - m.end[i]) * (end[i] - m.start[i]);
  if (!(dot > 0)) return false;
  m.points[m.count++] = m.end;
  m.end = end;
  m.params.line = p.line;
  m.params.id = p.id;
  ++m.inputs;
  position_ = end;
  return true;
}

void PathBuilder::flush_merge() noexcept {
  Merge& m = *merge_;
  if (!m.active) return;
  m.active = false;
  Curve c;
  if (make_line(m.start, m.end, cfg_.max_blend_half_width, c)) append(c, m.params, m.inputs);
}

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
  const Result r = append(c, params, 1);
  if (r == Result::Ok) position_ = end;
  return r;
}

Result PathBuilder::add_dwell(double seconds, const SegmentParams& params) noexcept {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return Result::InvalidSegment;
  if (!can_accept()) return Result::QueueFull;
  flush_merge();
  if (next_seq_ > first_unfinal_ && held(next_seq_ - 1).junction == Junction::Unknown) {
    Held& h = held(next_seq_ - 1);
    h.junction = Junction::Stop;
    h.dwell = seconds;
    h.dwell_inputs = 1;
    finalize(false);
    return Result::Ok;
  }
  const Result r = append_point(params);
  if (r != Result::Ok) return r;
  Held& h = held(next_seq_ - 1);
  h.junction = Junction::Stop;
  h.dwell = seconds;
  h.dwell_inputs = 1;
  h.inputs = 0;
  finalize(false);
  return Result::Ok;
}

void PathBuilder::flush() noexcept {
  flush_merge();
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
  return append(c, p, 0);
}

Result PathBuilder::append(const Curve& curve, const SegmentParams& params, uint32_t inputs) noexcept {
  if (!store_.segs.has_room()) return Result::QueueFull;
  const uint64_t seq = next_seq_;
  SegmentRecord& out = store_.segs.push_slot();
  out.curve = curve;
  out.s0 = s_end_;
  out.type = params.type;
  out.line = params.line;
  out.id = params.id;
  out.epoch = epoch_;
  store_.segs.publish();
  Held& h = held(seq);
  h = Held{};
  h.rec = out;
  h.params = params;
  h.inputs = inputs;
  next_seq_ = seq + 1;
  s_end_ += curve.length;
  if (seq > first_unfinal_) {
    Held& prev = held(seq - 1);
    if (prev.junction == Junction::Unknown) compute_junction(seq - 1);
  }
  // Keep only the history the windows can still reach.
  while (first_seq_ + static_cast<uint64_t>(span_) + 2 < first_unfinal_) ++first_seq_;
  finalize(false);
  return Result::Ok;
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
  a.junction = Junction::Window;
  a.vx = Vertex{};
  a.vx.s = b.rec.s0;
  a.vx.dt = dt;
  a.vx.curved = a.rec.curve.is_curved() || b.rec.curve.is_curved();
  a.vx.seg_in = j;
  a.vx.epoch = epoch_;
  a.c1 = kernel::kDeviationPerHalfWidth * ndt;
  a.c2 = 0;
  if (a.vx.curved) {
    AxisVec m2{};
    for (std::size_t k = 0; k < m2.size(); ++k) m2[k] = a.rec.curve.bound2[k] + b.rec.curve.bound2[k];
    a.c2 = 0.25 * norm(m2);
  }
  a.d0 = -1;
  a.final = false;
}

double PathBuilder::tolerance_of(uint64_t seq) const noexcept {
  const double t = held(seq).params.tolerance;
  return t > 0 ? t : kInf;
}

// Two segments lie in one run when no stop separates them.
bool PathBuilder::same_run(uint64_t a, uint64_t b) const noexcept {
  for (uint64_t k = std::min(a, b); k < std::max(a, b); ++k) {
    if (held(k).junction == Junction::Stop || held(k).junction == Junction::Unknown) return false;
  }
  return true;
}

double PathBuilder::initial_half(uint64_t j) noexcept {
  Held& h = held(j);
  if (h.d0 >= 0) return h.d0;
  const uint64_t span = static_cast<uint64_t>(span_);
  // The corner's own G64 P bounds its window (LinuxCNC: the termination of
  // the move that ends at the corner decides how the corner is blended).
  const double tol = tolerance_of(j);
  // Geometric room: at most `span` segments back and forward, within the
  // run, and beyond the two neighbours only over moves whose tolerance is
  // not tighter than this corner's.
  double back = 0;
  for (uint64_t k = j;; --k) {
    back += held(k).rec.curve.length;
    if (k == first_seq_ || k + span <= j + 1) break;
    const Held& prev = held(k - 1);
    if (prev.junction == Junction::Stop || prev.junction == Junction::Unknown) break;
    if (tolerance_of(k - 1) < tol) break;
  }
  double fwd = 0;
  for (uint64_t k = j + 1; k < next_seq_; ++k) {
    fwd += held(k).rec.curve.length;
    if (k >= j + span) break;
    const Junction jk = held(k).junction;
    if (jk == Junction::Stop || jk == Junction::Unknown) break;
    if (k + 1 < next_seq_ && tolerance_of(k + 1) < tol) break;
  }
  double d = std::min({back, fwd, cfg_.max_blend_half_width > 0 ? cfg_.max_blend_half_width : kInf});
  if (!(tol < kInf)) {
    // G64 without P: as large as the two moves allow, like LinuxCNC's blends.
    d = std::min({d, 0.5 * held(j).rec.curve.length, 0.5 * held(j + 1).rec.curve.length});
  }
  d = std::min(d, solve_half(h.c1, h.c2, tol));
  // Dense corners (CAM polylines): share the budget with the windows nearby.
  for (int pass = 0; pass < 3 && tol < kInf; ++pass) {
    double s1 = 0, s2 = 0;
    const uint64_t lo = j >= first_seq_ + 2 * span ? j - 2 * span : first_seq_;
    const uint64_t hi = std::min(j + 2 * span, next_seq_ - 1);
    for (uint64_t i = lo; i < hi; ++i) {
      const Held& o = held(i);
      if (o.junction != Junction::Window || std::fabs(o.vx.s - h.vx.s) >= 2 * d) continue;
      if (i != j && !same_run(i, j)) continue;
      s1 += o.c1;
      s2 += o.c2;
    }
    const double dn = solve_half(s1, s2, tol);
    if (dn >= d) break;
    d = dn;
  }
  if (!std::isfinite(d)) d = 0;
  h.d0 = d;
  h.w0 = h.c1 * d + h.c2 * d * d;
  h.tol = tol;
  return d;
}

void PathBuilder::final_half(uint64_t j) noexcept {
  Held& h = held(j);
  if (h.final) return;
  h.final = true;
  if (h.junction != Junction::Window) {
    h.vx.half = 0;
    return;
  }
  const double dj = initial_half(j);
  double cover = 0;
  const uint64_t span = static_cast<uint64_t>(span_);
  const uint64_t lo = j >= first_seq_ + 2 * span ? j - 2 * span : first_seq_;
  const uint64_t hi = std::min(j + 2 * span + 1, next_seq_ - 1);
  for (uint64_t i = lo; i < hi; ++i) {
    const Held& o = held(i);
    if (o.junction != Junction::Window) continue;
    if (i != j && !same_run(i, j)) continue;
    const double di = i == j ? dj : initial_half(i);
    if (std::fabs(o.vx.s - h.vx.s) < di + dj) cover += o.w0;
  }
  const double f = cover > h.tol ? h.tol / cover : 1.0;
  // Never sharp: a corner squeezed by its neighbours keeps a tiny window
  // (passed at a crawl, in a negligible time) rather than a kink.
  h.vx.half = std::max(dj * f * 0.999, 1e-9);
}

bool PathBuilder::ready(uint64_t m) const noexcept {
  const uint64_t need = m + 5 * static_cast<uint64_t>(span_) + 1;
  for (uint64_t k = m; k < next_seq_ && k <= need; ++k) {
    const Junction jk = held(k).junction;
    if (jk == Junction::Stop) return true;
    if (jk == Junction::Unknown) return false;
  }
  return next_seq_ > need;
}

bool PathBuilder::emit_vertices_upto(uint64_t j) noexcept {
  while (vertices_out_ <= j) {
    if (!store_.verts.has_room()) return false;
    const uint64_t k = vertices_out_;
    Vertex& out = store_.verts.push_slot();
    if (k >= first_seq_ && k < next_seq_ && held(k).junction == Junction::Window) {
      final_half(k);
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

void PathBuilder::finalize(bool flushing) noexcept {
  bool any = false;
  while (first_unfinal_ < next_seq_) {
    const uint64_t m = first_unfinal_;
    if (!flushing && !ready(m)) break;
    // Vertices whose windows may reach into m, up to the end of the run.
    uint64_t last = m;
    for (uint64_t k = m; k < next_seq_ && k < m + static_cast<uint64_t>(span_); ++k) {
      last = k;
      const Junction jk = held(k).junction;
      if (jk == Junction::Stop || jk == Junction::Unknown) break;
    }
    if (!store_.pieces.has_room(8)) break;
    if (!emit_vertices_upto(last)) break;
    if (!emit_pieces(m)) break;
    ++first_unfinal_;
    ++built_;
    any = true;
    while (first_seq_ + static_cast<uint64_t>(span_) + 2 < first_unfinal_) ++first_seq_;
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
  double cuts[8];
  int nc = 0;
  cuts[nc++] = 0;
  if (len > 0) {
    if (m > first_seq_ && held(m - 1).junction == Junction::Window) {
      const double d = held(m - 1).vx.half;
      if (d > 0) {
        cuts[nc++] = 0.5 * d;
        cuts[nc++] = d;
      }
    }
    if (h.junction == Junction::Window && h.vx.half > 0) {
      cuts[nc++] = len - h.vx.half;
      cuts[nc++] = len - 0.5 * h.vx.half;
    }
  }
  cuts[nc++] = len;
  std::sort(cuts, cuts + nc);
  double pts[8];
  int np = 0;
  const double gap = 1e-9 * std::max(1.0, len);
  for (int i = 0; i < nc; ++i) {
    const double c = std::clamp(cuts[i], 0.0, len);
    if (np == 0 || c - pts[np - 1] > gap) pts[np++] = c;
  }
  if (np >= 2) pts[np - 1] = len;
  const int pieces = len > 0 ? np - 1 : 0;
  for (int p = 0; p < pieces; ++p) {
    const double a = pts[p];
    const double b = pts[p + 1];
    const double ga = h.rec.s0 + a;
    const double gb = h.rec.s0 + b;
    Piece pc;
    pc.s0 = ga;
    pc.length = b - a;
    pc.seg = m;
    pc.epoch = epoch_;
    pc.probe = h.params.type == MotionType::Probe;
    AxisVec b1 = curve.bound1;
    AxisVec b2 = curve.bound2;
    AxisVec b3 = curve.bound3;
    uint64_t tlo = m, thi = m;
    bool any = false;
    for (uint64_t i = vlo; i < vhi; ++i) {
      const Held& o = held(i);
      if (o.junction != Junction::Window || !(o.vx.half > 0)) continue;
      if (gb <= o.vx.s - o.vx.half || ga >= o.vx.s + o.vx.half) continue;
      if (!any) tlo = i;
      thi = i + 1;
      any = true;
      add_correction_bounds(o.vx, ga - o.vx.s, gb - o.vx.s, held(i).rec.curve, held(i + 1).rec.curve, b1, b2, b3);
    }
    pc.v_lo = tlo;
    pc.v_hi = thi;
    // First derivative: analytic on a bare curve, else sampled plus the
    // Lipschitz margin from the second-derivative bound.
    AxisVec c1 = curve.bound1;
    double speed_max = 1;
    const double gn = group_norm(b2, curve.group);
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
          const double m = std::hypot(curve.u[k], curve.v[k]);
          c1[k] = std::min(b1[k], tang * m + std::fabs(curve.dh * curve.n[k]));
        }
        d1[k] = k < 3 ? 0.0 : curve.rate[k];
      }
      // The helix part always belongs to the XYZ group; other groups' rates
      // are constant.
      speed_max = curve.group == LengthGroup::Xyz ? std::hypot(tang, curve.dh) : group_norm(d1, curve.group);
    } else if (curve.kind == CurveKind::Helix || any) {
      speed_max = 0;
      AxisVec sampled{};
      const double xs[3] = {a, 0.5 * (a + b), b};
      for (double x : xs) {
        AxisVec pos, d1;
        curve.eval(x, pos, &d1);
        for (uint64_t i = tlo; i < thi; ++i) {
          const Held& o = held(i);
          if (o.junction != Junction::Window || !(o.vx.half > 0)) continue;
          const double dx = h.rec.s0 + x - o.vx.s;
          if (std::fabs(dx) >= o.vx.half) continue;
          add_correction(o.vx, dx, m > i, held(i).rec.curve, held(i + 1).rec.curve, pos, &d1, nullptr, nullptr);
        }
        for (std::size_t k = 0; k < d1.size(); ++k) sampled[k] = std::max(sampled[k], std::fabs(d1[k]));
        speed_max = std::max(speed_max, group_norm(d1, curve.group));
      }
      const double margin = 0.25 * (b - a);
      for (std::size_t k = 0; k < c1.size(); ++k) c1[k] = std::min(b1[k], sampled[k] + b2[k] * margin);
      speed_max = std::min(speed_max + gn * margin, group_norm(b1, curve.group));
    }
    const PieceLimits lim = derive_limits(c1, b2, b3, cfg_);
    pc.v_hard = lim.velocity;
    pc.accel = lim.accel;
    pc.jerk = lim.jerk;
    pc.barrier = lim.barrier;
    speed_max = std::max(speed_max, 1e-9);
    pc.inv_speed = 1.0 / speed_max;
    // Feeds and caps of this move and of the moves whose corners reach here.
    auto apply = [&](const SegmentParams& sp) {
      if (sp.max_velocity > 0) pc.v_hard = std::min(pc.v_hard, sp.max_velocity / speed_max);
      if (sp.max_acceleration > 0) pc.accel = std::min(pc.accel, sp.max_acceleration / speed_max);
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
    store_.pieces.push_slot() = pc;
  }
  if (h.junction == Junction::Stop || pieces == 0) {
    Piece st;
    st.s0 = h.rec.s0 + len;
    st.length = 0;
    st.seg = m;
    st.v_lo = st.v_hi = m;
    st.v_hard = 0;
    st.v_feed = st.v_rapid = kInf;
    st.accel = kInf;  // zero length: never limits a motion
    st.jerk = kInf;
    st.barrier = true;
    st.epoch = epoch_;
    st.stop = h.dwell_inputs > 0 ? StopKind::Dwell : StopKind::Stop;
    st.dwell_s = h.dwell;
    st.inputs_done = h.dwell_inputs + (pieces == 0 ? h.inputs : 0);
    store_.pieces.push_slot() = st;
  }
  return true;
}

}  // namespace cnc::tp
