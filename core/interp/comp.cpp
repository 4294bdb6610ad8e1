// Cutter radius compensation (G41/G42, G41.1/G42.1) in the XY and XZ
// planes: the tool path is the programmed path offset by the tool radius;
// convex corners get an arc around the programmed corner, concave corners
// move the previous move's end to the intersection of the offset paths.
// One move is held back so its end can still change (LinuxCNC does the
// same with its canon queue).
#include <cmath>

#include "core/interp/impl.hpp"
#include "core/interp/queueing_canon.hpp"

namespace cnc::interp {

namespace {
struct V2 {
  double x = 0, y = 0;
};
V2 operator+(V2 a, V2 b) { return {a.x + b.x, a.y + b.y}; }
V2 operator-(V2 a, V2 b) { return {a.x - b.x, a.y - b.y}; }
V2 operator*(V2 a, double k) { return {a.x * k, a.y * k}; }
double dot(V2 a, V2 b) { return a.x * b.x + a.y * b.y; }
double cross(V2 a, V2 b) { return a.x * b.y - a.y * b.x; }
double len(V2 a) { return std::hypot(a.x, a.y); }
V2 unit(V2 a) {
  const double l = len(a);
  return l > 0 ? a * (1.0 / l) : V2{};
}
V2 left_of(V2 d) { return {-d.y, d.x}; }

// Intersections of two circles / a line and a circle, nearest to `near`.
// Of two intersections, the one the held-back move reaches first going
// backwards from its end (a concave corner shortens that move).
V2 pick(V2 a1, V2 a2, V2 prev_end, V2 t_prev) {
  const double k1 = dot(a1 - prev_end, t_prev), k2 = dot(a2 - prev_end, t_prev);
  const bool b1 = k1 <= 1e-9, b2 = k2 <= 1e-9;
  if (b1 != b2) return b1 ? a1 : a2;
  return len(a1 - prev_end) <= len(a2 - prev_end) ? a1 : a2;
}

bool line_circle(V2 p, V2 d, V2 c, double r, V2 prev_end, V2 t_prev, V2& out) {
  const V2 f = p - c;
  const double b = dot(f, d), cc = dot(f, f) - r * r;
  const double disc = b * b - cc;
  if (disc < 0) return false;
  const double s = std::sqrt(disc);
  out = pick(p + d * (-b - s), p + d * (-b + s), prev_end, t_prev);
  return true;
}
bool circle_circle(V2 c1, double r1, V2 c2, double r2, V2 prev_end, V2 t_prev, V2& out) {
  const double d = len(c2 - c1);
  if (d < 1e-12 || d > r1 + r2 || d < std::fabs(r1 - r2)) return false;
  const double a = (r1 * r1 - r2 * r2 + d * d) / (2 * d);
  const double h = std::sqrt(std::max(0.0, r1 * r1 - a * a));
  const V2 u = unit(c2 - c1);
  const V2 m = c1 + u * a;
  out = pick(m + left_of(u) * h, m - left_of(u) * h, prev_end, t_prev);
  return true;
}
}  // namespace

namespace {
// Turn (radians) below which a convex corner is joined without an arc.
constexpr double kConvexCornerTolerance = 0.05;

struct Geo {
  bool arc = false;
  V2 start, end;  // tool centre
  V2 center;
  double radius = 0;
  int rotation = 0;
  V2 t_start, t_end;  // unit tangents of the programmed path
};

V2 arc_tangent(V2 center, V2 p, int rotation) {
  const V2 radial = unit(p - center);
  return rotation > 0 ? left_of(radial) : left_of(radial) * -1.0;
}
}  // namespace

void Interpreter::State::comp_emit(const CompMove& m) {
  queueing.count_output();
  Canon& out = queueing.real();
  if (m.kind == CompMove::Traverse) {
    out.straight_traverse(m.line, m.end);
  } else if (m.kind == CompMove::Feed) {
    out.straight_feed(m.line, m.end);
  } else {
    out.arc_feed(m.line, m.first_end, m.second_end, m.center1, m.center2, m.rotation, m.axis_end, m.end);
  }
}

void Interpreter::State::comp_flush() {
  auto& q = queueing.queue();
  while (!q.empty()) {
    QueuedCall c = std::move(q.front());
    q.pop_front();
    if (c.is_move) {
      comp_emit(c.move);
    } else {
      c.call();
    }
  }
}

CompMove* Interpreter::State::held_move() {
  auto& q = queueing.queue();
  for (auto it = q.rbegin(); it != q.rend(); ++it) {
    if (it->is_move) return &it->move;
  }
  return nullptr;
}

void Interpreter::State::hold_move(const CompMove& m) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  queueing.count_output();
  queueing.queue().push_back(QueuedCall{true, m, {}});
  // the move starts where the tool is now
  queueing.queue().back().move.start1 = pos[a1];
  queueing.queue().back().move.start2 = pos[a2];
}

