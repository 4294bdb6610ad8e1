#include "core/tp/executor.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::tp {
namespace {

constexpr int kMaxConstraints = 48;
constexpr int kBackwardBudget = 48;
// Distance slack, relative to 1 + distance: a new decision must keep a
// non-negative slack; following a brake already chosen may lose rounding.
constexpr double kStrict = 0.0;
constexpr double kLoose = 1e-7;
// A stop reached this close (units) is reached: brakes land on it up to rounding.
constexpr double kLanding = 1e-10;
constexpr double kVelEps = 1e-9;

}  // namespace

PathState Executor::Motion::at(double t) const noexcept {
  if (t <= switch_t) {
    PathState m = first.at(t);
    return m;
  }
  return second.at(t - switch_t);
}

Executor::Executor(const PlannerConfig& config, PathStore& store)
    : cfg_(config),
      floors_(limit_floors(config)),
      store_(store),
      tree_(store.pieces.capacity()) {}

void Executor::set_config(const PlannerConfig& config) noexcept {
  cfg_ = config;
  const LimitFloors f = limit_floors(config);
  // Pieces planned with the old limits keep the old floors.
  floors_.accel = std::min(floors_.accel, f.accel);
  floors_.jerk = std::min(floors_.jerk, f.jerk);
}

void Executor::set_position(const Pose& pose) noexcept {
  if (is_idle()) pose_ = pose;
}

bool Executor::is_idle() const noexcept { return cur_ == tail_ && v_ == 0 && a_ == 0 && !dwelling_; }

bool Executor::take_abort_done(uint32_t& epoch) noexcept {
  if (!abort_done_) return false;
  abort_done_ = false;
  epoch = epoch_;
  return true;
}

double Executor::path_position() const noexcept {
  return cur_ < tail_ ? piece(cur_).s0 + off_ : tail_s_;
}

double Executor::distance_to_tail() const noexcept { return tail_s_ - path_position(); }

// The limits that bind a stop are those of the stretch it covers (a line
// along one axis may brake at that axis's full acceleration, more than the
// floors), so the stretch is grown until it covers the distance it implies.
// A deceleration built up where the limits are higher is first eased with
// the jerk available here (approach_distance), as the executor itself does.
// Barriers (tight corners) are passed with a two-stage brake (their own
// small limits inside, the next pieces' beyond) that one set of limits does
// not describe: a stretch that reaches one is reported through
// `crosses_barrier` and its distance is only an upper bound.
double Executor::stop_distance(bool* crosses_barrier) const noexcept {
  if (crosses_barrier) *crosses_barrier = false;
  if (cur_ >= tail_ || (v_ == 0 && a_ == 0)) return 0;
  const double s = path_position();
  const PathState now{0, v_, a_};
  uint64_t end = cur_ + 1;
  double d = 0;
  for (int it = 0; it < 32; ++it) {
    double acc, jerk;
    limits_between(cur_, end, acc, jerk);
    const Constraint k{tail_s_ - s, 0, acc, jerk, tail_, kInf, true};
    d = approach_distance(now, 0, k);
    if (!(d < kInf)) break;
    // A brake that ends exactly on a boundary (a stop point) does not use
    // the limits beyond it.
    const uint64_t reach = std::min(tail_, piece_at(s + d - 1e-9 * (1 + d)) + 1);
    if (reach <= end) break;
    end = reach;
  }
  if (crosses_barrier) {
    for (uint64_t k = cur_; k < end && !*crosses_barrier; ++k) {
      *crosses_barrier = piece(k).barrier && piece(k).stop == StopKind::None;
    }
  }
  return d;
}

void Executor::pause() noexcept { hold_ = true; }

void Executor::resume() noexcept {
  if (aborting_) return;
  hold_ = false;
  step_active_ = false;
}

void Executor::step() noexcept {
  if (!hold_ || aborting_ || cur_ >= tail_) return;
  uint64_t k = cur_;
  while (k < tail_ && piece(k).length == 0) ++k;
  if (k >= tail_) {
    step_s_ = tail_s_;
  } else {
    const uint64_t m = piece(k).seg;
    while (k < tail_ && piece(k).seg == m) ++k;
    step_s_ = k < tail_ ? piece(k).s0 : tail_s_;
  }
  step_active_ = true;
  hold_ = false;
}

void Executor::abort() noexcept {
  aborting_ = true;
  step_active_ = false;
}

// ---------------------------------------------------------------------------
// Ring helpers (sequence ranges may wrap around the tree)

namespace {

template <class F>
void for_slots(uint64_t from, uint64_t to, std::size_t n, F&& f) {
  if (from >= to) return;
  const std::size_t a = static_cast<std::size_t>(from & (n - 1));
  const uint64_t len = to - from;
  if (a + len <= n) {
    f(a, static_cast<std::size_t>(a + len), from);
  } else {
    f(a, n, from);
    f(0, static_cast<std::size_t>(a + len - n), from + (n - a));
  }
}

}  // namespace

