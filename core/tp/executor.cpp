#include "core/tp/executor.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::tp {
namespace {

constexpr int kMaxRows = kNumAxes + 1;
// Longest averaging window the history rings hold (samples).
constexpr int kMaxFilter = 8192;
// A power of two (indices wrap by masking).
constexpr int kRing = 16384;
static_assert(kRing >= kMaxFilter + 2 && (kRing & (kRing - 1)) == 0);
// Velocities at which each piece's acceleration limit is tabulated.
constexpr int kGrid = 16;
// Tree channels: the limit at each grid velocity, then ceiling, feed, rapid.
constexpr int kChannels = kGrid + 3;
constexpr int kChV = kGrid, kChFeed = kGrid + 1, kChRapid = kGrid + 2;
// Parts of a span with their own braking acceleration in the envelope.
constexpr int kChunks = 4;
// A piece becomes at most this many spans.
constexpr int kSpansPerPiece = 24;
// Ceilings are rounded down to steps of this (logarithmic) size.
constexpr double kCeilingStep = 0.00995;  // ln 1.01
// Short pieces with equal caps are joined into spans up to this long.
constexpr double kMergeSpan = 0.5;
// Erosion boundaries considered inside one piece.
constexpr int kMaxCuts = 96;
// A stop closer than this is reached (units).
constexpr double kLanding = 1e-9;
// A gap to a stop at least this small is closed from rest in one step (at
// 250 us an acceleration of 0.16 units/s^2, far below any limit).
constexpr double kCreep = 1e-8;
constexpr double kVelEps = 1e-12;
// Slack on the envelope for what counts as an overrun, as a distance: the
// positions' rounding moves a brake that follows the envelope off it, and
// such a brake keeps v^2 - W^2 (not v - W) nearly constant, so the slack
// is on the squares: 2 a_top kEnvTol.
constexpr double kEnvTol = 1e-9;

}  // namespace

// The limit rows: every axis in the mask, then the XYZ norm when [TRAJ]
// linear limits are set. Acceleration and jerk include kLimitMargin.
struct Executor::Rows {
  int n = 0;
  int axis[kMaxRows] = {};  // axis index, -1 for the XYZ norm
  double a[kMaxRows] = {};
  double j[kMaxRows] = {};
};

// What a piece's limit table depends on, from the configuration alone:
// the limit rows, the averaging time, the generous bounds and the grid.
// The servo side and the producer each hold one; `gen` says which
// configuration it was made from.
struct Executor::Limits {
  Rows rows;
  std::array<double, kGrid> grid{};
  double tf = 0, v_bound = 0, a_top = 0;
  double T = 0;  // servo period
  int n = 1;  // samples averaged
  uint64_t gen = 0;
};

// A piece's limit table: the tree leaf (the limit at each grid velocity,
// ceiling, feed, rapid) and its ceiling, for configuration `gen`.
struct Executor::PieceLimits {
  double vals[kChannels] = {};
  double v = 0;
  uint64_t gen = UINT64_MAX;
};

// Per ingested piece: its ceiling (capped at v_bound_), and a compact
// copy of where it lies, whether it is a stop and its epoch: the range
// searches and the span splitting walk many neighbouring pieces, and a
// Piece (its derivative bounds per axis) spans several cache lines.
struct Executor::PieceData {
  double v = 0;
  double s0 = 0, end = 0;  // [s0, end] on the path parameter
  uint32_t epoch = 0;
  bool stop = false;
};

// Range minima over the pieces of the ring (segment tree over ring slots):
// the acceleration limit at each grid velocity, the ceiling, feed and rapid.
// Node-major: the envelope's queries for one span ask the same few nodes
// for different grid channels (one tree per channel was tried: 20 % more
// time per cycle).
struct Executor::Tree {
  std::size_t n = 0;  // leaves, a power of two
  std::unique_ptr<double[]> val;  // (2 n) x kChannels
  double* node(std::size_t i) noexcept { return &val[i * kChannels]; }
  const double* node(std::size_t i) const noexcept { return &val[i * kChannels]; }
  // A leaf's values; its ancestors follow with update().
  void set_leaf(std::size_t leaf, const double* v) noexcept {
    double* d = node(n + leaf);
    for (int c = 0; c < kChannels; ++c) d[c] = v[c];
  }
  // The ancestors of leaves [lo, hi) (hi <= n), level by level: about
  // hi - lo + log n nodes, where one update per leaf took log n each.
  void update(std::size_t lo, std::size_t hi) noexcept {
    if (hi <= lo) return;
    for (std::size_t i = (n + lo) / 2, j = (n + hi - 1) / 2; i >= 1; i /= 2, j /= 2) {
      for (std::size_t m = i; m <= j; ++m) {
        const double* l = node(2 * m);
        const double* r = node(2 * m + 1);
        double* d = node(m);
        for (int c = 0; c < kChannels; ++c) d[c] = std::min(l[c], r[c]);
      }
      if (i == 1) break;
    }
  }
  // Minimum of channel c over leaves [lo, hi).
  double query(std::size_t lo, std::size_t hi, int c) const noexcept {
    double m = kInf;
    for (lo += n, hi += n; lo < hi; lo /= 2, hi /= 2) {
      if (lo & 1) m = std::min(m, node(lo++)[c]);
      if (hi & 1) m = std::min(m, node(--hi)[c]);
    }
    return m;
  }
};

// A range minimum resolved: its value, and the stretches of the range's
// ends over which it resolves to the same pieces ([lo0, lo1) for lo,
// [hi0, hi1) for hi). No member initialisers: RangeMemo holds one per
// channel and marks which are set.
struct Executor::RangeStretch {
  double lo0, lo1, hi0, hi1, val;
  // Whether the range [lo, hi] resolves to the same pieces as this one.
  bool covers(double lo, double hi) const noexcept { return lo >= lo0 && lo < lo1 && hi >= hi0 && hi < hi1; }
};

// The last two range minima asked of each tree channel around piece
// `from` (one envelope span's queries; `valid` has bit c set once channel
// c's are), newest first. Two: the bisection over the braking
// acceleration alternates between ranges reaching back to two pieces on
// the same channel, and one entry a channel missed on 23 % of the queries
// on a dense spiral (4 % with two).
struct Executor::RangeMemo {
  static constexpr int kWays = 2;
  uint64_t from = 0;
  uint32_t valid = 0;
  std::array<std::array<RangeStretch, kWays>, kChannels> e;
  // The entry that answered last and the velocities (v0, v1] whose grid
  // channel is its channel: asked first, without the grid search.
  const RangeStretch* last = nullptr;
  double v0 = 0, v1 = 0;
};
static_assert(kChannels <= 32, "RangeMemo::valid has a bit per channel");

// A stretch of a piece with constant input limits, as the splitting makes
// it (on the planner's side, handed over through split_ring_). No member
// initialisers: the splitting's scratch arrays of them (160 a piece) are
// not zeroed on every call.
struct Executor::SplitSpan {
  double a, b;
  double vc, feed, rapid;
};

// Where a piece's split spans lie in split_ring_ ([first, first + count);
// none for a stop), and for which configuration they were made.
struct Executor::PieceSplit {
  uint64_t first = 0;
  int count = 0;
  uint64_t gen = UINT64_MAX;
};

// A stretch of a piece with constant input limits, with its envelope.
struct Executor::Span {
  double a = 0, b = 0;  // on the path parameter; a == b for a stop
  uint64_t piece = 0;
  StopKind stop = StopKind::None;
  double vc = 0;        // velocity ceiling for the input (eroded)
  double feed = kInf;   // feed ceiling (eroded; times the feed override)
  double rapid = kInf;  // rapid ceiling (eroded; times the rapid override)
  double w_start = 0;   // braking envelope at a
  double w_end = 0;     // and at b
  // The envelope per chunk (kChunks equal parts): its value at the chunk
  // boundaries, the braking acceleration assumed on each chunk and what
  // each chunk alone allows.
  double wk[kChunks + 1] = {};
  double ak[kChunks] = {};
  double ak_own[kChunks] = {};
  double alpha = 0;     // braking acceleration the envelope assumes
  double alpha_own = 0; // what this span alone allows (before spreading)
  bool enveloped = false;  // the envelope values have been computed
};

Executor::Executor(const PlannerConfig& config, PathStore& store, std::size_t split_ring_spans)
    : cfg_(config),
      store_(store),
      lim_(std::make_unique<Limits>()),
      prep_lim_(std::make_unique<Limits>()) {
  std::size_t c = 2;
  while (c < store.pieces.capacity()) c *= 2;
  pdata_ = std::make_unique<PieceData[]>(c);
  plim_ = std::make_unique<PieceLimits[]>(c);
  prep_pdata_ = std::make_unique<PieceData[]>(c);
  psplit_ = std::make_unique<PieceSplit[]>(c);
  pmask_ = c - 1;
  tree_ = std::make_unique<Tree>();
  tree_->n = c;
  tree_->val = std::make_unique<double[]>(2 * c * kChannels);
  for (std::size_t i = 0; i < 2 * c * kChannels; ++i) tree_->val[i] = kInf;
  stops_ = std::make_unique<uint64_t[]>(c);
  std::size_t sc = 2;
  while (sc < c * 2) sc *= 2;
  spans_ = std::make_unique<Span[]>(sc);
  smask_ = sc - 1;
  std::size_t rc = sc;
  if (split_ring_spans > 0) {
    rc = 2;
    while (rc < std::max<std::size_t>(split_ring_spans, 2 * kSpansPerPiece)) rc *= 2;
  }
  split_ring_ = std::make_unique<SplitSpan[]>(rc);
  rmask_ = rc - 1;
  hx_ = std::make_unique<double[]>(kRing);
  hv_ = std::make_unique<double[]>(kRing);
  ha_ = std::make_unique<double[]>(kRing);
  hcommit_ = std::make_unique<double[]>(kRing);
  halpha_ = std::make_unique<double[]>(kRing);
  hmax_ = std::make_unique<double[]>(kRing);
  configure(config);
  *prep_lim_ = *lim_;
  clear_history(0);
}

Executor::~Executor() = default;

