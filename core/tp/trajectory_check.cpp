#include "core/tp/trajectory_check.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "core/tp/lookahead_planner.hpp"
#include "core/tp/path_builder.hpp"

namespace cnc::tp {
namespace {

double dist3(const AxisVec& a, const AxisVec& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

double dot3(const std::array<double, 3>& a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

Result queue_move(TrajectoryPlanner& planner, const Program& program, std::size_t i) {
  const ProgramMove& m = program.moves[i];
  SegmentParams p = m.params;
  p.id = static_cast<uint32_t>(i);
  switch (m.kind) {
    case ProgramMove::Kind::Line: return planner.add_line(m.end, p);
    case ProgramMove::Kind::Circle: return planner.add_circle(m.end, m.center, m.normal, m.turns, p);
    case ProgramMove::Kind::Dwell: return planner.add_dwell(m.seconds, p);
  }
  return Result::InvalidSegment;
}

StreamChecker::StreamChecker(const PlannerConfig& config, const Program& program, int search_span)
    : cfg_(config), program_(program), span_(search_span) {
  Pose pos = program.start;
  for (const ProgramMove& m : program.moves) {
    Curve c;
    bool ok = false;
    if (m.kind == ProgramMove::Kind::Line) ok = make_line(pos, m.end, 0, c);
    if (m.kind == ProgramMove::Kind::Circle) ok = make_helix(pos, m.end, m.center, m.normal, m.turns, 0, c);
    if (!ok) {
      c = Curve{};
      c.start = c.end = pos;
    } else {
      pos = m.end;
    }
    curves_.push_back(c);
    std::array<double, 6> box{kInf, kInf, kInf, -kInf, -kInf, -kInf};
    constexpr int kBoxSamples = 256;
    for (int k = 0; k <= kBoxSamples; ++k) {
      AxisVec pt = c.start.v;
      if (c.length > 0) c.eval(c.length * k / kBoxSamples, pt);
      for (int a = 0; a < 3; ++a) {
        box[static_cast<std::size_t>(a)] = std::min(box[static_cast<std::size_t>(a)], pt[static_cast<std::size_t>(a)]);
        box[static_cast<std::size_t>(a + 3)] = std::max(box[static_cast<std::size_t>(a + 3)], pt[static_cast<std::size_t>(a)]);
      }
    }
    // Every point of the curve is within half a sample step (arc length) of
    // a sample.
    const double pad = 0.5 * c.length / kBoxSamples + 1e-12;
    for (int a = 0; a < 3; ++a) {
      box[static_cast<std::size_t>(a)] -= pad;
      box[static_cast<std::size_t>(a + 3)] += pad;
    }
    box_.push_back(box);
    const SegmentParams& p = m.params;
    double t = 1e-6;  // exact path: only rounding
    if (p.term == TermCond::Blend) t = p.tolerance > 0 ? p.tolerance : kInf;
    tol_.push_back(t);
  }
  for (int i = 0; i < 3; ++i) hist_[i] = program.start;
  nhist_ = 3;
}

double StreamChecker::distance_to_move(const Pose& p, std::size_t i) const {
  const Curve& c = curves_[i];
  if (c.length <= 0) return dist3(p.v, c.start.v);
  if (c.kind == CurveKind::Line) {
    double ab2 = 0, t = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = c.end[k] - c.start[k];
      ab2 += d * d;
      t += (p[k] - c.start[k]) * d;
    }
    t = ab2 > 0 ? std::clamp(t / ab2, 0.0, 1.0) : 0.0;
    double r = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = p[k] - (c.start[k] + t * (c.end[k] - c.start[k]));
      r += d * d;
    }
    return std::sqrt(r);
  }
  const double theta = c.omega * c.length;
  double q[3] = {p[0] - c.center[0], p[1] - c.center[1], p[2] - c.center[2]};
  if (c.dr == 0 && c.dh == 0) {
    // Circular arc in a plane: closed form.
    const double h = dot3(c.n, q) - c.h0;
    const double x = dot3(c.u, q);
    const double y = dot3(c.v, q);
    double phi = std::atan2(y, x);
    if (phi < 0) phi += 2 * std::numbers::pi;
    if (theta >= 2 * std::numbers::pi - 1e-12 || phi <= theta) {
      return std::hypot(std::hypot(x, y) - c.r0, h);
    }
    return std::min(dist3(p.v, c.start.v), dist3(p.v, c.end.v));
  }
  // Helix or spiral: sample, then refine every local minimum of the samples
  // by golden section. Refining only the nearest sample is not enough: turns
  // closer together than the sample step (a 1/3 mm pitch at radius 17 with
  // 0.85 mm between samples) put the nearest sample on the wrong turn, and
  // the distance then came out as about one pitch.
  const int n = std::max(32, static_cast<int>(theta / 0.05));
  const double step = c.length / n;
  std::vector<double> ds(static_cast<std::size_t>(n) + 1);
  AxisVec pt;
  double best = kInf;
  for (int k = 0; k <= n; ++k) {
    c.eval(step * k, pt);
    ds[static_cast<std::size_t>(k)] = dist3(p.v, pt);
    best = std::min(best, ds[static_cast<std::size_t>(k)]);
  }
  const double g = (std::sqrt(5.0) - 1) / 2;
  for (int k = 0; k <= n; ++k) {
    const double dk = ds[static_cast<std::size_t>(k)];
    const bool local_min = (k == 0 || dk <= ds[static_cast<std::size_t>(k - 1)]) &&
                           (k == n || dk <= ds[static_cast<std::size_t>(k + 1)]);
    // Every point within one step of sample k lies within half a step (arc
    // length) of sample k-1, k or k+1: a basin whose samples are all more
    // than half a step farther than the best found cannot hold the minimum.
    if (!local_min || dk - 0.5 * step >= best) continue;
    double lo = step * std::max(0, k - 1);
    double hi = step * std::min(n, k + 1);
    for (int it = 0; it < 60; ++it) {
      const double m1 = hi - g * (hi - lo);
      const double m2 = lo + g * (hi - lo);
      AxisVec p1, p2;
      c.eval(m1, p1);
      c.eval(m2, p2);
      if (dist3(p.v, p1) < dist3(p.v, p2)) {
        hi = m2;
      } else {
        lo = m1;
      }
    }
    c.eval(0.5 * (lo + hi), pt);
    best = std::min(best, dist3(p.v, pt));
  }
  return best;
}

void StreamChecker::add(const CycleOutputs& out, double feed_scale) {
  const double T = cfg_.cycle_time_s;
  const Pose& p = out.position;
  ++st_.samples;
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const double v = (p[i] - hist_[0][i]) / T;
    const double a = (p[i] - 2 * hist_[0][i] + hist_[1][i]) / (T * T);
    const double j = (p[i] - 3 * hist_[0][i] + 3 * hist_[1][i] - hist_[2][i]) / (T * T * T);
    st_.max_v[k] = std::max(st_.max_v[k], std::fabs(v));
    st_.max_a[k] = std::max(st_.max_a[k], std::fabs(a));
    st_.max_j[k] = std::max(st_.max_j[k], std::fabs(j));
    if (!(cfg_.axis_mask & (1u << i))) continue;
    const AxisLimits& l = cfg_.axes[k];
    st_.ratio_v = std::max(st_.ratio_v, std::fabs(v) / l.max_velocity);
    st_.ratio_a = std::max(st_.ratio_a, std::fabs(a) / l.max_acceleration);
    st_.ratio_j = std::max(st_.ratio_j, std::fabs(j) / l.max_jerk);
  }
  const std::size_t n = program_.moves.size();
  if (n > 0) {
    const std::size_t id = std::min<std::size_t>(out.id, n - 1);
    const std::size_t lo = id > static_cast<std::size_t>(span_) ? id - static_cast<std::size_t>(span_) : 0;
    const std::size_t hi = std::min(n, id + static_cast<std::size_t>(span_) + 1);
    double d = kInf;
    // Nearest moves first: later ones are then mostly skipped by their box.
    for (std::size_t r = 0; r < 2 * (hi - lo); ++r) {
      const std::size_t off = (r + 1) / 2;
      if (r % 2 == 1 ? id + off >= hi : id < lo + off) continue;
      const std::size_t i = r % 2 == 1 ? id + off : id - off;
      const std::array<double, 6>& b = box_[i];
      double lb2 = 0;
      for (int a = 0; a < 3; ++a) {
        const double x = p[a];
        const double e = std::max({b[static_cast<std::size_t>(a)] - x, 0.0, x - b[static_cast<std::size_t>(a + 3)]});
        lb2 += e * e;
      }
      if (lb2 >= d * d) continue;  // cannot be nearer
      d = std::min(d, distance_to_move(p, i));
    }
    st_.max_deviation = std::max(st_.max_deviation, d);
    // Corners blend with the tolerance of the move that ends there and their
    // windows may reach over neighbouring moves: the largest nearby applies.
    double allowed = 0;
    for (std::size_t i = lo; i < hi; ++i) allowed = std::max(allowed, tol_[i] == 1e-6 ? 0.0 : tol_[i]);
    if (allowed == 0) allowed = 1e-6;
    if (allowed < kInf) st_.deviation_ratio = std::max(st_.deviation_ratio, d / allowed);
    if (!out.done) {
      moving_time_ += T;
      const ProgramMove& m = program_.moves[id];
      const Curve& c = curves_[id];
      double f = m.params.feed;
      if (m.params.type != MotionType::Traverse && m.params.feed_override_allowed) f *= feed_scale;
      if (!(f > 0)) f = kInf;
      // What the axes allow along this move caps the feed that can be reached.
      for (int i = 0; i < 3; ++i) {
        const double r = c.kind == CurveKind::Line ? std::fabs(c.rate[static_cast<std::size_t>(i)]) : 1.0;
        if ((cfg_.axis_mask & (1u << i)) && r > 1e-12) f = std::min(f, cfg_.axes[static_cast<std::size_t>(i)].max_velocity / r);
      }
      if (cfg_.max_linear_velocity > 0) f = std::min(f, cfg_.max_linear_velocity);
      const double speed = dist3(p.v, hist_[0].v) / T;
      if (f < kInf && f > 0) {
        if (speed >= 0.99 * f) at_feed_time_ += T;
        feed_ratio_sum_ += T * std::min(1.0, speed / f);
      }
      st_.time_s += T;
    }
  }
  hist_[2] = hist_[1];
  hist_[1] = hist_[0];
  hist_[0] = p;
}

StreamStats StreamChecker::finish() const {
  StreamStats s = st_;
  s.at_feed_fraction = moving_time_ > 0 ? at_feed_time_ / moving_time_ : 0;
  s.mean_feed_ratio = moving_time_ > 0 ? feed_ratio_sum_ / moving_time_ : 0;
  Pose end = program_.start;
  for (const Curve& c : curves_) {
    if (c.length > 0) end = c.end;
  }
  double e = 0;
  for (int i = 0; i < kNumAxes; ++i) e = std::max(e, std::fabs(hist_[0][i] - end[i]));
  s.end_error = e;
  return s;
}

}  // namespace cnc::tp

