// Vertex smoothing of bands of short G64 P lines (the first smoothing
// stage of the path builder, before the corner windows of blend.hpp).
//
// A band is a run of feed lines with the same parameters under G64 with a
// P tolerance. Each interior vertex p_k may move toward the binomial
// average (p_{k-1} + 2 p_k + p_{k+1}) / 4 of its neighbours, by at most a
// budget (a share of P): that removes the alternating part of a band (a
// zig-zag whose wiggle lies inside P becomes a straight line, the noise of
// coordinates rounded to a few decimals is damped) while a polyline along a
// curve keeps its shape. The moved vertex lies within the budget of the
// programmed vertex, hence of both programmed segments it joins; a new
// segment between two moved vertices lies, by convexity of the distance to
// a segment, within the larger of its ends' distances from the programmed
// segment it replaces. That distance is charged to the corner windows'
// tolerance of the segment, so the path as a whole stays within P.
// Band ends (stops, program end, arcs, rapids, other feeds or modes) keep
// their programmed position. Plain functions: no allocation.
#pragma once

#include "core/util/pose.hpp"

namespace cnc::tp {

// Share of G64 P the vertex smoothing may use (the rest is for the corner
// windows; a band left straight needs none).
inline constexpr double kFitShare = 0.6;
// A vertex whose full binomial step is at most this share of P is always
// smoothed (a curve given as a polyline: damps rounding noise, shrinks the
// curve by a negligible amount).
inline constexpr double kFitAlwaysShare = 0.05;

// Distance from p to the segment [a, b] (all axes).
double distance_to_segment(const Pose& p, const Pose& a, const Pose& b) noexcept;

// Where vertex p (between the programmed points prev and next) goes.
// `before` / `after` (may be null: unknown or a band end) are the points
// beyond prev and next, used to tell an alternating band (the turn at p
// opposes a neighbour's turn) from a curve. `budget`: the largest
// displacement; `tol`: the band's G64 P.
Pose smooth_vertex(const Pose* before, const Pose& prev, const Pose& p, const Pose& next, const Pose* after,
                   double budget, double tol) noexcept;

}  // namespace cnc::tp