void Executor::limits_between(uint64_t from, uint64_t to, double& accel, double& jerk) const noexcept {
  accel = kInf;
  jerk = kInf;
  for_slots(from, to, tree_.size(), [&](std::size_t lo, std::size_t hi, uint64_t) {
    double a, j;
    tree_.range_limits(lo, hi, a, j);
    accel = std::min(accel, a);
    jerk = std::min(jerk, j);
  });
}

uint64_t Executor::piece_at(double s) const noexcept {
  if (cur_ >= tail_) return cur_;
  uint64_t lo = cur_, hi = tail_ - 1;
  while (lo < hi) {
    const uint64_t mid = lo + (hi - lo + 1) / 2;
    if (piece(mid).s0 <= s) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  return lo;
}

// ---------------------------------------------------------------------------
// Ingest and the backward pass over barriers

void Executor::ingest() noexcept {
  const uint64_t pub = store_.pieces.published();
  const uint64_t first_new = tail_;
  while (tail_ < pub) {
    const Piece& p = piece(tail_);
    if (p.epoch != epoch_) {
      // Planned before an abort: dropped.
      if (cur_ == tail_) ++cur_;
      ++tail_;
      store_.pieces.release_upto(cur_);
      continue;
    }
    if (cur_ == tail_) off_ = 0;
    tree_.set(slot(tail_), TreeLeaf{p.barrier ? 0.0 : p.v_hard, p.v_feed, p.v_rapid, p.inv_speed, p.accel, p.jerk,
                                    p.barrier, p.stop != StopKind::None});
    tail_s_ = p.s0 + p.length;
    ++tail_;
    bp_dirty_ = true;
  }
  // New barriers get a (conservative, end-of-queue limited) ceiling at once,
  // newest first; the backward pass relaxes them as the queue grows.
  for (uint64_t k = tail_; k > first_new;) {
    --k;
    if (!piece(k).barrier || piece(k).epoch != epoch_) continue;
    tree_.set_hard(slot(k), barrier_ceiling(k));
  }
}

double Executor::barrier_ceiling(uint64_t b) const noexcept {
  const Piece& bp = piece(b);
  if (bp.stop != StopKind::None || !(bp.v_hard > 0)) return 0;
  const double end_s = bp.s0 + bp.length;
  LimitTree::Query q;
  q.soft = false;
  q.x = bp.v_hard;
  double v_end = bp.v_hard;
  const double horizon = brake_distance(bp.v_hard, 0, 0, floors_.accel, floors_.jerk) + 1e-6;
  uint64_t k = b;
  bool closed = false;
  for (int it = 0; it < kMaxConstraints; ++it) {
    int64_t idx = -1;
    for_slots(k + 1, tail_, tree_.size(), [&](std::size_t lo, std::size_t hi, uint64_t base) {
      if (idx >= 0) return;
      const int64_t r = tree_.find_first(lo, hi, q);
      if (r >= 0) idx = static_cast<int64_t>(base + (static_cast<std::size_t>(r) - lo));
    });
    if (idx < 0) break;
    const uint64_t i = static_cast<uint64_t>(idx);
    const Piece& p = piece(i);
    const double d = p.s0 - end_s;
    if (d > horizon) {
      closed = true;
      break;
    }
    const double value = tree_.leaf(slot(i)).hard;
    if (value < v_end) {
      double acc, jerk;
      limits_between(b + 1, i, acc, jerk);
      v_end = std::min(v_end, (d <= 0 || !(acc < kInf)) ? value : max_entry_velocity(d, value, acc, jerk));
    }
    if (p.barrier) {
      closed = true;
      break;
    }
    q.x = std::min(q.x, value);
    k = i;
    if (it == kMaxConstraints - 1) v_end = 0;  // too many levels: be safe
  }
  if (!closed) {
    const double d = tail_s_ - end_s;
    if (d <= horizon) {
      double acc, jerk;
      limits_between(b + 1, tail_, acc, jerk);
      v_end = std::min(v_end, (d <= 0 || !(acc < kInf)) ? 0.0 : max_entry_velocity(d, 0, acc, jerk));
    }
  }
  return std::min(bp.v_hard, max_entry_velocity(bp.length, v_end, bp.accel, bp.jerk));
}

void Executor::backward_pass(int budget) noexcept {
  auto last_barrier_before = [&](uint64_t to) -> int64_t {
    int64_t found = -1;
    // Search the later slot range first.
    uint64_t from = cur_;
    if (to <= from) return -1;
    const std::size_t n = tree_.size();
    const std::size_t a = static_cast<std::size_t>(from & (n - 1));
    const uint64_t len = to - from;
    if (a + len <= n) {
      const int64_t r = tree_.find_last_barrier(a, static_cast<std::size_t>(a + len));
      if (r >= 0) found = static_cast<int64_t>(from + (static_cast<std::size_t>(r) - a));
    } else {
      const int64_t r2 = tree_.find_last_barrier(0, static_cast<std::size_t>(a + len - n));
      if (r2 >= 0) {
        found = static_cast<int64_t>(from + (n - a) + static_cast<std::size_t>(r2));
      } else {
        const int64_t r1 = tree_.find_last_barrier(a, n);
        if (r1 >= 0) found = static_cast<int64_t>(from + (static_cast<std::size_t>(r1) - a));
      }
    }
    return found;
  };
  if (bp_dirty_) {
    bp_dirty_ = false;
    bp_cursor_ = last_barrier_before(tail_);
  }
  while (budget-- > 0 && bp_cursor_ >= 0 && static_cast<uint64_t>(bp_cursor_) >= cur_) {
    const uint64_t b = static_cast<uint64_t>(bp_cursor_);
    const double nv = barrier_ceiling(b);
    const double old = tree_.leaf(slot(b)).hard;
    if (nv != old) tree_.set_hard(slot(b), nv);
    if (nv == old) {
      bp_cursor_ = -1;
      break;
    }
    bp_cursor_ = last_barrier_before(b);
  }
}

// ---------------------------------------------------------------------------
// Look-ahead walk and feasibility

int Executor::collect(double x, const LimitTree::Query& q0, Constraint* out, int max, double& boundary) const noexcept {
  const double s = path_position();
  boundary = kInf;
  const double T = cfg_.cycle_time_s;
  // Pieces before the first barrier keep the floors, except the one we are
  // in, which may itself be a barrier.
  const Piece& cp = piece(cur_);
  const double ha = std::min(floors_.accel, cp.accel);
  const double hj = std::min(floors_.jerk, cp.jerk);
  // Far enough to stop from the fastest state this step can reach, with
  // the acceleration it has now ramped out at the smallest jerk.
  const double a_up = std::max(a_, 0.0) + cp.jerk * T;  // at most, after this step
  const double v_up = v_ + std::max(a_, 0.0) * T + 0.5 * cp.jerk * T * T;
  const double horizon =
      std::max(brake_distance(x, 0, 0, ha, hj), brake_distance(v_up, a_up, 0, ha, hj)) + 2 * std::max(x, v_up) * T + 1e-6;
  LimitTree::Query q = q0;
  q.x = x;
  int n = 0;
  uint64_t k = cur_;
  bool closed = false;
  while (n < max - 2) {
    int64_t idx = -1;
    for_slots(k + 1, tail_, tree_.size(), [&](std::size_t lo, std::size_t hi, uint64_t base) {
      if (idx >= 0) return;
      const int64_t r = tree_.find_first(lo, hi, q);
      if (r >= 0) idx = static_cast<int64_t>(base + (static_cast<std::size_t>(r) - lo));
    });
    if (idx < 0) break;
    const uint64_t i = static_cast<uint64_t>(idx);
    const Piece& p = piece(i);
    const double d = p.s0 - s;
    if (d > horizon) {
      closed = true;
      break;
    }
    double acc, jerk;
    limits_between(cur_, i, acc, jerk);
    const double value = LimitTree::value(tree_.leaf(slot(i)), q);
    if (n == max - 3) {
      // Out of room: one conservative ceiling for the rest of the horizon.
      double rest = 0;
      if (tail_s_ - s > horizon) {
        const uint64_t end = piece_at(s + horizon) + 1;
        rest = kInf;
        for_slots(i, end, tree_.size(), [&](std::size_t lo, std::size_t hi, uint64_t) {
          rest = std::min(rest, tree_.range_value(lo, hi, q));
        });
        limits_between(cur_, end, acc, jerk);
      }
      out[n++] = {d, std::min(value, rest), acc, jerk, i, p.jerk, true};
      closed = true;
      break;
    }
    out[n++] = {d, value, acc, jerk, i, p.jerk, p.barrier};
    if (p.barrier) {
      boundary = d;
      closed = true;
      break;
    }
    q.x = std::min(q.x, value);
    k = i;
  }
  if (!closed && tail_s_ - s <= horizon) {
    double acc, jerk;
    limits_between(cur_, tail_, acc, jerk);
    out[n++] = {tail_s_ - s, 0, acc, jerk, tail_, kInf, true};
  }
  if (step_active_) {
    double acc, jerk;
    limits_between(cur_, piece_at(step_s_) + 1, acc, jerk);
    out[n++] = {step_s_ - s, 0, acc, jerk, tail_, kInf, true};
  }
  if (cp.barrier) boundary = std::min(boundary, cp.s0 + cp.length - s);
  if (cp.barrier && cp.length > 0) {
    // Inside a barrier the motion brakes with the barrier's own (small)
    // limits and leaves it with zero acceleration; beyond it the pieces'
    // own limits apply (the two-stage model the barrier ceilings use).
    const double to_end = cp.s0 + cp.length - s;
    double v_end = kInf;
    double j_after = kInf;
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Constraint& k = out[i];
      if (k.dist <= to_end + 1e-12) {
        out[m++] = k;
        continue;
      }
      double acc, jerk;
      limits_between(cur_ + 1, k.piece == tail_ ? tail_ : k.piece, acc, jerk);
      const double d = k.dist - to_end;
      v_end = std::min(v_end, acc < kInf ? max_entry_velocity(d, k.value, acc, jerk) : k.value);
      j_after = std::min({j_after, jerk, k.jerk_after});
    }
    n = m;
    if (v_end < kInf) out[n++] = {to_end, v_end, cp.accel, cp.jerk, cur_ + 1, j_after, true};
  }
  return n;
}

