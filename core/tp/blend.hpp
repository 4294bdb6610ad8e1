// Corner and transition smoothing. The programmed path P(s) is a chain of
// curves; at a junction j (path position s_j, tangent jump dt_j) the kink
// term H(s - s_j) (s - s_j) dt_j is replaced by its convolution with a
// smooth kernel of half width d_j, and any curvature jump by a smoothstep
// blend of the two extended curves. Outside [s_j - d_j, s_j + d_j] the path
// is untouched; windows may overlap (their corrections add), which is what
// turns a CAM polyline into a curve with continuous, slowly varying
// curvature. The result is C2 in s with a bounded third derivative, so a
// jerk-limited motion along it has bounded per-axis jerk.
// Realtime-safe: plain functions, no allocation.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/tp/curve.hpp"

namespace cnc::tp {

// Kernel: the Beta(3,3) density on the window, u = (s - s_j + d) / 2d.
namespace kernel {
// cdf, pdf, pdf1 and ramp also take GCC vector types (two samples at once:
// the same operations in the same order, so the same values as one at a
// time).
template <class T>
inline T cdf(T u) noexcept { return u * u * u * (10.0 + u * (-15.0 + 6.0 * u)); }  // W
template <class T>
inline T pdf(T u) noexcept {  // dW/du
  const T t = u * (1.0 - u);
  return 30.0 * t * t;
}
template <class T>
inline T pdf1(T u) noexcept { return 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u); }  // d2W/du2
inline double pdf2(double u) noexcept { return 60 * (1 + u * (-6 + 6 * u)); }     // d3W/du3
template <class T>
inline T ramp(T u) noexcept { return u * u * u * u * (2.5 + u * (-3.0 + u)); }  // integral of W
// Largest deviation of the smoothed ramp from the ramp, per unit of d:
// 2 (ramp(1/2)) = 0.15625.
inline constexpr double kDeviationPerHalfWidth = 0.15625;
// max |dW/du| = 1.875, max |d2W/du2| = 5.7735, max |d3W/du3| = 60.
inline constexpr double kPdfMax = 1.875;
inline constexpr double kPdf1Max = 5.773502691896258;
inline constexpr double kPdf2Max = 60.0;
}  // namespace kernel

struct Vertex {
  double s = 0;         // global path position of the junction
  double half = 0;      // half width of the smoothing window (0: none)
  AxisVec dt{};         // tangent of the outgoing curve minus the incoming
  bool curved = false;  // a neighbour is curved: the second-order term applies
  uint16_t axes = 0;    // bit k set: dt[k] is not zero (the only axes the kink term moves)
  uint64_t seg_in = 0;  // the segment ending here; seg_in + 1 starts here
  uint32_t epoch = 0;
};

// Adds the correction of vertex `vx` at x = s - vx.s (|x| < vx.half) to the
// position p and the derivatives that are not null. `after`: the point lies
// on the outgoing curve (the base curve being evaluated there), decided by
// the segment, not by the sign of x (which rounding may flip at x = 0).
// `in` and `out` are the neighbouring curves (used only when vx.curved).
void add_correction(const Vertex& vx, double x, bool after, const Curve& in, const Curve& out, AxisVec& p,
                    AxisVec* d1, AxisVec* d2, AxisVec* d3) noexcept;

// The derivatives add_correction adds (no position), the curvature blend's
// only on the axes of `axes` (curved_correction_axes: on the others its
// terms are zeros of either sign).
void add_correction_derivatives(const Vertex& vx, double x, bool after, const Curve& in, const Curve& out,
                                unsigned axes, AxisVec& d1, AxisVec& d2, AxisVec& d3) noexcept;

// The axes on which the curvature blend of vx.curved corner between `in`
// and `out` may add anything but a zero: those that turn at the corner,
// move on either curve, are the helix's, or where the curves do not meet.
unsigned curved_correction_axes(const Vertex& vx, const Curve& in, const Curve& out) noexcept;

// The derivatives add_correction adds for a corner without a curved
// neighbour (vx.curved false), without the position: the same values.
inline void add_kink_derivatives(const Vertex& vx, double x, bool after, AxisVec& d1, AxisVec& d2,
                                 AxisVec& d3) noexcept {
  const double d = vx.half;
  const double u = std::clamp((x + d) / (2 * d), 0.0, 1.0);
  const double g = kernel::cdf(u) - (after ? 1.0 : 0.0);
  const double g1 = kernel::pdf(u) / (2 * d);
  const double g2 = kernel::pdf1(u) / (4 * d * d);
  for (unsigned m = vx.axes; m != 0; m &= m - 1) {
    const auto k = static_cast<std::size_t>(std::countr_zero(m));
    const double t = vx.dt[k];
    d1[k] += g * t;
    d2[k] += g1 * t;
    d3[k] += g2 * t;
  }
}

