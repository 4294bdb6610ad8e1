#include "core/tp/blend.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace cnc::tp {
namespace {

double norm(const AxisVec& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s);
}

// Largest |W''| on [u0, u1].
double max_abs_pdf1(double u0, double u1) {
  double m = std::max(std::fabs(kernel::pdf1(u0)), std::fabs(kernel::pdf1(u1)));
  for (double c : {0.5 - std::sqrt(3.0) / 6, 0.5 + std::sqrt(3.0) / 6}) {
    if (c > u0 && c < u1) m = std::max(m, std::fabs(kernel::pdf1(c)));
  }
  return m;
}

double max_abs_pdf2(double u0, double u1) {
  double m = std::max(std::fabs(kernel::pdf2(u0)), std::fabs(kernel::pdf2(u1)));
  if (u0 < 0.5 && u1 > 0.5) m = std::max(m, 30.0);
  return m;
}

double max_pdf(double u0, double u1) {
  if (u0 <= 0.5 && u1 >= 0.5) return kernel::kPdfMax;
  return std::max(kernel::pdf(u0), kernel::pdf(u1));
}

// Largest |W - H| on [u0, u1]: at the point nearest the centre.
double max_step_error(double u0, double u1) {
  if (u0 <= 0.5 && u1 >= 0.5) return 0.5;
  if (u1 < 0.5) return kernel::cdf(u1);
  return 1 - kernel::cdf(u0);
}

}  // namespace

void add_correction(const Vertex& vx, double x, bool after, const Curve& in, const Curve& out, AxisVec& p,
                    AxisVec* d1, AxisVec* d2, AxisVec* d3) noexcept {
  const double d = vx.half;
  const double u = std::clamp((x + d) / (2 * d), 0.0, 1.0);
  const double e = 2 * d * (kernel::ramp(u) - (after ? u - 0.5 : 0.0));
  const double g = kernel::cdf(u) - (after ? 1.0 : 0.0);
  const double g1 = kernel::pdf(u) / (2 * d);
  const double g2 = kernel::pdf1(u) / (4 * d * d);
  const double g3 = kernel::pdf2(u) / (8 * d * d * d);
  for (unsigned m = vx.axes; m != 0; m &= m - 1) {
    const auto k = static_cast<std::size_t>(std::countr_zero(m));
    const double t = vx.dt[k];
    p[k] += e * t;
    if (d1) (*d1)[k] += g * t;
    if (d2) (*d2)[k] += g1 * t;
    if (d3) (*d3)[k] += g2 * t;
  }
  if (!vx.curved) return;
  AxisVec pi, pi1, pi2, pi3, po, po1, po2, po3;
  in.eval(in.length + x, pi, &pi1, &pi2, &pi3);
  out.eval(x, po, &po1, &po2, &po3);
  for (std::size_t k = 0; k < p.size(); ++k) {
    const double q0 = po[k] - pi[k] - x * vx.dt[k];
    const double q1 = po1[k] - pi1[k] - vx.dt[k];
    const double q2 = po2[k] - pi2[k];
    const double q3 = po3[k] - pi3[k];
    p[k] += g * q0;
    if (d1) (*d1)[k] += g1 * q0 + g * q1;
    if (d2) (*d2)[k] += g2 * q0 + 2 * g1 * q1 + g * q2;
    if (d3) (*d3)[k] += g3 * q0 + 3 * g2 * q1 + 3 * g1 * q2 + g * q3;
  }
}