namespace cnc::tp {
namespace {

// Thread CPU time: the planner's own work, without the preemption a shared
// machine adds to wall-clock time.
int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

RunResult run_program(TrajectoryPlanner& planner, const PlannerConfig& config, const Program& program,
                      const RunOptions& options) {
  RunResult r;
  // A chord merged from collinear moves (G64 Q) reports its last move's id
  // while the machine is anywhere along it: up to kMaxMergedMoves back.
  bool merges = false;
  for (const ProgramMove& m : program.moves) merges = merges || m.params.naive_cam_tolerance > 0;
  StreamChecker check(config, program, config.blend_span_segments + 4 + (merges ? kMaxMergedMoves : 0));
  const auto* la = dynamic_cast<const LookaheadPlanner*>(&planner);
  planner.set_position(program.start);
  std::size_t next = 0;
  bool flushed = false;
  double last_s = -kInf;
  if (options.measure_cpu) {
    r.cycle_ns.reserve(1 << 20);
    r.add_ns.reserve(program.moves.size());
  }
  CycleInputs in;
  CycleOutputs out;
  out.position = program.start;
  for (uint64_t cycle = 0; cycle < options.max_cycles; ++cycle) {
    if (options.before_cycle) options.before_cycle(cycle, planner, in);
    const bool starving = cycle >= options.starve_from_cycle && !r.starve_stopped;
    if (starving && cycle > options.starve_from_cycle && la && !la->executor().is_moving()) {
      r.starve_stopped = true;
      r.starve_stop_gap = la->executor().distance_to_tail();
    }
    for (int k = 0; !starving && k < options.moves_per_cycle && next < program.moves.size(); ++k) {
      const int64_t t0 = options.measure_cpu ? now_ns() : 0;
      const Result res = queue_move(planner, program, next);
      if (res == Result::QueueFull) break;
      if (options.measure_cpu) r.add_ns.push_back(static_cast<double>(now_ns() - t0));
      ++next;
    }
    if (options.flush_at_end && next == program.moves.size() && !flushed) {
      planner.flush();
      flushed = true;
    }
    const int64_t t0 = options.measure_cpu ? now_ns() : 0;
    planner.run_cycle(in, out);
    if (options.measure_cpu) r.cycle_ns.push_back(static_cast<double>(now_ns() - t0));
    ++r.cycles;
    check.add(out, in.feed_scale);
    if (options.after_cycle) options.after_cycle(r.cycles, out);
    if (la) {
      const Executor& e = la->executor();
      const double s = e.path_position();
      if (s < last_s - 1e-9) r.monotone = false;
      last_s = s;
      r.stop_margin = std::min(r.stop_margin, e.distance_to_tail() - e.stop_distance());
      r.servo_split += static_cast<uint64_t>(e.cycle_work().split);
    }
    if (next == program.moves.size() && out.done && planner.is_done()) {
      r.completed = true;
      break;
    }
  }
  if (la) r.overruns = la->executor().overruns();
  r.stats = check.finish();
  r.last = out;
  return r;
}

}  // namespace cnc::tp