// Distance needed from `m` to meet ceiling `k`. A deceleration stronger
// than the approach allows (or too strong to ramp out with its jerk before
// the velocity reaches zero) was built up where the limits are higher: it is
// first eased with the jerk available here, then the approach's limits apply.
double Executor::approach_distance(const PathState& m, double moved, const Constraint& k) const noexcept {
  const bool over = m.a < -k.accel;
  const bool doomed = m.a < 0 && m.v - m.a * m.a / (2 * k.jerk) < 0;
  if (!(over || doomed) || !(jerk_now_ > k.jerk)) return brake_distance(m.v, m.a, k.value, k.accel, k.jerk);
  double jp = jerk_now_;
  PathState e = m;
  double pre = 0;
  for (int pass = 0; pass < 2; ++pass) {
    // Ease (with jerk jp) to a1, the strongest deceleration the approach
    // sustains: over the limit it is -A; a deceleration ramped out with the
    // approach's jerk must not end below zero velocity:
    //   v + (a1^2 - a^2) / 2jp - a1^2 / 2J' >= 0.
    const double room = m.v - m.a * m.a / (2 * jp);
    if (room < 0) return kInf;
    const double coef = 1 / (2 * k.jerk) - 1 / (2 * jp);
    double a1 = std::max(m.a, -k.accel);
    if (coef > 0) a1 = std::max(a1, -std::sqrt(room / coef) * 0.999);
    const double t = std::max(0.0, (a1 - m.a) / jp);
    e = integrate({0, m.v, m.a}, jp, t);
    if (e.v < 0) return kInf;
    pre = e.s;
    // The jerk that really is available over that stretch.
    double acc, jerk;
    limits_between(cur_, piece_at(path_position() + moved + pre) + 1, acc, jerk);
    if (!(jerk < jp)) break;
    jp = jerk;
    if (!(jp > k.jerk)) return brake_distance(m.v, m.a, k.value, k.accel, k.jerk);
  }
  if (e.v <= k.value && e.a <= 0) {
    // Crossed the ceiling while easing: distance to that crossing.
    return pre;
  }
  return pre + brake_distance(e.v, e.a, k.value, k.accel, k.jerk);
}

