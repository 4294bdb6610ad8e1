#include "core/tp/curve.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>

namespace cnc::tp {
namespace {

double norm3(double x, double y, double z) { return std::sqrt(x * x + y * y + z * z); }

bool finite_pose(const Pose& p) {
  for (double x : p.v) {
    if (!std::isfinite(x)) return false;
  }
  return true;
}

}  // namespace

double group_norm(const AxisVec& v, LengthGroup g) noexcept {
  const int o = static_cast<int>(g) * 3;
  return norm3(v[static_cast<std::size_t>(o)], v[static_cast<std::size_t>(o + 1)], v[static_cast<std::size_t>(o + 2)]);
}

void Curve::eval(double s, AxisVec& p, AxisVec* d1, AxisVec* d2, AxisVec* d3) const noexcept {
  // A helix sets its first three axes itself; the linear terms of the
  // others (all of them on a line) are the same loop either way.
  const std::size_t first = kind == CurveKind::Helix ? 3 : 0;
  for (std::size_t k = first; k < p.size(); ++k) p[k] = start.v[k] + rate[k] * s;
  if (d1) *d1 = rate;
  if (d2) d2->fill(0.0);
  if (d3) d3->fill(0.0);
  if (kind == CurveKind::Helix) {
    const double phi = omega * s;
    const double c = std::cos(phi);
    const double sn = std::sin(phi);
    const double rho = r0 + dr * s;
    const double h = h0 + dh * s;
    for (std::size_t k = 0; k < 3; ++k) {
      const double e = c * u[k] + sn * v[k];
      const double f = -sn * u[k] + c * v[k];
      p[k] = center[k] + rho * e + h * n[k];
      if (d1) (*d1)[k] = dr * e + rho * omega * f + dh * n[k];
      if (d2) (*d2)[k] = 2 * dr * omega * f - rho * omega * omega * e;
      if (d3) (*d3)[k] = -3 * dr * omega * omega * e - rho * omega * omega * omega * f;
    }
  }
  if (s == 0) {
    p = start.v;
  } else if (s == length) {
    p = end.v;
  }
}

void Curve::eval_axes(double s, unsigned axes, AxisVec& p, AxisVec& d1, AxisVec& d2, AxisVec& d3) const noexcept {
  const bool helix = kind == CurveKind::Helix;
  const unsigned turning = helix ? axes & 7u : 0u;
  for (unsigned m = axes & ~turning; m != 0; m &= m - 1) {
    const auto k = static_cast<std::size_t>(std::countr_zero(m));
    p[k] = start.v[k] + rate[k] * s;
    d1[k] = rate[k];
    d2[k] = 0.0;
    d3[k] = 0.0;
  }
  if (turning != 0) {
    const double phi = omega * s;
    const double c = std::cos(phi);
    const double sn = std::sin(phi);
    const double rho = r0 + dr * s;
    const double h = h0 + dh * s;
    for (unsigned m = turning; m != 0; m &= m - 1) {
      const auto k = static_cast<std::size_t>(std::countr_zero(m));
      const double e = c * u[k] + sn * v[k];
      const double f = -sn * u[k] + c * v[k];
      p[k] = center[k] + rho * e + h * n[k];
      d1[k] = dr * e + rho * omega * f + dh * n[k];
      d2[k] = 2 * dr * omega * f - rho * omega * omega * e;
      d3[k] = -3 * dr * omega * omega * e - rho * omega * omega * omega * f;
    }
  }
  if (s == 0 || s == length) {
    const Pose& at = s == 0 ? start : end;
    for (unsigned m = axes; m != 0; m &= m - 1) {
      const auto k = static_cast<std::size_t>(std::countr_zero(m));
      p[k] = at.v[k];
    }
  }
}

bool make_line(const Pose& from, const Pose& to, double extension, Curve& out) noexcept {
  (void)extension;
  if (!finite_pose(from) || !finite_pose(to)) return false;
  AxisVec d{};
  for (std::size_t k = 0; k < d.size(); ++k) d[k] = to.v[k] - from.v[k];
  double len = 0;
  LengthGroup group = LengthGroup::Xyz;
  for (LengthGroup g : {LengthGroup::Xyz, LengthGroup::Abc, LengthGroup::Uvw}) {
    len = group_norm(d, g);
    group = g;
    if (len > 1e-12) break;
  }
  if (!(len > 1e-12)) return false;
  out = Curve{};
  out.kind = CurveKind::Line;
  out.group = group;
  out.start = from;
  out.end = to;
  out.length = len;
  for (std::size_t k = 0; k < d.size(); ++k) {
    out.rate[k] = d[k] / len;
    out.bound1[k] = std::fabs(out.rate[k]);
  }
  return true;
}

bool make_helix(const Pose& from, const Pose& to, const std::array<double, 3>& center,
                const std::array<double, 3>& normal, int turns, double extension, Curve& out) noexcept {
  if (!finite_pose(from) || !finite_pose(to) || turns < 0) return false;
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(center[static_cast<std::size_t>(i)]) || !std::isfinite(normal[static_cast<std::size_t>(i)])) {
      return false;
    }
  }
  const double nn = norm3(normal[0], normal[1], normal[2]);
  if (!(nn > 1e-12)) return false;
  Curve c;
  c.kind = CurveKind::Helix;
  c.group = LengthGroup::Xyz;
  c.start = from;
  c.end = to;
  c.center = center;
  for (int i = 0; i < 3; ++i) c.n[static_cast<std::size_t>(i)] = normal[static_cast<std::size_t>(i)] / nn;
  std::array<double, 3> sc{}, ec{};
  for (std::size_t i = 0; i < 3; ++i) {
    sc[i] = from.v[i] - center[i];
    ec[i] = to.v[i] - center[i];
  }
  const double h0 = sc[0] * c.n[0] + sc[1] * c.n[1] + sc[2] * c.n[2];
  const double h1 = ec[0] * c.n[0] + ec[1] * c.n[1] + ec[2] * c.n[2];
  std::array<double, 3> rs{}, re{};
  for (std::size_t i = 0; i < 3; ++i) {
    rs[i] = sc[i] - h0 * c.n[i];
    re[i] = ec[i] - h1 * c.n[i];
  }
  const double r0 = norm3(rs[0], rs[1], rs[2]);
  const double r1 = norm3(re[0], re[1], re[2]);
  if (!(r0 > 1e-9) || !(r1 > 1e-9)) return false;
  for (std::size_t i = 0; i < 3; ++i) c.u[i] = rs[i] / r0;
  c.v = {c.n[1] * c.u[2] - c.n[2] * c.u[1], c.n[2] * c.u[0] - c.n[0] * c.u[2], c.n[0] * c.u[1] - c.n[1] * c.u[0]};
  double angle = std::atan2(re[0] * c.v[0] + re[1] * c.v[1] + re[2] * c.v[2],
                            re[0] * c.u[0] + re[1] * c.u[1] + re[2] * c.u[2]);
  if (angle < 1e-9) angle += 2 * std::numbers::pi;
  angle += 2 * std::numbers::pi * turns;
  const double height = h1 - h0;
  const double len = std::hypot(0.5 * (r0 + r1) * angle, height);
  if (!(len > 1e-12) || !std::isfinite(len)) return false;
  c.length = len;
  c.r0 = r0;
  c.dr = (r1 - r0) / len;
  c.omega = angle / len;
  c.h0 = h0;
  c.dh = height / len;
  for (std::size_t k = 3; k < c.rate.size(); ++k) {
    c.rate[k] = (to.v[k] - from.v[k]) / len;
    c.bound1[k] = std::fabs(c.rate[k]);
  }
  const double rho_max = std::max({std::fabs(r0 - c.dr * extension), std::fabs(r0 + c.dr * (len + extension)), r0, r1});
  const double w = std::fabs(c.omega);
  for (std::size_t i = 0; i < 3; ++i) {
    const double m = std::hypot(c.u[i], c.v[i]);
    c.bound1[i] = (std::fabs(c.dr) + rho_max * w) * m + std::fabs(c.dh * c.n[i]);
    c.bound2[i] = (2 * std::fabs(c.dr) * w + rho_max * w * w) * m;
    c.bound3[i] = (3 * std::fabs(c.dr) * w * w + rho_max * w * w * w) * m;
  }
  out = c;
  return true;
}

}  // namespace cnc::tp