inline Executor::PieceData& Executor::pdata(uint64_t seq) noexcept { return pdata_[seq & pmask_]; }
inline const Executor::PieceData& Executor::pdata(uint64_t seq) const noexcept { return pdata_[seq & pmask_]; }
inline Executor::Span& Executor::span(uint64_t seq) noexcept { return spans_[seq & smask_]; }
inline const Executor::Span& Executor::span(uint64_t seq) const noexcept { return spans_[seq & smask_]; }
inline int Executor::ring(int ago) const noexcept { return (hist_pos_ - ago) & (kRing - 1); }

namespace {

// The limit rows, averaging window, generous bounds and grid a
// configuration gives (Executor::configure and the producer's copy).
template <class L>
void make_limits(const PlannerConfig& config, L& lim) noexcept {
  auto& r = lim.rows;
  r.n = 0;
  double tf = 0;
  double vsum = 0, asum = 0;
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(config.axis_mask & (1u << i))) continue;
    const AxisLimits& l = config.axes[static_cast<std::size_t>(i)];
    r.axis[r.n] = i;
    r.a[r.n] = l.max_acceleration * kLimitMargin;
    r.j[r.n] = l.max_jerk * kLimitMargin;
    tf = std::max(tf, l.max_acceleration / l.max_jerk);
    vsum += l.max_velocity * l.max_velocity;
    asum += l.max_acceleration * l.max_acceleration;
    ++r.n;
  }
  if (config.max_linear_acceleration > 0 || config.max_linear_jerk > 0) {
    r.axis[r.n] = -1;
    r.a[r.n] = config.max_linear_acceleration > 0 ? config.max_linear_acceleration * kLimitMargin : kInf;
    r.j[r.n] = config.max_linear_jerk > 0 ? config.max_linear_jerk * kLimitMargin : kInf;
    if (config.max_linear_acceleration > 0 && config.max_linear_jerk > 0) {
      tf = std::max(tf, config.max_linear_acceleration / config.max_linear_jerk);
    }
    ++r.n;
  }
  const double T = config.cycle_time_s;
  lim.T = T;
  lim.n = std::clamp(static_cast<int>(std::ceil(tf / T - 1e-9)), 1, kMaxFilter);
  lim.tf = lim.n * T;
  // Generous bounds: no piece is faster (pieces are capped to it), no input
  // sample accelerates harder.
  lim.v_bound = 2 * std::sqrt(vsum);
  if (config.max_linear_velocity > 0) lim.v_bound = std::min(lim.v_bound, 2 * config.max_linear_velocity);
  lim.a_top = 2 * std::sqrt(asum);
  for (int i = 0; i < kGrid; ++i) {
    const double f = static_cast<double>(i + 1) / kGrid;
    lim.grid[static_cast<std::size_t>(i)] = lim.v_bound * f * f;
  }
}

}  // namespace

void Executor::configure(const PlannerConfig& config) noexcept {
  cfg_ = config;
  T_ = config.cycle_time_s;
  make_limits(config, *lim_);
  n_ = lim_->n;
  tf_ = lim_->tf;
  v_bound_ = lim_->v_bound;
  a_top_ = lim_->a_top;
  reach_ = v_bound_ * (0.5 * tf_ + 2 * T_) + 1e-9;
  env_tol_ = 2 * a_top_ * kEnvTol;
  grid_ = lim_->grid;
}

void Executor::clear_history(double x) noexcept {
  // Only the newest n_ + 2 samples are ever read (the window and the one
  // leaving it); n_ changes only together with a clear. The whole ring
  // (16384 samples) took some 30 us in the cycle a path restarts.
  for (int k = 0; k < n_ + 2; ++k) {
    const int i = ring(k);
    hx_[i] = x;
    hv_[i] = 0;
    ha_[i] = 0;
    hcommit_[i] = kInf;
    halpha_[i] = 0;
  }
  x_ = y_ = x;
  v_ = w_ = b_ = 0;
}

void Executor::set_config(const PlannerConfig& config, uint64_t config_gen) noexcept {
  // The averaging window and the rows change only while nothing moves or
  // is queued; new limits apply from the next idle moment.
  if (is_idle() && out_ == ptail_) {
    configure(config);
    lim_->gen = config_gen;
    clear_history(x_);
    config_pending_ = false;
  } else {
    cfg_ = config;
    pending_gen_ = config_gen;
    config_pending_ = true;
  }
}

void Executor::apply_pending_config() noexcept {
  // Idle with what it has taken in: pieces published meanwhile are taken
  // in after this, their limit tables checked against the new number.
  if (!config_pending_ || !idle_ingested() || out_ != ptail_) return;
  configure(cfg_);
  lim_->gen = pending_gen_;
  clear_history(x_);
  config_pending_ = false;
}

void Executor::set_position(const Pose& pose) noexcept {
  if (is_idle()) pose_ = pose;
}

bool Executor::at_rest() const noexcept {
  if (v_ != 0) return false;
  for (int i = 0; i <= n_; ++i) {
    if (hx_[ring(i)] != x_) return false;
  }
  return true;
}

bool Executor::idle_ingested() const noexcept {
  return in_ == stail_ && pfin_ == ptail_ && out_ == ptail_ && at_rest() && !dwelling_;
}

bool Executor::is_idle() const noexcept { return idle_ingested() && ptail_ == store_.pieces.published(); }

bool Executor::take_abort_done(uint32_t& epoch) noexcept {
  if (!abort_done_) return false;
  abort_done_ = false;
  epoch = epoch_;
  return true;
}

double Executor::final_end() const noexcept { return stail_ > in_ ? span(stail_ - 1).b : x_; }

double Executor::distance_to_tail() const noexcept { return std::max(0.0, final_end() - y_); }

void Executor::pause() noexcept { hold_ = true; }

void Executor::resume() noexcept {
  if (aborting_) return;
  hold_ = false;
  step_active_ = false;
}

void Executor::step() noexcept {
  if (!hold_ || aborting_ || in_ >= stail_) return;
  // The end of the move the machine is on.
  const SegmentRecord& sr = store_.segs.at(piece(span(in_).piece).seg);
  step_s_ = std::max(x_, sr.s0 + sr.curve.length);
  step_active_ = true;
  hold_ = false;
}

void Executor::abort() noexcept {
  aborting_ = true;
  step_active_ = false;
}

// ---------------------------------------------------------------------------
// Limits
//
// Output sample k averages input samples k-N+1..k: its velocity w is the
// mean input velocity, its acceleration b the mean input acceleration, its
// jerk g = (a_k - a_{k-N}) / T_f, and it lies within v (T_f/2 + T) of every
// sample it averages (v bounding their velocities). An input sample j
// influences the outputs j..j+N. It gets a limit alpha_j: the largest |a|
// for which, wherever those outputs may lie and at any velocity up to what
// it commits to (its own plus what the window may still gain; later samples
// respect it), every axis keeps
//   c1 |b| + c2 w^2 <= A  and  c1 |g| + 3 c2 w |b| + c3 w^3 <= J,
// c1..c3 bounding the path's derivatives there, when |b| and |a_k - a_{k-N}|
// stay within alpha. The input keeps |a_k| <= alpha_k and |a_k - a_{k-N}| <=
// the largest alpha of the samples N+1 back (each valid where output k is).