bool Executor::feasible(const PathState& m, double moved, const Constraint* c, int n, int* worst,
                        double tol) const noexcept {
  bool ok = true;
  double worst_slack = kInf;
  for (int i = 0; i < n; ++i) {
    const Constraint& k = c[i];
    const double d = k.dist - moved;
    // Still accelerating: the velocity peaks once the acceleration is ramped
    // out; if that happens past the point, with the jerk available there.
    double peak = m.v;
    double ramp = 0;
    if (m.a > 0) {
      ramp = integrate({0, m.v, m.a}, -k.jerk, m.a / k.jerk).s;
      peak = m.v + m.a * m.a / (2 * (ramp <= d ? k.jerk : std::min(k.jerk, k.jerk_after)));
    }
    double slack;
    if (k.tight && m.a > 1e-9 && ramp > d) {
      // Would still be accelerating at (or past) a point where braking may
      // have to begin.
      slack = d - ramp;
      if (d > 0 && slack >= -tol * (1 + d) && peak <= k.value + kVelEps) continue;
    } else if (peak <= k.value + kVelEps) {
      continue;
    } else if (d <= 0) {
      slack = d - 1;  // at or past the ceiling while above it
    } else {
      const double bd = std::max(approach_distance(m, moved, k), ramp);
      slack = d - bd;
      if (slack >= -tol * (1 + d)) continue;
    }
    ok = false;
    if (slack < worst_slack) {
      worst_slack = slack;
      if (worst) *worst = i;
    }
  }
  if (!ok || n < 2) return ok;
  // Each ceiling can be met on its own; one brake must meet them all.
  int needing = 0;
  for (int i = 0; i < n; ++i) {
    const double peak = m.a > 0 ? m.v + m.a * m.a / (2 * c[i].jerk) : m.v;
    if (peak > c[i].value + kVelEps) ++needing;
  }
  if (needing < 2) return true;
  JerkProfile p;
  const int j = find_brake(m, moved, c, n, -1, tol, p);
  if (j >= 0) return true;
  if (worst) *worst = j < -1 ? -2 - j : 0;
  return false;
}