void Interpreter::State::comp_straight(bool traverse, const Pose& end) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const double r = cutter_radius;
  const bool left = cutter_side == 410;
  const V2 p0{comp_program_pos[a1], comp_program_pos[a2]};
  const V2 p1{end[a1], end[a2]};
  const V2 tool{pos[a1], pos[a2]};
  CompMove m;
  m.kind = traverse ? CompMove::Traverse : CompMove::Feed;
  m.line = current_line;
  m.end = end;
  if (cutter_first_move) {
    // Entry (LinuxCNC 2.9): the tool ends beside the programmed end point,
    // offset perpendicular to the entry move.
    const double d = len(p1 - tool);
    if (d <= r) fail("Length of cutter compensation entry move is not greater than the tool radius");
    const V2 dir = unit(p1 - tool);
    const V2 t = p1 + (left ? left_of(dir) : left_of(dir) * -1.0) * r;
    m.end[a1] = t.x;
    m.end[a2] = t.y;
    comp_flush();
    hold_move(m);
    // Corners after the entry treat it as the programmed direction, offset
    // to pass through its end (LinuxCNC 2.9).
    last_tangent_x = dir.x;
    last_tangent_y = dir.y;
    last_curvature = 0;
    cutter_first_move = false;
    comp_program_pos = end;
    pos = m.end;
    return;
  }
  const V2 d = unit(p1 - p0);
  if (len(p1 - p0) < 1e-12) {
    // no motion in the plane: other axes only
    Pose e = pos;
    for (int i = 0; i < kNumAxes; ++i) {
      if (i != a1 && i != a2) e[i] = end[i];
    }
    m.end = e;
    comp_flush();
    hold_move(m);
    comp_program_pos = end;
    pos = e;
    return;
  }
  // The offset from the direction's angle, as LinuxCNC computes it: the
  // residue of sin(pi) decides the sign of a zero in the printed output.
  const double theta = std::atan2(p1.y - p0.y, p1.x - p0.x);
  double normal = left ? theta + kPi / 2 : theta - kPi / 2;
  if (normal <= -kPi) normal += 2 * kPi;
  const V2 n{std::cos(normal), std::sin(normal)};
  Geo g;
  g.start = p0 + n * r;
  g.end = p1 + n * r;
  g.t_start = g.t_end = d;
  comp_corner(V2Ref{g.start.x, g.start.y}, V2Ref{d.x, d.y}, false, V2Ref{}, 0, 0);
  // comp_corner may have changed where this move starts (concave corner)
  m.end[a1] = g.end.x;
  m.end[a2] = g.end.y;
  hold_move(m);
  last_tangent_x = d.x;
  last_tangent_y = d.y;
  last_curvature = 0;
  comp_program_pos = end;
  pos = m.end;
}