namespace {

// Largest alpha in [0, hi] with m |(e0 + e1 alpha, f0 + f1 alpha)| +
// d alpha <= L (all coefficients >= 0, so the left side rises with
// alpha); 0 when even alpha = 0 is over. Without the d term the root of a
// quadratic (taken a hair low against rounding), else by bisection.
double largest_within(double m, double e0, double e1, double f0, double f1, double d, double L, double hi) noexcept {
  auto over = [&](double al) {
    const double e = e0 + e1 * al, f = f0 + f1 * al;
    return m * std::sqrt(e * e + f * f) + d * al - L;
  };
  if (d == 0) {
    if (!(m > 0)) return L >= 0 ? hi : 0;
    const double lm = L / m;
    const double c = e0 * e0 + f0 * f0 - lm * lm;
    if (!(c <= 0)) return 0;
    const double q = e1 * e1 + f1 * f1;
    const double bq = e0 * e1 + f0 * f1;
    const double den = bq + std::sqrt(bq * bq - q * c);
    if (!(den > 0)) return c == 0 ? 0 : hi;
    const double al = std::min(hi, (1 - 1e-9) * (-c / den));
    if (over(al) <= 0) return al;
  }
  if (!(over(0.0) <= 0)) return 0;
  if (over(hi) <= 0) return hi;
  double lo = 0;
  for (int it = 0; it < 48; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (over(mid) <= 0) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

// Largest |a| for one piece's bounds at output velocity u. `arc`, when
// not null, is the helix (arc, helix or spiral) the piece follows with no
// corner window on it: its in-plane derivatives are then known in
// direction, not only in size. On a helix P(s) = c + rho (cos(ws) u +
// sin(ws) v) + h n, axis x's derivatives are m (E e_x + F f_x) + n_x
// (...) with (e_x, f_x) a unit vector turning with s (m = |(u_x, v_x)|),
// so the output's acceleration P' b + P'' w^2 and jerk P' g + 3 P'' w b +
// P''' w^3 on that axis are at most m sqrt(E^2 + F^2) + |dh n_x| |b|
// (|g| for the jerk) with
//   acceleration E = |dr| |b| + rho om^2 u^2,  F = rho om |b| + 2 |dr| om u^2,
//   jerk         E = |dr| |g| + 3 rho om^2 u |b| + 3 |dr| om^2 u^3,
//                F = rho om |g| + 6 |dr| om u |b| + rho om^3 u^3
// (om the angle per unit s, u the output velocity; |b| <= alpha and
// |g| <= alpha / T_f as below). The sums c1 |b| + c2 u^2 and
// c1 |g| + 3 c2 u |b| + c3 u^3 add parts that lie at right angles: on a
// circle the normal jerk of a speed change (3 c2 u |b|) adds in
// quadrature to the tangential one (c1 |g| + c3 u^3), which leaves a
// curved piece near its velocity ceiling about twice the tangential
// acceleration. Either bound holds, so each axis takes the larger alpha.
double limit_at(const PieceBounds& b, const Curve* arc, const int* axis, const double* A, const double* J, int n,
                double tf, double u, double hi) noexcept {
  double a = kInf;
  double rho = 0, om = 0, dr = 0, dh = 0;
  if (arc) {
    rho = std::max(std::fabs(arc->r0), std::fabs(arc->r0 + arc->dr * arc->length));
    om = std::fabs(arc->omega);
    dr = std::fabs(arc->dr);
    dh = std::fabs(arc->dh);
  }
  for (int i = 0; i < n; ++i) {
    const int ax = axis[i];
    const double c1 = ax >= 0 ? b.c1[static_cast<std::size_t>(ax)] : b.lin1;
    if (!(c1 > 1e-12)) continue;
    const double c2 = ax >= 0 ? b.c2[static_cast<std::size_t>(ax)] : b.lin2;
    const double c3 = ax >= 0 ? b.c3[static_cast<std::size_t>(ax)] : b.lin3;
    double acc = (A[i] - c2 * u * u) / c1;
    double jerk = (J[i] - c3 * u * u * u) / (c1 / tf + 3 * c2 * u);
    if (arc && ax >= 0 && ax < 3) {
      const auto k = static_cast<std::size_t>(ax);
      const double m = std::sqrt(arc->u[k] * arc->u[k] + arc->v[k] * arc->v[k]);
      const double nz = dh * std::fabs(arc->n[k]);
      const double u2 = u * u, u3 = u2 * u;
      // Acceleration: E = |dr| al + rho om^2 u^2, F = rho om al + 2 |dr| om u^2.
      const double acc_arc = largest_within(m, rho * om * om * u2, dr, 2 * dr * om * u2, rho * om, nz, A[i], hi);
      // Jerk (|g| = al / T_f): E = (|dr| / T_f + 3 rho om^2 u) al + 3 |dr| om^2 u^3,
      // F = (rho om / T_f + 6 |dr| om u) al + rho om^3 u^3.
      const double jerk_arc =
          largest_within(m, 3 * dr * om * om * u3, dr / tf + 3 * rho * om * om * u, rho * om * om * om * u3,
                         rho * om / tf + 6 * dr * om * u, nz / tf, J[i], hi);
      acc = std::max(acc, acc_arc);
      jerk = std::max(jerk, jerk_arc);
    }
    a = std::min({a, acc, jerk});
  }
  return std::max(a, 0.0);
}

}  // namespace

// Smallest value of tree channel c over the pieces overlapping [lo, hi]
// around piece `from`, not across a stop (outputs never cross one while the
// input moves).
double Executor::range_min(uint64_t from, double lo, double hi, int c) const noexcept {
  ++work_.queries;
  if (from >= ptail_) return 0;
  RangeStretch e;
  return resolved_min(from, lo, hi, c, e);
}

// range_min's search and tree query; `e` is set to the stretches of lo
// and hi that resolve to the same pieces (and so to the same minimum).
double Executor::resolved_min(uint64_t from, double lo, double hi, int c, RangeStretch& e) const noexcept {
  ++work_.searches;
  const uint64_t first = store_.pieces.released();
  // Stops bound the range.
  uint64_t k_lo = first, k_hi = ptail_;
  {
    // The first stop after `from`, and the last one before it.
    uint64_t l = stop_head_, h = stop_tail_;
    while (l < h) {
      const uint64_t m = l + (h - l) / 2;
      if (stops_[m & pmask_] > from) {
        h = m;
      } else {
        l = m + 1;
      }
    }
    if (l < stop_tail_) k_hi = std::min(k_hi, stops_[l & pmask_]);
    if (l > stop_head_) k_lo = std::max(k_lo, stops_[(l - 1) & pmask_] + 1);
  }
  // Pieces overlapping [lo, hi]: the first piece starting after x, by a
  // search galloping out from a start near it (the ranges asked for lie
  // around `from`, a few pieces wide, in a queue of thousands), then
  // bisecting. The start is the answer of the previous query on the same
  // side when that lies near `from`: the envelope's bisections ask ranges
  // whose ends move by a piece or two (or not at all) from one query to
  // the next. Any start gives the same answer (the pieces' starts are in
  // order), a near one in fewer steps.
  const PieceData* const pd = pdata_.get();
  const std::size_t pmask = pmask_;
  auto s0 = [pd, pmask](uint64_t k) { return pd[k & pmask].s0; };
  auto first_after = [&](double x, uint64_t hint) {
    if (k_hi <= k_lo) return k_lo;
    const uint64_t near = hint + 64 >= from && hint <= from + 64 ? hint : from;
    const uint64_t f = std::clamp(near, k_lo, k_hi - 1);
    uint64_t l = k_lo, h = k_hi;  // pieces before l start at or before x, from h on after it
    uint64_t step = 1;
    if (s0(f) > x) {
      h = f;
      while (h - k_lo > step && s0(h - step) > x) {
        h -= step;
        step *= 2;
      }
      if (h - k_lo > step) l = h - step + 1;
    } else {
      l = f + 1;
      while (k_hi - l > step && !(s0(l + step - 1) > x)) {
        l += step;
        step *= 2;
      }
      if (k_hi - l > step) h = l + step - 1;
    }
    while (l < h) {
      const uint64_t m = l + (h - l) / 2;
      if (s0(m) > x) {
        h = m;
      } else {
        l = m + 1;
      }
    }
    return l;
  };
  // first_after(x) is l exactly for x in [s0(l - 1), s0(l)) (without the
  // bound on a side where l is k_lo or k_hi).
  auto stretch = [&](uint64_t l, double& from_x, double& to_x) {
    from_x = l > k_lo ? s0(l - 1) : -kInf;
    to_x = l < k_hi ? s0(l) : kInf;
  };
  uint64_t a = first_after(lo, hint_lo_);
  hint_lo_ = a;
  stretch(a, e.lo0, e.lo1);
  if (a > k_lo) --a;  // the piece holding lo
  a = std::min(a, from);
  const uint64_t b_after = first_after(hi, hint_hi_);
  hint_hi_ = b_after;
  stretch(b_after, e.hi0, e.hi1);
  const uint64_t b = std::max(b_after, from + 1);
  if (b <= a) return e.val = kInf;
  const std::size_t n = tree_->n;
  const std::size_t sa = static_cast<std::size_t>(a & (n - 1));
  const uint64_t len = b - a;
  if (sa + len <= n) return e.val = tree_->query(sa, static_cast<std::size_t>(sa + len), c);
  return e.val = std::min(tree_->query(sa, n, c), tree_->query(0, static_cast<std::size_t>(sa + len - n), c));
}

// range_min over the ranges one envelope span asks (all around the same
// piece, with the pieces and the tree unchanged): the envelope's nested
// bisections ask ranges whose ends move by less than a piece from one
// query to the next, and those that resolve to the same pieces as one of
// the last two asked of the same channel take its answer without a
// search or a tree query (the same value: the minimum over the same
// pieces). Counted as queries all the same (the walk's budget is
// in queries, so its pace, and the motion, do not change).
double Executor::range_min(RangeMemo& memo, double lo, double hi, int c) const noexcept {
  ++work_.queries;
  if (memo.from >= ptail_) return 0;
  auto& ways = memo.e[static_cast<std::size_t>(c)];
  const uint32_t bit = 1u << c;
  memo.v0 = c > 0 ? grid_[static_cast<std::size_t>(c - 1)] : -kInf;
  memo.v1 = c < kGrid - 1 ? grid_[static_cast<std::size_t>(c)] : kInf;
  if (memo.valid & bit) {
    for (const RangeStretch& e : ways) {
      if (e.covers(lo, hi)) {
        memo.last = &e;
        return e.val;
      }
    }
    for (int w = RangeMemo::kWays - 1; w > 0; --w) ways[static_cast<std::size_t>(w)] = ways[static_cast<std::size_t>(w - 1)];
  } else {
    // Stretches nothing lies in.
    for (RangeStretch& e : ways) e = RangeStretch{kInf, -kInf, kInf, -kInf, 0};
    memo.valid |= bit;
  }
  memo.last = &ways[0];
  return resolved_min(memo.from, lo, hi, c, ways[0]);
}

int Executor::grid_index(double v) const noexcept {
  // The first grid velocity at or above v (the last one above them all),
  // by a binary search over the 16 entries: the closed form through the
  // quadratic grid (a square root and a ceil, a libm call on baseline
  // x86-64) took a fifth of the planner's time on 3D_Chips.
  static_assert(kGrid == 16, "grid_index searches 16 entries");
  const auto g = [&](int i) { return grid_[static_cast<std::size_t>(i)]; };
  int i = 0;
  if (g(7) < v) i = 8;
  if (g(i + 3) < v) i += 4;
  if (g(i + 1) < v) i += 2;
  if (g(i) < v) i += 1;
  return i;
}

// The limit for an input sample whose outputs lie within [lo, hi] at
// velocities up to u: the smallest over the pieces there.
double Executor::accel_limit(uint64_t from, double lo, double hi, double u) const noexcept {
  return std::max(0.0, std::min(a_top_, range_min(from, lo, hi, grid_index(u))));
}

double Executor::accel_limit(RangeMemo& memo, double lo, double hi, double u) const noexcept {
  const RangeStretch* e = memo.last;
  if (e && u > memo.v0 && u <= memo.v1 && e->covers(lo, hi) && memo.from < ptail_) {
    ++work_.queries;
    return std::max(0.0, std::min(a_top_, e->val));
  }
  return std::max(0.0, std::min(a_top_, range_min(memo, lo, hi, grid_index(u))));
}

double Executor::ceiling(const Span& sp) const noexcept {
  return std::min({sp.vc, env_feed_ * sp.feed, env_rapid_ * sp.rapid});
}

// ---------------------------------------------------------------------------
// Ingest, spans and the envelope

namespace {

// A piece's velocity ceiling under `lim` (0 for a stop). Ceilings of
// curved pieces are rounded down to 1 % steps: neighbours with nearly
// equal ceilings then share spans (fewer for the envelope).
template <class L>
double piece_ceiling(const Piece& p, const L& lim) noexcept {
  if (p.stop != StopKind::None) return 0;
  double v = std::min(p.v_hard, lim.v_bound);
  bool curved = p.bounds.lin2 > 0 || p.bounds.lin3 > 0;
  for (int i = 0; i < kNumAxes && !curved; ++i) curved = p.bounds.c2[static_cast<std::size_t>(i)] > 0;
  if (curved && v > 1e-9) v = std::exp(std::floor(std::log(v) / kCeilingStep) * kCeilingStep);
  return v;
}

// A piece's limit table under `lim`.
template <class L, class T>
void piece_limits(const Piece& p, const Curve* arc, const L& lim, T& out) noexcept {
  out.gen = lim.gen;
  if (p.stop != StopKind::None) {
    out.v = 0;
    for (int c = 0; c < kChannels; ++c) out.vals[c] = kInf;
    return;
  }
  const double v = piece_ceiling(p, lim);
  out.v = v;
  const auto& r = lim.rows;
  for (int i = 0; i < kGrid; ++i) {
    const double u = std::min(lim.grid[static_cast<std::size_t>(i)], v);
    out.vals[i] = std::min({limit_at(p.bounds, arc, r.axis, r.a, r.j, r.n, lim.tf, u, lim.a_top), p.a_cap, lim.a_top});
  }
  out.vals[kChV] = v;
  out.vals[kChFeed] = p.v_feed;
  out.vals[kChRapid] = p.v_rapid;
}

}  // namespace

// The helix a piece follows when no corner window touches it (its exact
// shape for limit_at), else null.
const Curve* Executor::bare_helix(const Piece& p) const noexcept {
  if (p.stop != StopKind::None || p.v_lo != p.v_hi) return nullptr;
  const Curve& c = store_.segs.at(p.seg).curve;
  return c.kind == CurveKind::Helix ? &c : nullptr;
}

void Executor::set_prepare_config(const PlannerConfig& config, uint64_t config_gen) noexcept {
  make_limits(config, *prep_lim_);
  prep_lim_->gen = config_gen;
  // The pieces prepared before and not released may still be split (and
  // are neighbours of pieces still to be split): their ceilings under
  // these limits, so that spans marked with this configuration are made
  // from it alone, as the servo side would make them.
  for (uint64_t k = std::max(store_.pieces.released(), prep_next_ > pmask_ ? prep_next_ - pmask_ : 0); k < prep_next_;
       ++k) {
    prep_pdata_[k & pmask_].v = piece_ceiling(piece(k), *prep_lim_);
  }
}

void Executor::prepare_published() noexcept {
  // The builder published these (on this thread); their slots are free:
  // a piece is published only with room in the ring, so the servo side
  // has taken in and released the piece that used the slot before.
  const uint64_t pub = store_.pieces.published();
  if (prep_next_ >= pub && prep_split_next_ >= pub) return;
  for (; prep_next_ < pub; ++prep_next_) {
    const Piece& p = piece(prep_next_);
    PieceLimits& t = plim_[prep_next_ & pmask_];
    piece_limits(p, bare_helix(p), *prep_lim_, t);
    PieceData& d = prep_pdata_[prep_next_ & pmask_];
    d.v = t.v;
    d.s0 = p.s0;
    d.end = p.s0 + p.length;
    d.epoch = p.epoch;
    d.stop = p.stop != StopKind::None;
    prep_tail_s_ = d.end;
    if (d.stop) prep_last_stop_ = prep_next_;
  }
  // The spans before the tables: run_cycle reads split_ready_ after
  // prepared_, so a piece it may split has been split here (its rule,
  // finalize's, holds over the published pieces when it holds over those
  // taken in).
  split_published(pub);
  prepared_.store(pub, std::memory_order_release);
}

// The producer's share of finalize: a piece is split once every piece
// that may spread data onto it is published (finalize's rule over the
// published pieces), into spans in split_ring_. Pieces the servo side has
// already taken in (split by itself meanwhile) are skipped; a full ring
// waits (run_cycle then splits the pieces it needs itself).
void Executor::split_published(uint64_t pub) noexcept {
  const Limits& L = *prep_lim_;
  const double spread = 0.5 * L.tf + 2 * L.T;
  const double reach = L.v_bound * spread + 1e-9;
  const double settle = 0.5 * L.a_top * (L.tf + 2 * L.T) * (L.tf + 2 * L.T);
  const uint64_t taken = spans_taken_.load(std::memory_order_acquire);
  prep_split_next_ = std::max(prep_split_next_, taken);
  const uint64_t first_kept = store_.pieces.released();
  for (; prep_split_next_ < pub; ++prep_split_next_) {
    const uint64_t p = prep_split_next_;
    const PieceData& d = prep_pdata_[p & pmask_];
    const bool stop_ahead = prep_last_stop_ != UINT64_MAX && prep_last_stop_ >= p;
    if (!stop_ahead && d.end + d.v * spread + settle > prep_tail_s_) break;
    // Split spans of pieces [taken, p) may still be read.
    const uint64_t oldest = taken < p ? psplit_[taken & pmask_].first : prep_rec_head_;
    if (prep_rec_head_ + kSpansPerPiece - oldest > rmask_ + 1) break;
    PieceSplit& ps = psplit_[p & pmask_];
    ps.first = prep_rec_head_;
    ps.gen = L.gen;
    ps.count = 0;
    if (!d.stop) {
      SplitSpan sub[kSpansPerPiece];
      ps.count = split_piece(p, prep_pdata_.get(), true, first_kept, pub, d.epoch, spread, reach, sub);
      for (int i = 0; i < ps.count; ++i) split_ring_[prep_rec_head_++ & rmask_] = sub[i];
    }
  }
  split_ready_.store(prep_split_next_, std::memory_order_release);
}

void Executor::ingest() noexcept {
  const uint64_t pub = prepared_.load(std::memory_order_acquire);
  const uint64_t first = ptail_;
  PieceLimits own;
  // At most kIngestPerCycle pieces per cycle: the rest wait in the ring
  // (the builder may publish thousands at once). Each is a copy of the
  // table the producer computed.
  for (int budget = kIngestPerCycle; ptail_ < pub && budget > 0; --budget) {
    ++work_.ingested;
    const Piece& p = piece(ptail_);
    {
      PieceData& d = pdata(ptail_);
      d.s0 = p.s0;
      d.end = p.s0 + p.length;
      d.epoch = p.epoch;
      d.stop = p.stop != StopKind::None;
    }
    if (p.epoch != epoch_) {
      // Planned before an abort: dropped.
      if (out_ == ptail_) ++out_;
      if (pfin_ == ptail_) ++pfin_;
      ++ptail_;
      continue;
    }
    if (idle_ingested() && p.s0 != x_) {
      // A path after an abort or a reset starts further along the path
      // parameter; the machine is where it was.
      clear_history(p.s0);
    }
    PieceData& d = pdata(ptail_);
    const PieceLimits* t = &plim_[ptail_ & pmask_];
    if (t->gen != lim_->gen) {
      // Made for other limits than these (changed while moving).
      piece_limits(p, bare_helix(p), *lim_, own);
      t = &own;
      ++work_.limits;
    }
    d.v = t->v;
    if (p.stop != StopKind::None) {
      last_stop_ = ptail_;
      if (stop_tail_ - stop_head_ > pmask_) ++stop_head_;
      stops_[stop_tail_++ & pmask_] = ptail_;
    }
    tree_->set_leaf(static_cast<std::size_t>(ptail_ & pmask_), t->vals);
    tail_s_ = p.s0 + p.length;
    ++ptail_;
  }
  // The ancestors of the leaves set (the slots may wrap around the ring).
  if (ptail_ > first) {
    const std::size_t lo = static_cast<std::size_t>(first & pmask_);
    const std::size_t len = static_cast<std::size_t>(ptail_ - first);
    if (lo + len <= tree_->n) {
      tree_->update(lo, lo + len);
    } else {
      tree_->update(lo, tree_->n);
      tree_->update(0, lo + len - tree_->n);
    }
  }
  finalize();
}

// A piece is split into spans once every piece that may spread data onto
// it is in: those within reach_ after it, up to the next stop (nothing
// spreads across a stop: the input rests there until the output has
// caught up).
void Executor::finalize() noexcept {
  spans_added_ = false;
  for (int budget = kSplitPerCycle; pfin_ < ptail_ && budget > 0; --budget) {
    const Piece& p = piece(pfin_);
    const bool stop_ahead = last_stop_ != UINT64_MAX && last_stop_ >= pfin_ && last_stop_ < ptail_;
    // What may spread onto p from later pieces: lower ceilings within
    // V_p (T_f/2 + 2T), and outputs of samples braking here at most that
    // far ahead.
    const double horizon = pdata(pfin_).v * (0.5 * tf_ + 2 * T_) + 0.5 * a_top_ * (tf_ + 2 * T_) * (tf_ + 2 * T_);
    if (!stop_ahead && p.s0 + p.length + horizon > tail_s_) break;
    if (stail_ - sfirst_ + kSpansPerPiece + 2 > smask_ + 1) break;
    make_spans(pfin_);
    ++pfin_;
  }
  // The producer may reuse the split spans of pieces before pfin_.
  spans_taken_.store(pfin_, std::memory_order_release);
  // About twice a stop from top speed (generous bounds: v_bound_ and
  // a_top_ are twice the machine's).
  const double near = v_bound_ * v_bound_ / std::max(a_top_, 1e-9) + v_bound_ * tf_;
  // New spans: a walk from the tail. A walk raises the spans within a
  // stop of the old tail, whatever was added; walking after every piece
  // (one every cycle or two on a dense program) walked that stretch again
  // every time, most of the envelope's work. While the tail lies far
  // ahead of the input (more than kDeferNear x near: nothing the input
  // may brake for within its reach changes), new spans wait until
  // kDeferBatch x near of path has been added since the last walk, or
  // nothing was added for kDeferIdle cycles; closer to the input they are
  // walked at once as before. Spans not walked yet keep the lower
  // envelope of the shorter path (or zero): the input stays safe.
  if (spans_added_) {
    env_deferred_ = true;
    env_idle_ = 0;
  } else if (env_deferred_) {
    ++env_idle_;
  }
  if (env_deferred_ && (final_end() - x_ < kDeferNear * near || final_end() - env_walk_s_ >= kDeferBatch * near ||
                        env_idle_ >= kDeferIdle)) {
    env_deferred_ = false;
    env_walk_s_ = final_end();
    ++work_.walks;
    envelope_request(false);
  }
  // The walk is urgent (kQueriesUrgent) on spans within about twice a
  // stop from top speed ahead of the input (`near`) that the input may
  // need soon: spans no walk has reached yet (envelope zero: the start,
  // the look-ahead arriving), and spans within about twice a stop from
  // twice the speed the input runs or is heading for (`reach`). Farther
  // spans keep the lower envelope of a slightly shorter path a few cycles
  // longer, beyond where the input brakes for: with a look-ahead shorter
  // than `near` (the circle of 0.05 mm lines: 42 mm of it against 42)
  // every walk from the tail was urgent, all the time. The urgent slice
  // also waits while the input's step searched in the last kSearchQuiet
  // cycles (braking against the envelope, up to 18 brake simulations a
  // cycle; such searches come in runs): the two together made the
  // slowest cycles.
  double v_ref = std::max(v_, w_);
  if (in_ < stail_ && span(in_).stop == StopKind::None) v_ref = std::max(v_ref, ceiling(span(in_)));
  v_ref *= 2;
  const double reach = std::min(near, v_ref * v_ref / std::max(a_top_, 1e-9) + v_ref * tf_);
  envelope_work(near, reach);
}

void Executor::make_spans(uint64_t p) noexcept {
  const Piece& pc = piece(p);
  if (pc.stop != StopKind::None) {
    Span& s = span(stail_++);
    s = Span{};
    s.a = s.b = pc.s0;
    s.piece = p;
    s.stop = pc.stop;
    spans_added_ = true;
    return;
  }
  SplitSpan sub[kSpansPerPiece];
  int ns = 0;
  const PieceSplit& ps = psplit_[p & pmask_];
  if (p < split_ready_.load(std::memory_order_acquire) && ps.gen == lim_->gen) {
    // Split on the planner's side for these limits: a copy.
    ns = ps.count;
    for (int i = 0; i < ns; ++i) sub[i] = split_ring_[(ps.first + static_cast<uint64_t>(i)) & rmask_];
    ++work_.taken;
  } else {
    // Only pieces with a lower ceiling within this piece's own spread can
    // cap its velocity: one range minimum says whether to look.
    const double spread = 0.5 * tf_ + 2 * T_;
    const double vreach = pdata(p).v * spread;
    const bool lower_v = range_min(p, pc.s0 - vreach, pc.s0 + pc.length + vreach, kChV) < pdata(p).v;
    ns = split_piece(p, pdata_.get(), lower_v, store_.pieces.released(), ptail_, epoch_, spread, reach_, sub);
    ++work_.split;
  }
  append_spans(p, sub, ns);
}

// A piece (not a stop) cut into at most kSpansPerPiece stretches of
// constant caps, into `out`; their number. `pd` holds the compact data of
// the pieces [first_kept, tail) (the servo side's or the producer's copy),
// `scan` whether neighbours may cap this piece's velocity, `epoch` the
// piece's. A function of the pieces and the configuration alone: the
// planner's side and the servo thread make the same spans.
int Executor::split_piece(uint64_t p, const PieceData* pd, bool scan_neighbours, uint64_t first_kept, uint64_t tail,
                          uint32_t epoch, double spread, double reach, SplitSpan* out) const noexcept {
  const Piece& pc = piece(p);
  const PieceData& dp = pd[p & pmask_];
  const double lo = pc.s0;
  const double hi = pc.s0 + pc.length;
  // Ceilings: an output in piece q averages input samples within
  // v_q (T_f/2 + T) of it (the input moves no faster near q), so each piece
  // caps the input over that distance around it. Collect the caps that
  // reach into this piece and where they end inside it.
  struct Cap {
    double from, to, v, feed, rapid;
  };
  Cap caps[2 * kMaxCuts];
  int ncap = 0;
  // Caps over the whole piece add no cut and lower every part alike: one
  // minimum (a dense curved run has hundreds of them per piece, and each
  // part used to loop over them all).
  double v_all = dp.v;
  double cuts[kMaxCuts + 2];
  int ncut = 0;
  cuts[ncut++] = lo;
  cuts[ncut++] = hi;
  auto consider = [&](const PieceData& q) {
    const double vq = q.v;
    const double r = vq * spread;
    const double from = q.s0 - r;
    const double to = q.end + r;
    if (to <= lo || from >= hi) return;
    if (!(vq < dp.v)) return;
    if (from <= lo && to >= hi) {
      v_all = std::min(v_all, vq);
      return;
    }
    if (ncap < 2 * kMaxCuts) caps[ncap++] = {from, to, vq, pc.v_feed, pc.v_rapid};
    if (from > lo && ncut < kMaxCuts) cuts[ncut++] = from;
    if (to < hi && ncut < kMaxCuts) cuts[ncut++] = to;
  };
  // Feeds and rapids (requests, not machine limits) apply to the input
  // where they are: the output reaches a lower feed within T_f/2.
  const double scan = scan_neighbours ? dp.v * spread : -1;
  for (uint64_t k = p; scan >= 0 && k > first_kept;) {
    --k;
    const PieceData& q = pd[k & pmask_];
    if (q.stop || q.epoch != epoch || lo - q.end > scan) break;
    consider(q);
  }
  for (uint64_t k = p + 1; scan >= 0 && k < tail; ++k) {
    const PieceData& q = pd[k & pmask_];
    if (q.stop || q.s0 - hi > scan) break;
    consider(q);
  }
  std::sort(cuts, cuts + ncut);
  // Sub-intervals with their caps.
  struct Part {
    double a, b, v, feed, rapid;
  };
  Part parts[kMaxCuts + 2];
  int np = 0;
  for (int i = 0; i + 1 < ncut; ++i) {
    const double a = cuts[i];
    const double b = cuts[i + 1];
    if (!(b > a)) continue;
    Part pt{a, b, v_all, pc.v_feed, pc.v_rapid};
    for (int c = 0; c < ncap; ++c) {
      if (caps[c].from <= a && caps[c].to >= b) {
        pt.v = std::min(pt.v, caps[c].v);
        pt.feed = std::min(pt.feed, caps[c].feed);
        pt.rapid = std::min(pt.rapid, caps[c].rapid);
      }
    }
    if (np > 0 && parts[np - 1].v == pt.v && parts[np - 1].feed == pt.feed && parts[np - 1].rapid == pt.rapid) {
      parts[np - 1].b = b;
    } else {
      parts[np++] = pt;
    }
  }
  // Each span brakes with one acceleration (the smallest its outputs may
  // meet): cut the piece at doubling distances from both ends, so that a
  // tight corner next to a long move limits only the stretch near it.
  // The stretches with their caps only: an array of whole Spans (160 of
  // them, their envelope fields zeroed) cost about a microsecond per
  // piece, most of the splitting.
  SplitSpan sub[kMaxCuts + 64];
  int ns = 0;
  for (int i = 0; i < np; ++i) {
    double pts[64];
    int nq = 0;
    pts[nq++] = parts[i].a;
    for (double d = 0.025; d < reach && 4 * d < hi - lo && nq < 60; d *= 1.4142135623730951) {
      if (lo + d > parts[i].a && lo + d < parts[i].b) pts[nq++] = lo + d;
      if (hi - d > parts[i].a && hi - d < parts[i].b) pts[nq++] = hi - d;
    }
    pts[nq++] = parts[i].b;
    std::sort(pts, pts + nq);
    for (int j = 0; j + 1 < nq; ++j) {
      if (!(pts[j + 1] > pts[j])) continue;
      if (ns >= static_cast<int>(std::size(sub))) break;
      sub[ns++] = {pts[j], pts[j + 1], parts[i].v, parts[i].feed, parts[i].rapid};
    }
  }
  // At most kSpansPerPiece: merge the shortest span into a neighbour (the
  // merged span keeps the lower caps).
  while (ns > kSpansPerPiece) {
    int m = 0;
    for (int i = 1; i < ns; ++i) {
      if (sub[i].b - sub[i].a < sub[m].b - sub[m].a) m = i;
    }
    const int o = m == 0 ? 1 : (m == ns - 1 ? m - 1 : (sub[m - 1].b - sub[m - 1].a < sub[m + 1].b - sub[m + 1].a ? m - 1 : m + 1));
    const int l = std::min(m, o);
    sub[l].b = sub[l + 1].b;
    sub[l].vc = std::min(sub[l].vc, sub[l + 1].vc);
    sub[l].feed = std::min(sub[l].feed, sub[l + 1].feed);
    sub[l].rapid = std::min(sub[l].rapid, sub[l + 1].rapid);
    for (int i = l + 1; i + 1 < ns; ++i) sub[i] = sub[i + 1];
    --ns;
  }
  if (ns == 0) {
    sub[0] = {lo, hi, dp.v, pc.v_feed, pc.v_rapid};
    ns = 1;
  }
  for (int i = 0; i < ns; ++i) out[i] = sub[i];
  return ns;
}

// The spans of piece p (its split stretches) appended to the ring: the
// servo side's part of the splitting, which depends on where the input is.
void Executor::append_spans(uint64_t p, const SplitSpan* sub, int ns) noexcept {
  const Piece& pc = piece(p);
  const double lo = pc.s0;
  const double hi = pc.s0 + pc.length;
  for (int i = 0; i < ns; ++i) {
    // Dense short pieces with nearly the same caps share a span (fewer
    // spans for the envelope to walk, and the span ring holds more path).
    // Only where the piece's caps are no lower than the span's: growing a
    // span must never lower a ceiling the input may already brake for
    // (seeds 1, 5, 6 of TpSmoothing.RandomWigglyBands... on Mill-F at
    // 250 us ran out of safe choices when it did).
    if (ns == 1 && hi - lo < 0.25 * kMergeSpan && stail_ > sfirst_ && stail_ > in_ + 1 && merge_ok_) {
      Span& last = span(stail_ - 1);
      const double len = sub[i].b - last.a;
      auto close = [](double x, double y) { return (x == y) || (std::isfinite(x) && std::isfinite(y) && std::fabs(x - y) <= 0.03 * std::max(x, y)); };
      if (last.stop == StopKind::None && std::fabs(last.b - sub[i].a) < 1e-12 && len <= kMergeSpan &&
          sub[i].b - sub[i].a < 0.25 * kMergeSpan && close(last.vc, sub[i].vc) && close(last.feed, sub[i].feed) &&
          close(last.rapid, sub[i].rapid) && sub[i].vc >= last.vc && sub[i].feed >= last.feed &&
          sub[i].rapid >= last.rapid) {
        last.b = sub[i].b;
        last.vc = std::min(last.vc, sub[i].vc);
        last.feed = std::min(last.feed, sub[i].feed);
        last.rapid = std::min(last.rapid, sub[i].rapid);
        last.enveloped = false;
        spans_added_ = true;  // walk it again from the tail
        continue;
      }
    }
    Span& sp = span(stail_++);
    sp = Span{};
    sp.a = sub[i].a;
    sp.b = sub[i].b;
    sp.piece = p;
    sp.vc = sub[i].vc;
    sp.feed = sub[i].feed;
    sp.rapid = sub[i].rapid;
    spans_added_ = true;
  }
  // Only whole short pieces join (cuts near long pieces' ends stay).
  merge_ok_ = ns == 1 && hi - lo < 0.25 * kMergeSpan;
}

// Braking envelope: the largest input velocity at each point from which
// the input can still brake (at each span's `alpha`) within every ceiling
// ahead and come to rest at the end of the spans. Recomputed backward from
// `last` while it changes.
//
// The walk is spread over cycles (envelope_work, a bounded number of spans
// per cycle): spans not yet walked keep the values of an earlier, shorter
// published path, which are lower (appending spans only relaxes the stop at
// the end), so the input under them stays safe, only slower until the walk
// has passed. A span never walked yet has an envelope of zero.
void Executor::envelope_request(bool full) noexcept {
  if (env_active_) {
    // One walk at a time: restarting at the tail on every new piece could
    // keep a long walk from ever reaching the input.
    env_pending_ = true;
    env_pending_full_ = env_pending_full_ || full;
    return;
  }
  if (stail_ <= in_) return;
  env_active_ = true;
  env_k_ = stail_ - 1;
  // A walk may end where a span's values do not change, but never on the
  // newest span (it may be new or grown), nor anywhere when the ceilings
  // changed everywhere (overrides).
  env_floor_ = full ? 0 : stail_ - 1;
  if (!full && !span(in_).enveloped && span(in_).stop == StopKind::None) {
    // The input stands on spans no walk has reached: a start, where the
    // whole look-ahead arrives at once and the walk from the tail takes
    // many cycles to come down to the input (15 on a dense spiral, the
    // machine standing). Walk first from a few spans ahead of the input:
    // the spans after them, not walked yet, have an envelope of zero, so
    // this is the envelope of the path ending there (within the published
    // path, lower than the full one); the walk from the tail follows and
    // raises it.
    uint64_t m = in_;
    while (m + 1 < stail_ && m - in_ < kStartWalkSpans && span(m + 1).stop == StopKind::None &&
           span(m).b < x_ + kStartWalkNear * (v_bound_ * v_bound_ / std::max(a_top_, 1e-9))) {
      ++m;
    }
    if (m + 1 < stail_) {
      env_k_ = m;
      env_floor_ = m;
      env_pending_ = true;
    }
  }
}

void Executor::envelope_work(double near, double reach) noexcept {
  // Spans and range minima: a curved span may cost many times a straight
  // one, so the walk also stops once its own queries this cycle reach the
  // slice's (at least one span a cycle): kQueriesUrgent while the span to
  // walk next is urgent (finalize), else kQueriesPerCycle.
  const int q0 = work_.queries;
  const int s0 = work_.searches;
  for (int spans = 0;; ++spans) {
    if (!env_active_) {
      if (!env_pending_) return;
      env_pending_ = false;
      const bool full = env_pending_full_;
      env_pending_full_ = false;
      envelope_request(full);
      if (!env_active_) return;
    }
    const uint64_t k = env_k_;
    if (k < in_ || k >= stail_) {
      env_active_ = false;
      continue;
    }
    const double ahead = span(k).a - x_;
    const bool urgent = ahead < near && (ahead < reach || !span(k).enveloped) && since_search_ > kSearchQuiet;
    if (spans > 0 && (spans >= kEnvelopePerCycle || work_.queries - q0 >= (urgent ? kQueriesUrgent : kQueriesPerCycle))) {
      return;
    }
    const double w_end = (k + 1 >= stail_) ? 0.0 : span(k + 1).w_start;
    const bool known = span(k).enveloped;
    const double before = span(k).w_start;
    const double before_end = span(k).w_end;
    envelope_span(k, w_end);
    ++work_.enveloped;
    work_.envelope_queries = work_.queries - q0;
    work_.envelope_searches = work_.searches - s0;
    if ((known && k < env_floor_ && span(k).w_start == before && span(k).w_end == before_end) || k == in_ || k == 0) {
      env_active_ = false;
      continue;
    }
    --env_k_;
  }
}

void Executor::envelope_span(uint64_t k, double w_end) noexcept {
  Span& s = span(k);
  s.enveloped = true;
  if (s.stop != StopKind::None) {
    s.w_start = s.w_end = 0;
    for (int c = 0; c <= kChunks; ++c) s.wk[c] = 0;
    for (int c = 0; c < kChunks; ++c) s.ak[c] = s.ak_own[c] = kInf;
    s.alpha = s.alpha_own = kInf;
    return;
  }
  s.w_end = w_end;
  s.wk[kChunks] = w_end;
  const double ceil = ceiling(s);
  const double h = (s.b - s.a) / kChunks;
  s.alpha_own = kInf;
  s.alpha = kInf;
  RangeMemo memo;
  memo.from = s.piece;
  for (int c = kChunks - 1; c >= 0; --c) {
    const double c0 = s.a + c * h;
    const double c1 = c0 + h;
    const double we = s.wk[c + 1];
    // A braking sample on this chunk at velocity up to w has its outputs
    // within w (T_f/2 + 2T) ahead and within the window's span behind (its
    // velocity at most w + a_guess T_f over T_f).
    auto brake_limit = [&](double w, double a_guess) {
      const double vw = w + a_guess * tf_;
      return accel_limit(memo, c0 - vw * (0.5 * tf_ + 4 * T_), c1 + w * (0.5 * tf_ + 2 * T_), vw);
    };
    // Self-consistent: braking at alpha here leaves the window at most
    // alpha T_f faster than now, and alpha must hold for that.
    auto own_at = [&](double w) {
      const double a_hi = brake_limit(w, 0);
      if (brake_limit(w, a_hi) >= a_hi) return a_hi;
      double lo = 0, hi = a_hi;
      for (int it = 0; it < 8; ++it) {
        const double mid = 0.5 * (lo + hi);
        (brake_limit(w, mid) >= mid ? lo : hi) = mid;
      }
      return lo;
    };
    // Only this chunk's own limit: the input brakes with the limit of the
    // chunks its step reaches (brake_alpha), and the spread of a harder
    // limit ahead over the window is covered by the run-time rules (each
    // sample's limit holds for the samples after it; safe() simulates the
    // brake with the limits of where it goes). Taking the minimum over a
    // window of travel ahead as well was tried: no limit or margin
    // violation without it in the property runs, and 14 % less time on
    // random lines with it gone.
    auto alpha_at = [&](double w) { return own_at(w); };
    // The largest w on the brake curve from `we` with the alpha valid for
    // every velocity up to it (alpha falls with w).
    const double a0 = alpha_at(we);
    double hi = std::min(ceil, brake_curve(we, a0, h));
    double alpha = alpha_at(hi);
    if (hi > brake_curve(we, alpha, h)) {
      double lo = std::min(we, hi);
      alpha = alpha_at(lo);
      for (int it = 0; it < 10; ++it) {
        const double mid = 0.5 * (lo + hi);
        const double am = alpha_at(mid);
        if (mid <= brake_curve(we, am, h)) {
          lo = mid;
          alpha = am;
        } else {
          hi = mid;
        }
      }
      hi = lo;
    }
    s.wk[c] = hi;
    s.ak[c] = alpha;
    // own_at(hi): alpha is alpha_at (= own_at) of the final hi on both
    // branches above (asking again took a sixth of the envelope's queries).
    s.ak_own[c] = alpha;
    s.alpha_own = std::min(s.alpha_own, s.ak_own[c]);
    s.alpha = std::min(s.alpha, alpha);
  }
  s.w_start = s.wk[0];
}

double Executor::chunk_alpha(uint64_t k, double x) const noexcept {
  const Span& s = span(k);
  if (s.stop != StopKind::None) return kInf;
  const double h = (s.b - s.a) / kChunks;
  const int c = h > 0 ? std::clamp(static_cast<int>((x - s.a) / h), 0, kChunks - 1) : 0;
  return s.ak[c];
}

// The braking acceleration for a step from x0 that ends by x1: the
// largest envelope acceleration of the chunks it touches. Braking at it
// keeps the input under the envelope across chunk boundaries (the curve
// of the harder-braking chunk is the lower one on the far side), and it
// is valid for the sample: each chunk's value allows for outputs 2 T
// beyond the chunk. `k` is a span at or before x0; it is moved on.
double Executor::brake_alpha(uint64_t& k, double x0, double x1) const noexcept {
  // The input moves on to the next span within kLanding of a span's end
  // (handle_stops): so does this search, or a simulated brake from such a
  // point would take the harder limit of the span left behind, which the
  // real step there does not (seed 6 of the random wiggly bands, LC, 250 us).
  while (k + 1 < stail_ && span(k).stop == StopKind::None && x0 >= span(k).b - kLanding) ++k;
  if (k >= stail_ || span(k).stop != StopKind::None) return a_top_;
  double a = chunk_alpha(k, x0);
  for (uint64_t q = k; q < stail_ && span(q).stop == StopKind::None && span(q).a <= x1; ++q) {
    const Span& o = span(q);
    const double oh = (o.b - o.a) / kChunks;
    for (int j = 0; j < kChunks; ++j) {
      const double j0 = o.a + j * oh;
      if (j0 + oh >= x0 && j0 <= x1) a = std::max(a, o.ak[j]);
    }
  }
  return a;
}

// The envelope within a span for braking in discrete steps of T at alpha:
// v^2 - alpha T v falls by exactly 2 alpha times the distance covered by
// such a step, so the curve v = alpha T/2 + sqrt((w_end - alpha T/2)^2 +
// 2 alpha (b - x)) is invariant under it (the continuous sqrt(w_end^2 +
// 2 alpha d) would leave a discrete brake short of every stop).
double Executor::brake_curve(double w_end, double alpha, double d) const noexcept {
  const double h = 0.5 * alpha * T_;
  const double e = std::max(0.0, w_end - h);
  return h + std::sqrt(e * e + 2 * alpha * std::max(0.0, d));
}

double Executor::envelope_at(uint64_t k, double x) const noexcept {
  const Span& s = span(k);
  if (s.stop != StopKind::None) return 0;
  const double h = (s.b - s.a) / kChunks;
  const int c = h > 0 ? std::clamp(static_cast<int>((x - s.a) / h), 0, kChunks - 1) : 0;
  const double ce = c == kChunks - 1 ? s.b : s.a + (c + 1) * h;
  return std::min({ceiling(s), s.wk[c], brake_curve(s.wk[c + 1], s.ak[c], std::max(0.0, ce - x))});
}

// Smallest envelope value over (z0, z1], starting the span search at k
// (moved on to the span holding z1). The envelope falls within a span and
// rises only at span starts, so each span's part is checked at its right
// end; a stop inside is zero.
double Executor::min_envelope(double z0, double z1, uint64_t& k) const noexcept {
  if (z1 > final_end() + kLanding) return 0;
  double m = kInf;
  while (k < stail_) {
    const Span& s = span(k);
    if (s.stop != StopKind::None) {
      if (s.a > z0 && s.a <= z1) return 0;
      if (s.a > z1) break;
      ++k;
      continue;
    }
    if (s.b < z0 || (s.b <= z0 && z1 > z0)) {
      ++k;
      continue;
    }
    m = std::min(m, envelope_at(k, std::min(z1, s.b)));
    if (s.b >= z1) break;
    ++k;
  }
  return m;
}

// ---------------------------------------------------------------------------
// The input

// Whether v exceeds the envelope value w: strictly (bar rounding), or by
// more than the slack on the squares when `loose`.
bool Executor::above(double v, double w, bool loose) const noexcept {
  if (!loose) return v > w * (1 + 1e-12) + kVelEps;
  return v > w && v * v > w * w + env_tol_;
}

// Whether, after a step to velocity v_new (acceleration a_new), the input
// can still brake within the envelope: the fastest brake the history rule
// allows (accelerations still in the window unwind first), at each span's
// envelope acceleration, must stay under the envelope; once the window's
// accelerations are all braking, the envelope guarantees the rest.
bool Executor::safe(double v_new, double a_new, bool loose) const noexcept {
  ++work_.brakes;
  if (v_new < 0) v_new = 0;
  const double xn = x_ + v_new * T_;
  if (step_active_ && xn > step_s_ + kLanding) return false;
  uint64_t k = in_;
  if (above(v_new, min_envelope(x_, xn, k), loose)) return false;
  const int n = n_;
  // Simulated step i (after this one) has a_{k-N} = the sample i+1 older
  // than the newest stored one's N-th predecessor; the window's limits
  // that still apply then are those of samples i+1 .. N-1 back plus the
  // new one.
  auto old_a = [&](int i) { return i == n - 1 ? a_new : ha_[ring(n - 2 - i)]; };
  int last_pos = -1;
  for (int i = 0; i < n; ++i) {
    if (old_a(i) > 0) last_pos = i;
  }
  double cx = xn, cv = v_new;
  for (int i = 0; i <= last_pos && cv > 0; ++i) {
    // The largest limit of the samples 0 .. n-2-i back (prefix maxima,
    // computed once per cycle by plan_input).
    double am = i <= n - 2 ? hmax_[n - 2 - i] : 0.0;
    uint64_t kb = k < stail_ ? k : stail_ - 1;
    const double al = brake_alpha(kb, cx, cx + cv * T_);
    am = std::max(am, al);
    const double a = std::max(-al, old_a(i) - am);
    double nv = cv + a * T_;
    if (nv < 0) nv = 0;
    const double nx = cx + nv * T_;
    if (step_active_ && nx > step_s_ + kLanding) return false;
    if (above(nv, min_envelope(cx, nx, k), loose)) return false;
    cx = nx;
    cv = nv;
  }
  if (cv > 0) {
    if (step_active_) {
      // Brake for the step's end with the smallest envelope acceleration
      // up to it.
      double al = kInf;
      for (uint64_t q = k; q < stail_ && span(q).a <= step_s_; ++q) {
        for (int j = 0; j < kChunks; ++j) al = std::min(al, span(q).ak[j]);
      }
      if (!(al < kInf) || cv * cv > 2 * al * std::max(0.0, step_s_ - cx)) return false;
    }
    uint64_t kq = k;
    if (above(cv, min_envelope(cx, cx, kq), loose)) {
      // Exactly at cx: the envelope of the span holding it.
      while (kq < stail_ && span(kq).stop == StopKind::None && span(kq).b < cx) ++kq;
      if (kq >= stail_ || above(cv, envelope_at(kq, cx), loose)) return false;
    }
  }
  return true;
}

// hmax_[m]: the largest limit of the samples 0 .. m back (m < n_): the
// limits of the window that still apply m steps on, for the brake
// simulations (once per call instead of once per simulated step).
void Executor::prefix_max_alpha() const noexcept {
  double m = 0;
  for (int i = 0; i < n_; ++i) {
    m = std::max(m, halpha_[ring(i)]);
    hmax_[i] = m;
  }
}

void Executor::push_sample(double x, double v, double a, double commit, double alpha) noexcept {
  hist_pos_ = (hist_pos_ + 1) & (kRing - 1);
  hx_[hist_pos_] = x;
  hv_[hist_pos_] = v;
  ha_[hist_pos_] = a;
  hcommit_[hist_pos_] = commit;
  halpha_[hist_pos_] = alpha;
}

void Executor::plan_input(const CycleInputs& in) noexcept {
  const int n = n_;
  // The window after this step: the N-1 newest samples and this one; and
  // the sample leaving it (a_{k-N}), whose limit still applies here.
  double vwin = v_;
  double cap = kInf;
  double alpha_win = 0;
  for (int i = 0; i < n; ++i) {
    const int idx = ring(i);
    if (i < n - 1) vwin = std::max(vwin, hv_[idx]);
    cap = std::min(cap, hcommit_[idx]);
    alpha_win = std::max(alpha_win, halpha_[idx]);
  }
  const double a_old = ha_[ring(n - 1)];
  const Span& s = span(in_);
  double target = std::min({s.vc, std::max(0.0, in.feed_scale) * s.feed, std::max(0.0, in.rapid_scale) * s.rapid});
  if (in.max_velocity < 1e300) target = std::min(target, std::max(0.0, in.max_velocity) * piece(s.piece).inv_speed);
  if (hold_ || aborting_) target = 0;
  // This sample's limits. Its outputs lie between the oldest sample of
  // the window and, ahead, what the input covers in T_f/2 at the velocity
  // it commits to: braking commits to no faster than now (and its outputs
  // to the window's velocity), speeding up to what the window may reach.
  const double back = x_ - y_ + 3 * std::max(v_, vwin) * T_;
  const uint64_t pc_idx = s.piece;
  // Braking: the envelope's acceleration of the span the step ends on;
  // each span's value holds for samples up to one step before it, so the
  // largest over the spans this step may reach.
  uint64_t k_dn = in_;
  const double a_dn = brake_alpha(k_dn, x_, x_ + v_ * T_);
  const double a_up1 = accel_limit(pc_idx, x_ - back, x_ + vwin * (0.5 * tf_ + 2 * T_), std::max(vwin, v_));
  const double c_up = std::max(vwin, v_ + a_up1 * (tf_ + T_));
  const double a_up = std::min(a_up1, accel_limit(pc_idx, x_ - back, x_ + c_up * (0.5 * tf_ + 2 * T_), c_up));
  double lo = std::max(-a_dn, a_old - std::max(alpha_win, a_dn));
  double hi = std::min(a_up, a_old + std::max(alpha_win, a_up));
  lo = std::min(lo, 0.0);
  hi = std::max(hi, 0.0);
  hi = std::min(hi, (cap - v_) / T_);
  if (hi < lo) hi = lo;
  const double want = std::clamp((target - v_) / T_, lo, hi);
  double a = want;
  prefix_max_alpha();  // for safe()
  const bool want_safe = safe(v_ + want * T_, want);
  since_search_ = want_safe ? std::min(since_search_ + 1, kSearchQuiet + 1) : 0;
  if (want_safe) recovering_ = false;
  if (!want_safe) {
    if (!safe(v_ + lo * T_, lo)) {
      // After an override dropped, braking as hard as allowed is the
      // expected reaction, not a broken guarantee. A brake that follows
      // the envelope exactly drifts off it by rounding: not counted.
      if (!recovering_ && !safe(v_ + lo * T_, lo, true)) ++overruns_;
      a = lo;
    } else {
      double l = lo, h = want;
      for (int it = 0; it < 16; ++it) {
        const double m = 0.5 * (l + h);
        (safe(v_ + m * T_, m) ? l : h) = m;
      }
      a = l;
    }
  }
  double vn = v_ + a * T_;
  if (vn < 0) {
    vn = 0;
    a = -v_ / T_;
  }
  double xn = x_ + vn * T_;
  // Land exactly on a stop (or the end of the spans) that is all but
  // reached.
  {
    // The first stop at or after the input (a stop span follows the span
    // ending at it).
    uint64_t k = in_;
    // From (nearly) rest, a gap the braking rules leave (rounding, or a step below
    // the search's resolution) is closed in one step when that takes a
    // small fraction of this step's acceleration bounds.
    double creep = std::max(kCreep, 0.01 * std::min(hi, -lo) * T_ * T_);
    if (v_ * T_ > creep) creep = 0;
    const double reach = std::max(xn + kLanding, x_ + creep);
    while (k < stail_ && span(k).stop == StopKind::None && span(k).b <= reach) ++k;
    double stop_at = final_end();
    if (k < stail_ && span(k).stop != StopKind::None) stop_at = std::min(stop_at, span(k).a);
    if (step_active_) stop_at = std::min(stop_at, step_s_);
    // The remaining distance is within this step's reach (or it would pass
    // the stop): land on it exactly, decelerating.
    const double gap = stop_at - x_;
    if (xn > stop_at - kLanding || (gap <= vn * T_ && gap >= 0) || (gap >= 0 && gap <= creep)) {
      xn = std::max(x_, stop_at);
      vn = (xn - x_) / T_;
      a = (vn - v_) / T_;
      if (a < lo) {
        // Not within this step's braking: get as close as it allows.
        a = lo;
        vn = std::max(0.0, v_ + a * T_);
        xn = std::min(stop_at, x_ + vn * T_);
      }
    }
  }
  // What this sample's limit is valid for: later samples stay within it.
  const double vmax = std::max(vwin, vn);
  const double commit = a >= 0 ? c_up : std::min(vmax, v_);
  push_sample(xn, vn, a, commit, a >= 0 ? a_up : a_dn);
  x_ = xn;
  v_ = vn;
}

void Executor::update_output() noexcept {
  const int n = n_;
  // Relative to the newest position: no drift from a running sum.
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += hx_[ring(i)] - x_;
  const double w = (x_ - hx_[ring(n)]) / tf_;
  b_ = (w - w_) / T_;
  w_ = w;
  y_ = x_ + sum / n;
  if (std::fabs(w_) < kVelEps) w_ = 0;
}

// The input moves on to the next span when it passes the end of its own;
// at a stop it rests until the output has arrived, dwells, then passes it.
void Executor::handle_stops() noexcept {
  while (in_ < stail_) {
    const Span& s = span(in_);
    if (s.stop == StopKind::None) {
      if (x_ >= s.b - kLanding && in_ + 1 < stail_) {
        ++in_;
        continue;
      }
      return;
    }
    if (v_ != 0 || x_ < s.a - kLanding || hold_ || aborting_ || !at_rest()) return;
    if (s.stop == StopKind::Dwell) {
      if (!dwelling_) {
        dwelling_ = true;
        dwell_left_ = piece(s.piece).dwell_s;
      }
      if (dwell_left_ > 0.5 * T_) {
        dwell_left_ -= T_;
        return;
      }
      if (piece(s.piece).spindle_wait && !spindles_at_speed_) {
        waiting_spindle_ = true;
        return;
      }
      dwelling_ = false;
    }
    x_ = s.a;
    ++in_;
  }
}

// The output's piece, and the inputs finished once it passes pieces.
void Executor::advance_output() noexcept {
  // Spans may join several pieces, so the input's piece is only known as
  // "at least the first piece of its span"; the output passes a stop only
  // once the input has left it.
  const uint64_t input_first = in_ < stail_ ? span(in_).piece : ptail_;
  while (out_ < ptail_) {
    const Piece& p = piece(out_);
    bool passed;
    if (p.stop != StopKind::None) {
      passed = out_ < input_first && y_ >= p.s0 - kLanding;
    } else {
      // Up to a stop that follows, the end is the stop's position (the
      // input lands on it exactly; the piece's end may differ by rounding).
      const bool next_stop = out_ + 1 < ptail_ && piece(out_ + 1).stop != StopKind::None;
      const double end = next_stop ? std::min(p.s0 + p.length, piece(out_ + 1).s0) : p.s0 + p.length;
      passed = out_ + 1 < ptail_ && y_ >= end && (next_stop ? out_ + 1 < input_first : piece(out_ + 1).s0 <= y_);
    }
    if (!passed) break;
    completed_ += p.inputs_done;
    ++out_;
  }
  // Everything done: the last piece (a stop) is passed too.
  if (in_ == stail_ && pfin_ == ptail_ && out_ + 1 == ptail_ && at_rest()) {
    completed_ += piece(out_).inputs_done;
    ++out_;
  }
}

void Executor::release() noexcept {
  // Pieces behind the output, unless pieces still to be split may take
  // data from them (within reach_) or the output's last samples lie on
  // them (limits hold over the samples a jerk spans).
  uint64_t keep = out_;
  // Nothing spreads across a stop: with everything split and a stop at
  // the end, later pieces take nothing from these (a look-ahead shorter
  // than the reach would otherwise never free its segments).
  const bool stop_end = pfin_ == ptail_ && last_stop_ != UINT64_MAX && last_stop_ + 1 == ptail_;
  const double back = std::min((pfin_ < ptail_ ? piece(pfin_).s0 : tail_s_) - (stop_end ? 0.0 : 2 * reach_),
                               y_ - 4 * std::max(v_, w_) * T_ - 1e-9);
  uint64_t k = store_.pieces.released();
  while (k < keep && piece(k).s0 + piece(k).length < back) ++k;
  keep = std::min(keep, k);
  // Segments and vertices the kept pieces use; with every piece done, the
  // newest piece's (pieces still to come start there): the builder needs
  // the room when the machine stands at the end of what it published.
  uint64_t seg = UINT64_MAX;
  if (keep < ptail_) {
    seg = piece(keep).seg;
    const uint64_t upto = std::min(ptail_, out_ + 1);
    for (uint64_t q = keep; q < upto; ++q) seg = std::min({seg, piece(q).seg, piece(q).v_lo});
  } else if (ptail_ > store_.pieces.released()) {
    seg = std::min(piece(ptail_ - 1).seg, piece(ptail_ - 1).v_lo);
  }
  store_.pieces.release_upto(keep);
  if (seg != UINT64_MAX) {
    store_.segs.release_upto(seg);
    store_.verts.release_upto(seg);
  }
  sfirst_ = std::max(sfirst_, in_);
}

void Executor::reset(const Pose& pose) noexcept {
  finish_abort();
  clear_history(x_);
  pose_ = pose;
  speed_ = 0;
}

void Executor::finish_abort() noexcept {
  out_ = pfin_ = ptail_;
  in_ = sfirst_ = stail_;
  spans_taken_.store(pfin_, std::memory_order_release);
  store_.pieces.release_upto(ptail_);
  store_.segs.release_upto(store_.segs.published());
  store_.verts.release_upto(store_.verts.published());
  last_stop_ = UINT64_MAX;
  stop_head_ = stop_tail_;
  env_active_ = env_pending_ = env_pending_full_ = env_deferred_ = false;
  ++epoch_;
  abort_done_ = true;
  aborting_ = false;
  hold_ = false;
  step_active_ = false;
  dwelling_ = false;
}

void Executor::eval(uint64_t seq, double offset, Pose& out, double* speed) const noexcept {
  const Piece& p = piece(seq);
  const SegmentRecord& sr = store_.segs.at(p.seg);
  AxisVec pos, d1;
  // The move's end exactly (the curve returns its programmed end point at
  // s == length).
  double local = (p.s0 - sr.s0) + offset;
  if (std::fabs(local - sr.curve.length) <= 1e-12 * (1 + sr.curve.length)) local = sr.curve.length;
  sr.curve.eval(local, pos, &d1);
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
  for (uint64_t k = out_; k < ptail_; ++k) {
    const Piece& p = piece(k);
    if (p.length > 0 && s >= p.s0 - 1e-9 && s <= p.s0 + p.length + 1e-9) {
      eval(k, std::clamp(s - p.s0, 0.0, p.length), out, nullptr);
      return true;
    }
    if (p.s0 > s) break;
  }
  return false;
}

double Executor::stop_distance() const noexcept {
  if (at_rest()) return 0;
  // The fastest brake the history allows, then the envelope's
  // accelerations, until rest.
  const int n = n_;
  prefix_max_alpha();
  double cx = x_, cv = v_;
  uint64_t k = in_;
  for (int i = 0; cv > 0 && i < 10'000'000; ++i) {
    const double al = brake_alpha(k, cx, cx + cv * T_);
    if (!(al > 0)) {
      // A span the envelope's walk has not reached (envelope zero): the
      // input moves there only by the rounding slack (kVelEps), which
      // comes to rest within the step. Braking at zero would loop here
      // for ten million steps.
      cx += cv * T_;
      break;
    }
    double am = al;
    if (i < n) am = std::max(am, hmax_[n - 1 - i]);
    const double old = i < n ? ha_[ring(n - 1 - i)] : -al;
    const double a = std::max(-al, old - am);
    cv = std::max(0.0, cv + a * T_);
    cx += cv * T_;
  }
  return std::max(0.0, cx - y_);
}

// ---------------------------------------------------------------------------

void Executor::run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept {
  ++cycles_;
  work_ = CycleWork{};
  // Limits given while moving, at the first idle moment (before anything
  // new is taken in).
  apply_pending_config();
  ingest();
  const double kf = std::max(0.0, in.feed_scale);
  const double kr = std::max(0.0, in.rapid_scale);
  if (kf != env_feed_ || kr != env_rapid_) {
    if (kf < env_feed_ || kr < env_rapid_) recovering_ = true;
    env_feed_ = kf;
    env_rapid_ = kr;
    // Every ceiling changed: a walk over the whole queue, spread over
    // cycles like any other (until it has passed, spans ahead keep the
    // envelope of the previous overrides: within the machine's limits and
    // the published path, above a lowered feed for a moment).
    envelope_request(true);
  }
  if (!probe_tripped_ && in.probe_input && out_ < ptail_ && piece(out_).probe && !aborting_) {
    probe_tripped_ = true;
    probed_ = pose_;
    aborting_ = true;
  }
  spindles_at_speed_ = in.spindles_at_speed;
  waiting_spindle_ = false;
  handle_stops();
  if (step_active_ && x_ >= step_s_ - kLanding && at_rest()) {
    step_active_ = false;
    hold_ = true;
  }
  const bool resting = in_ >= stail_ || span(in_).stop != StopKind::None || dwelling_;
  if (!resting) {
    plan_input(in);
  } else {
    // The window fills with the resting position (the step from the last
    // velocity to rest is an acceleration like any other).
    const double a_rest = -v_ / T_;
    since_search_ = kSearchQuiet + 1;
    push_sample(x_, 0, a_rest, a_rest < 0 ? v_ : kInf, std::fabs(a_rest));
    v_ = 0;
  }
  update_output();
  if (aborting_ && at_rest()) finish_abort();
  advance_output();
  if (out_ < ptail_) {
    const Piece& p = piece(out_);
    if (p.length > 0) {
      eval(out_, std::clamp(y_ - p.s0, 0.0, p.length), pose_, &speed_);
    } else if (out_ > store_.pieces.released() && piece(out_ - 1).length > 0) {
      eval(out_ - 1, piece(out_ - 1).length, pose_, &speed_);
    }
  }
  release();
  out.position = pose_;
  out.path_velocity = w_ * speed_;
  out.path_acceleration = b_;
  if (out_ < ptail_) {
    const Piece& p = piece(out_);
    const SegmentRecord& sr = store_.segs.at(p.seg);
    out.line = sr.line;
    out.id = sr.id;
    out.tag = sr.tag;
    out.distance_to_go = std::max(0.0, sr.s0 + sr.curve.length - y_);
    out.move_end = sr.curve.end;
  } else {
    out.distance_to_go = 0;
    out.move_end = pose_;
  }
  out.done = is_idle();
  out.waiting_for_spindle = waiting_spindle_;
  out.probe_tripped = probe_tripped_;
  if (probe_tripped_) out.probed_position = probed_;
}

}  // namespace cnc::tp