bool Executor::motion_ok(const Motion& mo, const Constraint* c, int n, double T, double tol) const noexcept {
  const PathState end = mo.at(T);
  if (end.v < -kVelEps) return false;
  if (!feasible(end, end.s, c, n, nullptr, tol)) return false;
  // Ceilings crossed during the cycle: the velocity at the crossing.
  for (int i = 0; i < n; ++i) {
    if (!(c[i].dist > 0 && c[i].dist <= end.s)) continue;
    double lo = 0, hi = T;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (mo.at(mid).s < c[i].dist ? lo : hi) = mid;
    }
    if (mo.at(hi).v > c[i].value + kVelEps) return false;
  }
  return true;
}

double Executor::current_ceiling(const LimitTree::Query& q) const noexcept {
  if (cur_ >= tail_) return 0;
  return LimitTree::value(tree_.leaf(slot(cur_)), q);
}

void Executor::plan_cycle(const CycleInputs& in) noexcept {
  // A brake that lands on a ceiling before the end of the cycle is followed,
  // in the same cycle, by a new decision from the new place (what lies
  // beyond a barrier is only known once there).
  double left = cfg_.cycle_time_s;
  for (int it = 0; it < 16 && left > 1e-12 && cur_ < tail_; ++it) {
    if (v_ == 0 && a_ == 0 && piece(cur_).stop != StopKind::None) return;
    left -= plan_step(in, left, it < 15);
  }
}