void Interpreter::State::comp_arc(int g, const Pose& end, double c1, double c2, int rotation) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  (void)g;
  const double r = cutter_radius;
  const bool left = cutter_side == 410;
  const V2 p0{comp_program_pos[a1], comp_program_pos[a2]};
  const V2 p1{end[a1], end[a2]};
  V2 c{c1, c2};
  const double R = len(p1 - c);
  // tool inside the arc when the comp side faces the centre
  const bool inside = (rotation > 0) == left;
  // The arc the tool follows to `to` about `centre`, and the state after it
  // (tangent and curvature at the programmed end `p1`).
  auto arc_move = [&](const V2& to, const V2& centre) {
    CompMove m;
    m.kind = CompMove::Arc;
    m.line = current_line;
    m.end = end;
    m.end[a1] = to.x;
    m.end[a2] = to.y;
    m.first_end = to.x;
    m.second_end = to.y;
    m.center1 = centre.x;
    m.center2 = centre.y;
    m.rotation = rotation;
    m.axis_end = end[a3];
    return m;
  };
  auto after_arc = [&](const V2& tangent_center, const Pose& tool_end) {
    const V2 t1 = arc_tangent(tangent_center, p1, rotation);
    last_tangent_x = t1.x;
    last_tangent_y = t1.y;
    last_curvature = rotation > 0 ? 1 / R : -1 / R;
    comp_program_pos = end;
    pos = tool_end;
  };
  if (cutter_first_move) {
    // Entry arc (LinuxCNC 2.9): from where the tool is to the offset end
    // point, about a centre moved along the radius through that end until
    // it is as far from both ends. The tool must start farther than its
    // radius from the programmed end.
    const V2 tool{pos[a1], pos[a2]};
    if (len(p1 - tool) <= r) fail("Radius of cutter compensation entry arc is not greater than the tool radius");
    const double tr = inside ? R - r : R + r;
    if (tr <= 0) fail("Tool radius not less than arc radius with comp");
    const V2 u = unit(p1 - c);
    const V2 e = c + u * tr;
    // |c + u*k - tool| = |c + u*k - e| = tr - k, solved for k
    const V2 w = c - tool;
    const double k = (tr * tr - dot(w, w)) / (2 * (dot(w, u) + tr));
    c = c + u * k;
    const CompMove m = arc_move(e, c);
    comp_flush();
    hold_move(m);
    cutter_first_move = false;
    after_arc(V2{c1, c2}, m.end);
    return;
  }
  // A centre-format arc's two radii may differ within the tolerance: the
  // tool path starts beside the programmed start and ends beside the
  // programmed end (with a zero radius tool exactly there, as in LinuxCNC);
  // a concave corner before it meets the circle through its start.
  const double tr = inside ? R - r : R + r;
  const double R0 = len(p0 - c);
  const double tr_start = inside ? R0 - r : R0 + r;
  if (tr <= 0 || tr_start <= 0) fail("Tool radius not less than arc radius with comp");
  const V2 s = c + unit(p0 - c) * tr_start;
  const V2 e = c + unit(p1 - c) * tr;
  const V2 t0 = arc_tangent(c, p0, rotation);
  comp_corner(V2Ref{s.x, s.y}, V2Ref{t0.x, t0.y}, true, V2Ref{c.x, c.y}, tr_start, rotation);
  const CompMove m = arc_move(e, c);
  hold_move(m);
  after_arc(c, m.end);
}