// add_kink_derivatives at the samples x = xg[i] - vx.s, i in [0, n) (n
// even), added to rows[k][i] of d1, d2 and d3 for the axes k of vx.axes: two
// samples at a time, the same values where the window reaches the sample
// (|x| < vx.half); elsewhere a zero of either sign (add_kink_derivatives
// adds nothing there), which bounds of absolute values do not see.
inline void add_kink_derivative_rows(const Vertex& vx, bool after, const double* xg, int n, double* const* d1,
                                     double* const* d2, double* const* d3) noexcept {
  using V2 = double __attribute__((vector_size(16)));
  using M2 = long long __attribute__((vector_size(16)));
  const double d = vx.half;
  const double two_d = 2 * d;
  const double four_dd = 4 * d * d;
  const double step = after ? 1.0 : 0.0;
  for (int i = 0; i + 1 < n; i += 2) {
    V2 xs;
    std::memcpy(&xs, xg + i, sizeof xs);
    const V2 x = xs - vx.s;
    const V2 ax = (V2)((M2)x & 0x7fffffffffffffffLL);
    const M2 in = ax < d;
    // Inside the window (x + d) / 2d lies in [0, 1]: the clamp of
    // add_kink_derivatives changes nothing there.
    const V2 u = (x + d) / two_d;
    const V2 g = (V2)((M2)(kernel::cdf(u) - step) & in);
    const V2 g1 = (V2)((M2)(kernel::pdf(u) / two_d) & in);
    const V2 g2 = (V2)((M2)(kernel::pdf1(u) / four_dd) & in);
    for (unsigned m = vx.axes; m != 0; m &= m - 1) {
      const auto k = static_cast<std::size_t>(std::countr_zero(m));
      const double t = vx.dt[k];
      V2 r1, r2, r3;
      std::memcpy(&r1, d1[k] + i, sizeof r1);
      std::memcpy(&r2, d2[k] + i, sizeof r2);
      std::memcpy(&r3, d3[k] + i, sizeof r3);
      r1 += g * t;
      r2 += g1 * t;
      r3 += g2 * t;
      std::memcpy(d1[k] + i, &r1, sizeof r1);
      std::memcpy(d2[k] + i, &r2, sizeof r2);
      std::memcpy(d3[k] + i, &r3, sizeof r3);
    }
  }
}

// Per-axis bounds, over x in [x0, x1] (relative to the vertex), of the
// first, second and third derivatives of the correction, added to b1, b2
// and b3, and (when b4 is given, corners between straight moves only) of
// the fourth derivative.
void add_correction_bounds(const Vertex& vx, double x0, double x1, const Curve& in, const Curve& out, AxisVec& b1,
                           AxisVec& b2, AxisVec& b3, AxisVec* b4 = nullptr) noexcept;

// Largest |correction| over the window (what the deviation budget counts).
double correction_size(const Vertex& vx, const Curve& in, const Curve& out) noexcept;

// Size of one corner's correction at x (relative to the vertex) with half
// width d: |dt| E(x; d), E the smoothed ramp's error (symmetric, largest at
// x = 0 where it is kDeviationPerHalfWidth d), plus, for a corner next to a
// curved move, a bound of the curvature blend's share (m2: bound of the
// norm of the two curves' second derivatives). Zero outside the window.
// Each term grows with d, so a sum over corners only shrinks when windows
// do. `second`, if given, gets a bound of the second derivative over the
// whole window.
inline double correction_norm_at(double dt_norm, double m2, double d, double x, double* second = nullptr) noexcept {
  if (second) *second = dt_norm * kernel::kPdfMax / (2 * d) + 3.1 * m2;
  const double ax = std::fabs(x);
  if (!(d > 0) || ax >= d) return 0;
  const double u = (d - ax) / (2 * d);
  double e = dt_norm * 2 * d * kernel::ramp(u);
  // The curvature blend g q0: |g| = W(u) here, |q0| <= m2 x^2 / 2.
  if (m2 > 0) e += 0.5 * m2 * x * x * kernel::cdf(u);
  return e;
}

// Adds correction_norm_at(dt_norm, m2, d, xs[i] - s) to sums[i] for i in
// [0, n) (d > 0): the same values, two samples at a time (GCC vector
// types: the same operations in the same order on each lane; issue 20: the
// final window check sums every corner near a sample at 17-65 samples).
inline void add_correction_norms(double dt_norm, double m2, double d, double s, const double* xs, int n,
                                 double* sums) noexcept {
  using V2 = double __attribute__((vector_size(16)));
  using M2 = long long __attribute__((vector_size(16)));
  const double c = dt_norm * 2 * d;
  const double c2 = 0.5 * m2;
  const double two_d = 2 * d;
  int i = 0;
  for (; i + 1 < n; i += 2) {
    V2 x, acc;
    std::memcpy(&x, xs + i, sizeof x);
    std::memcpy(&acc, sums + i, sizeof acc);
    const V2 xr = x - s;
    const V2 ax = (V2)((M2)xr & 0x7fffffffffffffffLL);
    const V2 u = (d - ax) / two_d;
    V2 e = c * kernel::ramp(u);
    if (m2 > 0) e += c2 * xr * xr * kernel::cdf(u);
    acc += (V2)((M2)e & (ax < d));
    std::memcpy(sums + i, &acc, sizeof acc);
  }
  for (; i < n; ++i) sums[i] += correction_norm_at(dt_norm, m2, d, xs[i] - s);
}

}  // namespace cnc::tp