double Executor::plan_step(const CycleInputs& in, double T, bool split) noexcept {
  LimitTree::Query q;
  q.feed_scale = std::max(0.0, in.feed_scale);
  q.rapid_scale = std::max(0.0, in.rapid_scale);
  q.max_velocity = in.max_velocity > 0 ? in.max_velocity : 0.0;
  q.soft = true;
  const double c_cur = current_ceiling(q);
  const double target = (hold_ || aborting_) ? 0.0 : c_cur;
  const double s = path_position();
  const Piece& cp = piece(cur_);
  // Limits for the free motion: acceleration over the distance needed to
  // bring it down, jerk over what this cycle can cover.
  const double ja = std::max(cp.jerk, 1e-9);
  const double aa = std::fabs(a_);
  const double ramp = (v_ + aa * aa / ja) * (aa / ja + 2 * T) + 1e-9;
  const double travel = v_ * T + std::max(a_, 0.0) * T * T * 0.5 + cp.jerk * T * T * T / 6 + 1e-9;
  // Never look past the next stop point: the motion ends there.
  uint64_t stop_at = tail_;
  for_slots(cur_ + 1, tail_, tree_.size(), [&](std::size_t lo, std::size_t hi, uint64_t base) {
    if (stop_at != tail_) return;
    const int64_t r = tree_.find_first_stop(lo, hi);
    if (r >= 0) stop_at = base + (static_cast<std::size_t>(r) - lo);
  });
  const double vpeak = a_ > 0 ? v_ + a_ * a_ / (2 * std::max(cp.jerk, 1e-9)) : v_;
  Constraint cs[kMaxConstraints];
  double boundary = kInf;
  const int n = collect(std::max(c_cur, vpeak), q, cs, kMaxConstraints, boundary);
  double acc_free, jerk_dummy, acc_dummy, jerk_free;
  limits_between(cur_, std::min(piece_at(s + ramp) + 1, stop_at), acc_free, jerk_dummy);
  // Jerk: over what this step can cover, but not past a barrier boundary
  // where the step is cut anyway.
  uint64_t jerk_end = std::min(piece_at(s + travel) + 1, stop_at);
  if (split && boundary < kInf) jerk_end = std::max(cur_ + 1, std::min(jerk_end, piece_at(s + boundary)));
  limits_between(cur_, jerk_end, acc_dummy, jerk_free);
  (void)jerk_dummy;
  (void)acc_dummy;
  jerk_now_ = jerk_free;
  // Where a barrier starts or the one we are in ends, the step ends: what
  // applies beyond is only known from there (its ceilings assume the
  // braking for what lies beyond starts right there).
  auto cut = [&](const Motion& mo, double t0) -> double {
    if (!split || !(boundary > 1e-12) || mo.at(T).s <= boundary) return -1;
    double lo = t0, hi = T;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      (mo.at(mid).s < boundary ? lo : hi) = mid;
    }
    active_ = false;
    advance(mo.at(hi));
    return std::max(hi, 1e-9);
  };

  // Follows a brake (`prof`, from `t0` in this step) toward the ceiling that
  // starts `dist` ahead. Once there, and if splitting is allowed, the step
  // ends: the next decision is made from that place.
  auto follow = [&](const Motion& mo, double t0, const JerkProfile& prof, double dist, double value) {
    const PathState end_state = mo.at(T);
    if (split && value <= 1e-9 && dist <= boundary) {
      // A brake to a stop ends at rest exactly where it stops.
      const double t_end = t0 + prof.total_time();
      if (t_end <= T) {
        active_ = false;
        PathState e = mo.at(t_end);
        if (std::fabs(e.s - dist) < 1e-9) e.s = dist;
        e.v = 0;
        e.a = 0;
        advance(e);
        return std::max(t_end, 1e-9);
      }
    }
    const double stop_at = std::min(dist, boundary);
    if (split && stop_at > 1e-12 && end_state.s >= stop_at) {
      // The first time this step's motion reaches the point (possibly
      // before the brake even started).
      double lo = 0, hi = T;
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (mo.at(mid).s < stop_at ? lo : hi) = mid;
      }
      active_ = false;
      advance(mo.at(hi));
      return std::max(hi, 1e-9);
    }
    active_ = true;
    brake_ = prof;
    brake_t_ = T - t0;
    brake_target_s_ = s + dist;
    brake_target_v_ = value;
    advance(end_state);
    return T;
  };

  const PathState st{0, v_, a_};
  Motion free;
  free.first = velocity_profile(st, target, acc_free, jerk_free);
  if (motion_ok(free, cs, n, T, kStrict)) {
    const double used = cut(free, 0);
    if (used >= 0) return used;
    active_ = false;
    advance(free.at(T));
    return T;
  }
  Motion base = free;
  if (active_) {
    // Re-base the brake so that it starts now at s = 0.
    const PathState now = brake_.at(brake_t_);
    JerkProfile shifted;
    shifted.start = {0, now.v, now.a};
    double t = brake_t_;
    for (std::size_t i = 0; i < 3; ++i) {
      shifted.duration[i] = std::max(0.0, brake_.duration[i] - t);
      t = std::max(0.0, t - brake_.duration[i]);
      shifted.jerk[i] = brake_.jerk[i];
    }
    Motion act;
    act.first = shifted;
    if (motion_ok(act, cs, n, T, kLoose)) return follow(act, 0, shifted, brake_target_s_ - s, brake_target_v_);
    base = act;
  }
  int worst = -1;
  if (!feasible(base.at(0), 0, cs, n, &worst, kLoose)) {
    // Already unable to meet a ceiling (an override dropped): brake as hard
    // as the limits allow toward the lowest ceiling that is failing.
    // Brake as hard as every failing ceiling's approach allows, toward the
    // lowest of them.
    int low = worst;
    double acc = kInf, jerk = kInf;
    for (int i = 0; i < n; ++i) {
      const double peak = a_ > 0 ? v_ + a_ * a_ / (2 * cs[i].jerk) : v_;
      if (peak <= cs[i].value) continue;
      if (cs[i].value < cs[low].value) low = i;
      acc = std::min(acc, cs[i].accel);
      jerk = std::min(jerk, cs[i].jerk);
    }
    if (!(acc < kInf)) {
      acc = cs[low].accel;
      jerk = cs[low].jerk;
    }
    Motion fb;
    fb.first = velocity_profile(st, std::min(brake_target(st, cs[low]), target), acc, jerk);
    return follow(fb, 0, fb.first, cs[low].dist, cs[low].value);
  }
  // Latest instant in this step from which the binding brake still fits.
  double lo = 0, hi = T;
  for (int it = 0; it < 48; ++it) {
    const double mid = 0.5 * (lo + hi);
    const PathState m = base.at(mid);
    int w2 = -1;
    if (feasible(m, m.s, cs, n, &w2, kStrict)) {
      lo = mid;
    } else {
      hi = mid;
      worst = w2;
    }
  }
  if (worst < 0) {
    const PathState m = base.at(hi);
    feasible(m, m.s, cs, n, &worst, kStrict);
  }
  const PathState sw = base.at(lo);
  double target_dist = 0;
  Motion mo = base;
  mo.switch_t = lo;
  double target_value = 0;
  mo.second = choose_brake(sw, cs, n, std::max(worst, 0), target_dist, target_value);
  return follow(mo, lo, mo.second, target_dist, target_value);
}

// The brake to follow from `sw`: the shortest brake toward one ceiling that
// also respects every other one (passing the nearer ones below their
// ceiling, and able to meet the farther ones after it ends); if no single
// one does, the hardest of them.
bool Executor::brake_valid(const JerkProfile& p, double moved, int j, const Constraint* c, int n,
                           double tol) const noexcept {
  const PathState end = p.end();
  for (int k = 0; k < n; ++k) {
    if (k == j) continue;
    const double dk = c[k].dist - moved;
    if (c[k].dist <= c[j].dist) {
      if (dk <= 0) continue;
      // Velocity where the brake passes the nearer ceiling.
      double v_at;
      if (end.s - moved <= dk) {
        v_at = end.v;
      } else {
        double lo = 0, hi = p.total_time();
        for (int it = 0; it < 50; ++it) {
          const double mid = 0.5 * (lo + hi);
          (p.at(mid).s - moved < dk ? lo : hi) = mid;
        }
        v_at = p.at(hi).v;
        if (c[k].tight && p.at(hi).a > 1e-9) return false;
      }
      if (v_at > c[k].value + kVelEps) return false;
    } else if (end.v > c[k].value) {
      // After the brake ends (zero acceleration) the farther ceiling must
      // still be reachable.
      const double room = c[k].dist - c[j].dist;
      if (brake_distance(end.v, 0, c[k].value, c[k].accel, c[k].jerk) > room + tol * (1 + room)) return false;
    }
  }
  return true;
}