void add_correction_derivatives(const Vertex& vx, double x, bool after, const Curve& in, const Curve& out,
                                unsigned axes, AxisVec& d1, AxisVec& d2, AxisVec& d3) noexcept {
  add_kink_derivatives(vx, x, after, d1, d2, d3);
  if (!vx.curved) return;
  const double d = vx.half;
  const double u = std::clamp((x + d) / (2 * d), 0.0, 1.0);
  const double g = kernel::cdf(u) - (after ? 1.0 : 0.0);
  const double g1 = kernel::pdf(u) / (2 * d);
  const double g2 = kernel::pdf1(u) / (4 * d * d);
  const double g3 = kernel::pdf2(u) / (8 * d * d * d);
  AxisVec pi, pi1, pi2, pi3, po, po1, po2, po3;
  in.eval_axes(in.length + x, axes, pi, pi1, pi2, pi3);
  out.eval_axes(x, axes, po, po1, po2, po3);
  for (unsigned m = axes; m != 0; m &= m - 1) {
    const auto k = static_cast<std::size_t>(std::countr_zero(m));
    const double q0 = po[k] - pi[k] - x * vx.dt[k];
    const double q1 = po1[k] - pi1[k] - vx.dt[k];
    const double q2 = po2[k] - pi2[k];
    const double q3 = po3[k] - pi3[k];
    d1[k] += g1 * q0 + g * q1;
    d2[k] += g2 * q0 + 2 * g1 * q1 + g * q2;
    d3[k] += g3 * q0 + 3 * g2 * q1 + 3 * g1 * q2 + g * q3;
  }
}

unsigned curved_correction_axes(const Vertex& vx, const Curve& in, const Curve& out) noexcept {
  unsigned axes = vx.axes;
  for (std::size_t k = 0; k < in.rate.size(); ++k) {
    const bool helix = k < 3 && (in.is_curved() || out.is_curved());
    if (helix || in.rate[k] != 0 || out.rate[k] != 0 || in.start.v[k] != out.start.v[k] ||
        in.end.v[k] != out.start.v[k]) {
      axes |= 1u << k;
    }
  }
  return axes;
}

void add_correction_bounds(const Vertex& vx, double x0, double x1, const Curve& in, const Curve& out, AxisVec& b1,
                           AxisVec& b2, AxisVec& b3, AxisVec* b4) noexcept {
  const double d = vx.half;
  if (!(d > 0)) return;
  x0 = std::max(x0, -d);
  x1 = std::min(x1, d);
  if (x1 < x0) return;
  const double u0 = (x0 + d) / (2 * d);
  const double u1 = (x1 + d) / (2 * d);
  const double g0 = max_step_error(u0, u1);
  const double g1 = max_pdf(u0, u1) / (2 * d);
  const double g2 = max_abs_pdf1(u0, u1) / (4 * d * d);
  const double g4 = b4 ? max_abs_pdf2(u0, u1) / (8 * d * d * d) : 0.0;
  for (unsigned m = vx.axes; m != 0; m &= m - 1) {  // the others add nothing (the factors are finite)
    const auto k = static_cast<std::size_t>(std::countr_zero(m));
    const double t = std::fabs(vx.dt[k]);
    b1[k] += t * g0;
    b2[k] += t * g1;
    b3[k] += t * g2;
    if (b4) (*b4)[k] += t * g4;
  }
  if (!vx.curved) return;
  const double g3 = max_abs_pdf2(u0, u1) / (8 * d * d * d);
  const double xm = std::max(std::fabs(x0), std::fabs(x1));
  for (std::size_t k = 0; k < b2.size(); ++k) {
    const double m2 = in.bound2[k] + out.bound2[k];
    const double m3 = in.bound3[k] + out.bound3[k];
    const double q0 = 0.5 * m2 * xm * xm;
    const double q1 = m2 * xm;
    b1[k] += g1 * q0 + g0 * q1;
    b2[k] += g2 * q0 + 2 * g1 * q1 + g0 * m2;
    b3[k] += g3 * q0 + 3 * g2 * q1 + 3 * g1 * m2 + g0 * m3;
  }
}

double correction_size(const Vertex& vx, const Curve& in, const Curve& out) noexcept {
  double size = kernel::kDeviationPerHalfWidth * vx.half * norm(vx.dt);
  if (vx.curved) {
    AxisVec m2{};
    for (std::size_t k = 0; k < m2.size(); ++k) m2[k] = in.bound2[k] + out.bound2[k];
    size += 0.25 * norm(m2) * vx.half * vx.half;
  }
  return size;
}

}  // namespace cnc::tp
