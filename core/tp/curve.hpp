// The programmed geometry of one queued move: a straight line or a helix
// (circle, helix or planar spiral in any plane) in the nine axes, with
// derivatives along its path parameter, extendable past both ends (the
// corner smoothing evaluates neighbours beyond their end points).
// Realtime-safe: plain data, no allocation.
#pragma once

#include <array>
#include <cstdint>

#include "core/util/pose.hpp"

namespace cnc::tp {

using AxisVec = std::array<double, kNumAxes>;

enum class CurveKind : uint8_t { Line, Helix };

// Which axes measure the path length (LinuxCNC's rule: XYZ if they move,
// else ABC, else UVW). Feed rates apply to that group.
enum class LengthGroup : uint8_t { Xyz, Abc, Uvw };

struct Curve {
  CurveKind kind = CurveKind::Line;
  LengthGroup group = LengthGroup::Xyz;
  Pose start;
  Pose end;
  double length = 0;  // span of the path parameter s
  AxisVec rate{};     // ds-derivative of every axis that moves linearly
  // Helix part (XYZ): centre + rho(s) (cos(w s) u + sin(w s) v) + h(s) n
  std::array<double, 3> center{};
  std::array<double, 3> u{};
  std::array<double, 3> v{};
  std::array<double, 3> n{};
  double r0 = 0, dr = 0;  // rho(s) = r0 + dr s
  double omega = 0;       // angle per unit s
  double h0 = 0, dh = 0;  // h(s) = h0 + dh s
  // Per-axis bounds of |dP/ds|, |d2P/ds2|, |d3P/ds3| over s in
  // [-extension, length + extension].
  AxisVec bound1{};
  AxisVec bound2{};
  AxisVec bound3{};

  // Position and derivatives at s (outside [0, length] on the extension).
  // s == 0 and s == length give the programmed end points exactly.
  void eval(double s, AxisVec& p, AxisVec* d1 = nullptr, AxisVec* d2 = nullptr, AxisVec* d3 = nullptr) const noexcept;
  // eval on the axes of `axes` only (bit k: axis k); the other entries are
  // left as they were. The same values as eval on those axes.
  void eval_axes(double s, unsigned axes, AxisVec& p, AxisVec& d1, AxisVec& d2, AxisVec& d3) const noexcept;
  bool is_curved() const noexcept { return kind == CurveKind::Helix; }
};

// A straight move; false when nothing moves.
bool make_line(const Pose& from, const Pose& to, double extension, Curve& out) noexcept;

// Arc, helix or spiral from `from` to `to` around the axis through `center`
// along `normal` (counter-clockwise seen from its tip), plus `turns` full
// turns; the radius changes linearly when the end radius differs. False for
// a degenerate circle (zero radius, zero normal, non-finite numbers).
bool make_helix(const Pose& from, const Pose& to, const std::array<double, 3>& center,
                const std::array<double, 3>& normal, int turns, double extension, Curve& out) noexcept;

// Length of the path-defining group of an axis vector (for feed rates).
double group_norm(const AxisVec& v, LengthGroup g) noexcept;

}  // namespace cnc::tp