int Executor::find_brake(const PathState& m, double moved, const Constraint* c, int n, int prefer, double tol,
                         JerkProfile& out) const noexcept {
  auto needs = [&](int j) {
    const double peak = m.a > 0 ? m.v + m.a * m.a / (2 * c[j].jerk) : m.v;
    return peak > c[j].value + kVelEps && c[j].dist - moved > 0;
  };
  auto attempt = [&](int j) {
    out = velocity_profile(m, brake_target(m, c[j]), c[j].accel, c[j].jerk);
    return brake_valid(out, moved, j, c, n, tol);
  };
  if (prefer >= 0 && prefer < n && attempt(prefer)) return prefer;
  // Lowest ceilings first: their brakes are the hardest.
  bool tried[kMaxConstraints] = {};
  if (prefer >= 0 && prefer < n) tried[prefer] = true;
  for (;;) {
    int best = -1;
    for (int j = 0; j < n; ++j) {
      if (!tried[j] && needs(j) && (best < 0 || c[j].value < c[best].value)) best = j;
    }
    if (best < 0) break;
    tried[best] = true;
    if (attempt(best)) return best;
  }
  // The hardest brake every approach allows, toward the lowest ceiling.
  int low = -1;
  double acc = kInf, jerk = kInf;
  for (int j = 0; j < n; ++j) {
    if (!needs(j)) continue;
    if (low < 0 || c[j].value < c[low].value) low = j;
    acc = std::min(acc, c[j].accel);
    jerk = std::min(jerk, c[j].jerk);
  }
  if (low < 0) return -1;
  out = velocity_profile(m, brake_target(m, c[low]), acc, jerk);
  return brake_valid(out, moved, low, c, n, tol) ? low : -2 - low;
}

// The velocity a brake for `k` aims at: its value, or, for a tight point
// approached while accelerating, the velocity reached by levelling off now
// if that is lower (the acceleration must be gone by the point).
double Executor::brake_target(const PathState& m, const Constraint& k) const noexcept {
  if (k.tight && m.a > 0) return std::min(k.value, m.v + m.a * m.a / (2 * k.jerk));
  return k.value;
}

JerkProfile Executor::choose_brake(const PathState& sw, const Constraint* c, int n, int binding,
                                   double& target_dist, double& target_value) const noexcept {
  JerkProfile p;
  int j = find_brake(sw, sw.s, c, n, binding, kLoose, p);
  if (j < -1) j = -2 - j;  // none is valid: the hardest one
  if (j < 0) {
    j = binding;
    p = velocity_profile(sw, brake_target(sw, c[j]), c[j].accel, c[j].jerk);
  }
  target_dist = c[j].dist;
  target_value = c[j].value;
  if (j >= 0 && p.end().v > target_value) target_value = p.end().v;
  return p;
}

// ---------------------------------------------------------------------------
// Moving along the pieces

void Executor::advance(const PathState& end) noexcept {
  v_ = end.v;
  a_ = end.a;
  if (std::fabs(v_) < 1e-10 && std::fabs(a_) < 1e-7) {
    v_ = 0;
    a_ = 0;
  }
  if (v_ < 0) v_ = 0;
  off_ += std::max(0.0, end.s);
  while (cur_ < tail_) {
    const Piece& p = piece(cur_);
    if (p.length == 0) break;
    const uint64_t nx = cur_ + 1;
    const bool must_stop = nx >= tail_ || piece(nx).stop != StopKind::None;
    // A brake that ends at a stop lands on it up to rounding: snap.
    if (must_stop && v_ == 0 && a_ == 0 && off_ < p.length && off_ > p.length - kLanding) off_ = p.length;
    // A brake that ends on a piece boundary lands on it up to rounding.
    if (!must_stop && off_ < p.length && off_ > p.length - 1e-12 * (1 + p.length)) off_ = p.length;
    if (off_ < p.length) break;
    if (must_stop) {
      if (off_ > p.length + 1e-6 || v_ > 1e-6) ++overruns_;
      if (off_ > p.length + 1e-9 || v_ > 1e-6) {
        v_ = 0;
        a_ = 0;
        active_ = false;
      }
      if (v_ > 0 || a_ != 0) {
        // Exactly at the end while still moving: stay until it stops.
        off_ = p.length;
        break;
      }
      eval(cur_, p.length, pose_, &speed_);
      completed_ += p.inputs_done;
      cur_ = nx;
      off_ = 0;
      break;
    }
    off_ -= p.length;
    completed_ += p.inputs_done;
    cur_ = nx;
  }
}