// Joins the held-back move to a new one starting (offset) at `start` with
// programmed tangent `t_new` at the programmed corner.
void Interpreter::State::comp_corner(V2Ref start_ref, V2Ref t_new_ref, bool new_is_arc, V2Ref center_ref, double tool_r, int rotation) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const V2 start{start_ref.x, start_ref.y};
  const V2 t_new{t_new_ref.x, t_new_ref.y};
  const V2 corner{comp_program_pos[a1], comp_program_pos[a2]};
  const bool left = cutter_side == 410;
  CompMove* held = held_move();
  if (held == nullptr) return;
  CompMove& prev = *held;
  const V2 prev_end{prev.end[a1], prev.end[a2]};
  const V2 t_prev{last_tangent_x, last_tangent_y};
  const double turn = cross(t_prev, t_new);
  const double along = dot(t_prev, t_new);
  if (len(prev_end - start) < 1e-9) {
    comp_flush();
    return;
  }
  bool convex = left ? turn < 0 : turn > 0;
  if (std::fabs(turn) < 1e-12 && along > 0) {
    comp_flush();
    return;
  }
  if (std::fabs(turn) < 1e-12) {
    // Reversal: the new path leaves along the old one backwards. It is a
    // concave corner when the new path runs off to the side away from the
    // tool (the tool then sits between the two paths), so the offsets
    // cross; otherwise the tool turns around the corner (two lines, or
    // arcs of the same bend, turn around it too).
    double k_new = 0;
    if (new_is_arc) {
      const double rp = len(corner - V2{center_ref.x, center_ref.y});
      k_new = rotation > 0 ? 1 / rp : -1 / rp;
    }
    const double spread = k_new + last_curvature;  // > 0: new path left of the old one reversed
    convex = std::fabs(spread) < 1e-12 || (left ? spread > 0 : spread < 0);
  }
  // A convex corner turning less than 0.05 rad gets no arc: the new move
  // goes on from where the held-back one ends (LinuxCNC 2.9 does the same;
  // the step is at most the tool radius times the angle).
  if (convex && std::atan2(std::fabs(turn), along) < kConvexCornerTolerance) {
    comp_flush();
    return;
  }
  // concave: meet where the offset paths cross
  V2 x;
  bool ok = false;
  const bool prev_arc = prev.kind == CompMove::Arc;
  if (convex) {
  } else if (!prev_arc && !new_is_arc) {
    const double den = cross(t_prev, t_new);
    if (std::fabs(den) < 1e-12) fail("Cannot intersect parallel lines");
    const double k = cross(start - prev_end, t_new) / den;
    x = prev_end + t_prev * k;
    ok = true;
  } else if (!prev_arc && new_is_arc) {
    ok = line_circle(prev_end, t_prev, V2{center_ref.x, center_ref.y}, tool_r, prev_end, t_prev, x);
  } else if (prev_arc && !new_is_arc) {
    const V2 pc{prev.center1, prev.center2};
    ok = line_circle(start, t_new, pc, len(prev_end - pc), prev_end, t_prev, x);
  } else {
    const V2 pc{prev.center1, prev.center2};
    ok = circle_circle(pc, len(prev_end - pc), V2{center_ref.x, center_ref.y}, tool_r, prev_end, t_prev, x);
  }
  // A concave corner turning more than a right angle with an arc, where
  // the offset paths do not meet: the tool turns around the corner instead
  // of refusing a gouge (LinuxCNC's crazy-paths runs so).
  if (!convex && !ok && along < 0 && (prev_arc || new_is_arc)) convex = true;
  if (convex) {
    const CompMove before = prev;
    comp_flush();  // prev is gone after this
    CompMove a;
    a.kind = CompMove::Arc;
    a.line = current_line;
    a.end = before.end;
    a.end[a1] = start.x;
    a.end[a2] = start.y;
    a.first_end = start.x;
    a.second_end = start.y;
    a.center1 = corner.x;
    a.center2 = corner.y;
    a.rotation = left ? -1 : 1;
    a.axis_end = before.end[a3];
    comp_emit(a);
    pos = a.end;
    return;
  }
  if (!ok) {
    fail(new_is_arc ? "Arc move in concave corner cannot be reached by the tool without gouging"
                    : "Straight feed in concave corner cannot be reached by the tool without gouging");
  }
  // A held-back line whose end would have to lie behind its start, against
  // its programmed direction, makes the tool run backwards and cut into the
  // corner's other side (LinuxCNC refuses this gouge too).
  if (!prev_arc) {
    const V2 prev_start{prev.start1, prev.start2};
    if (dot(x - prev_start, t_prev) < 0) {
      fail(new_is_arc ? "Arc move in concave corner cannot be reached by the tool without gouging"
                      : "Straight feed in concave corner cannot be reached by the tool without gouging");
    }
  }
  prev.end[a1] = x.x;
  prev.end[a2] = x.y;
  if (prev_arc) {
    prev.first_end = x.x;
    prev.second_end = x.y;
  }
  const Pose joined = prev.end;
  comp_flush();  // prev is gone after this
  pos = joined;
}

}  // namespace cnc::interp