void Executor::handle_rest() noexcept {
  const double T = cfg_.cycle_time_s;
  if (!(v_ == 0 && a_ == 0)) return;
  if (aborting_) {
    finish_abort();
    return;
  }
  if (step_active_ && path_position() >= step_s_ - 1e-9) {
    step_active_ = false;
    hold_ = true;
  }
  while (cur_ < tail_ && !hold_) {
    const Piece& p = piece(cur_);
    if (p.stop == StopKind::None) break;
    if (p.stop == StopKind::Dwell) {
      if (!dwelling_) {
        dwelling_ = true;
        dwell_left_ = p.dwell_s;
      }
      if (dwell_left_ > 0.5 * T) {
        dwell_left_ -= T;
        return;
      }
      dwelling_ = false;
    }
    completed_ += p.inputs_done;
    ++cur_;
    off_ = 0;
  }
}

void Executor::reset(const Pose& pose) noexcept {
  finish_abort();
  v_ = 0;
  a_ = 0;
  pose_ = pose;
  speed_ = 0;
}

void Executor::finish_abort() noexcept {
  for (uint64_t k = cur_; k < tail_; ++k) tree_.clear(slot(k));
  cur_ = tail_;
  off_ = 0;
  store_.pieces.release_upto(cur_);
  store_.segs.release_upto(store_.segs.published());
  store_.verts.release_upto(store_.verts.published());
  ++epoch_;
  abort_done_ = true;
  aborting_ = false;
  hold_ = false;
  step_active_ = false;
  active_ = false;
  dwelling_ = false;
  bp_cursor_ = -1;
}

void Executor::eval(uint64_t seq, double offset, Pose& out, double* speed) const noexcept {
  const Piece& p = piece(seq);
  const SegmentRecord& sr = store_.segs.at(p.seg);
  AxisVec pos, d1;
  sr.curve.eval((p.s0 - sr.s0) + offset, pos, &d1);
  for (uint64_t j = p.v_lo; j < p.v_hi; ++j) {
    const Vertex& vx = store_.verts.at(j);
    if (!(vx.half > 0)) continue;
    const double x = (p.s0 - vx.s) + offset;
    if (std::fabs(x) >= vx.half) continue;
    add_correction(vx, x, p.seg > vx.seg_in, store_.segs.at(vx.seg_in).curve, store_.segs.at(vx.seg_in + 1).curve, pos,
                   &d1, nullptr, nullptr);
  }
  out.v = pos;
  if (speed) *speed = group_norm(d1, sr.curve.group);
}

bool Executor::evaluate_at(double s, Pose& out) const noexcept {
  if (cur_ >= tail_) return false;
  const uint64_t k = piece_at(s);
  const Piece& p = piece(k);
  if (s < p.s0 - 1e-9 || s > p.s0 + p.length + 1e-9) return false;
  eval(k, std::clamp(s - p.s0, 0.0, p.length), out, nullptr);
  return true;
}

void Executor::run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept {
  ingest();
  backward_pass(kBackwardBudget);
  if (!probe_tripped_ && in.probe_input && cur_ < tail_ && piece(cur_).probe && !aborting_) {
    probe_tripped_ = true;
    probed_ = pose_;
    aborting_ = true;
  }
  handle_rest();
  const bool at_rest = v_ == 0 && a_ == 0;
  if (cur_ < tail_ && !dwelling_) {
    const bool blocked = at_rest && (hold_ || aborting_ || piece(cur_).stop != StopKind::None);
    if (!blocked) plan_cycle(in);
  }
  if (cur_ < tail_) eval(cur_, off_, pose_, &speed_);
  // Release what is behind.
  for (uint64_t k = store_.pieces.released(); k < cur_; ++k) tree_.clear(slot(k));
  store_.pieces.release_upto(cur_);
  if (cur_ < tail_) {
    const Piece& p = piece(cur_);
    const uint64_t keep = std::min(p.seg, p.v_lo);
    store_.segs.release_upto(keep);
    store_.verts.release_upto(keep);
  }
  out.position = pose_;
  out.path_velocity = v_ * (cur_ < tail_ ? speed_ : 0.0);
  out.path_acceleration = a_;
  if (cur_ < tail_) {
    const Piece& p = piece(cur_);
    const SegmentRecord& sr = store_.segs.at(p.seg);
    out.line = sr.line;
    out.id = sr.id;
    out.distance_to_go = std::max(0.0, sr.s0 + sr.curve.length - (p.s0 + off_));
    out.move_end = sr.curve.end;
  } else {
    out.distance_to_go = 0;
    out.move_end = pose_;
  }
  out.done = is_idle();
  out.probe_tripped = probe_tripped_;
  if (probe_tripped_) out.probed_position = probed_;
}

}  // namespace cnc::tp
