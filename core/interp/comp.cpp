// Cutter radius compensation (G41/G42, G41.1/G42.1) in the XY and XZ
// planes: the tool path is the programmed path offset by the tool radius;
// convex corners get an arc around the programmed corner, concave corners
// move the previous move's end to where the offset paths meet. The last
// move is held back so its end can still change (LinuxCNC does the same
// with its canon queue).
//
// The geometry follows LinuxCNC 2.9's step by step, angles included
// (directions as atan2 angles, quarter and half turns added in long double
// as its M_PI_2l/M_PIl constants make them): the printed output is rounded
// to 4 decimals, and a value computed another way lands on the other side
// of a rounding tie (x.xxxx5) or 1e-4 away where a concave corner meets an
// arc whose start and end radii differ within the tolerance.
#include <cmath>

#include "core/interp/impl.hpp"
#include "core/interp/queueing_canon.hpp"

namespace cnc::interp {

namespace {
constexpr long double kPiL = 3.141592653589793238462643383279502884L;
constexpr long double kHalfPiL = 1.570796326794896619231321691639751442L;
// Corner angle (radians) below which a convex corner needs no arc and
// around which corners count as reversals (LinuxCNC's
// TOLERANCE_CONCAVE_CORNER).
constexpr double kCornerTolerance = 0.05;

// The tool is inside the arc when the compensation side faces its centre.
bool tool_inside_arc(bool left, int turn) { return (left && turn > 0) || (!left && turn < 0); }

// Signed sweep (radians, positive counterclockwise) of an arc from (x1, y1)
// to (x2, y2) about (c1, c2) with `turn` full or partial turns.
double sweep(double x1, double y1, double c1, double c2, int turn, double x2, double y2) {
  if (turn == 0) return 0.0;
  double a = std::atan2(y1 - c2, x1 - c1);
  double b = std::atan2(y2 - c2, x2 - c1);
  if (turn > 0) {
    if (b <= a) b = static_cast<double>(b + 2 * kPiL);
    return static_cast<double>((b - a) + (turn - 1) * (2 * kPiL));
  }
  if (a <= b) a = static_cast<double>(a + 2 * kPiL);
  return static_cast<double>((b - a) + (turn + 1) * (2 * kPiL));
}
}  // namespace

void Interpreter::State::comp_emit(const CompMove& m) {
  queueing.count_output();
  Canon& out = queueing.real();
  CompMove e = m;
  // A lathe tool's controlled point is its nose's centre; its origin (what
  // the machine positions) sits off it by the nose radius in X and Z as the
  // orientation (1-8) says. Orientations 0 and 9 have the origin there.
  const int o = cutter_orientation;
  const double r = cutter_radius;
  if (plane == Plane::XZ && o >= 1 && o <= 8) {
    const double dx = (o == 2 || o == 6 || o == 1) ? -r : (o == 3 || o == 8 || o == 4) ? r : 0.0;
    const double dz = (o == 2 || o == 7 || o == 3) ? -r : (o == 1 || o == 5 || o == 4) ? r : 0.0;
    e.end[0] += dx;
    e.end[2] += dz;
    if (e.kind == CompMove::Arc) {
      e.first_end += dz;
      e.center1 += dz;
      e.second_end += dx;
      e.center2 += dx;
    }
  }
  if (e.kind == CompMove::Traverse) {
    out.straight_traverse(e.line, e.end);
  } else if (e.kind == CompMove::Feed) {
    out.straight_feed(e.line, e.end);
  } else {
    out.arc_feed(e.line, e.first_end, e.second_end, e.center1, e.center2, e.rotation, e.axis_end, e.end);
  }
}

void Interpreter::State::comp_flush() {
  comp_start_valid = false;
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

void Interpreter::State::hold_move(const CompMove& m) {
  queueing.count_output();
  queueing.queue().push_back(QueuedCall{true, m, {}});
}

void Interpreter::State::comp_set_start(double s1, double s2) {
  comp_start1 = s1;
  comp_start2 = s2;
  comp_start_valid = true;
}

// Moves the end of the held-back moves to (e1, e2) in the plane, refusing
// what makes the tool gouge, and sends them on. A line whose new end lies
// behind its start (against its programmed direction) would run backwards
// into the corner's other side; an arc that would sweep further than
// programmed (by more than 0.001 in or 0.0254 mm of angle) would cut past
// the corner.
void Interpreter::State::comp_move_end(double e1, double e2) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  for (QueuedCall& c : queueing.queue()) {
    if (!c.is_move) continue;
    CompMove& m = c.move;
    if (m.kind == CompMove::Arc) {
      const double r1 = std::hypot(m.first_end - m.center1, m.second_end - m.center2);
      const double r2 = std::hypot(e1 - m.center1, e2 - m.center2);
      if (std::fabs(r1 - r2) > 0.01) fail("Cutter compensation generated an arc with mismatched radii (a bug)");
      const double s = sweep(comp_start1, comp_start2, m.center1, m.center2, m.rotation, e1, e2);
      const double slack = units == Units::Mm ? 0.0254 : 0.001;
      if (m.original_sweep != 0.0 && comp_start_valid && std::fabs(s) > std::fabs(m.original_sweep) + slack) {
        fail("Arc move in concave corner cannot be reached by the tool without gouging");
      }
      m.first_end = e1;
      m.second_end = e2;
    } else {
      const double dot = m.dir1 * (e1 - comp_start1) + m.dir2 * (e2 - comp_start2);
      if (comp_start_valid && dot < 0) {
        fail(m.kind == CompMove::Traverse ? "Straight traverse in concave corner cannot be reached by the tool without gouging"
                                          : "Straight feed in concave corner cannot be reached by the tool without gouging");
      }
    }
    m.end[a1] = e1;
    m.end[a2] = e2;
  }
  comp_flush();
  comp_set_start(e1, e2);
}

void Interpreter::State::comp_straight(bool traverse, const Pose& end) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const double r = cutter_radius;
  const bool left = cutter_side == 410;
  const double cx = pos[a1], cy = pos[a2];
  const double px = end[a1], py = end[a2];
  if (!(r > 0.0)) {
    // A zero radius compensates nothing: the move as programmed (LinuxCNC
    // 2.9 too, which then also leaves its first-move state as it is).
    comp_flush();
    if (traverse) {
      emit_traverse(end);
    } else {
      emit_feed(end);
    }
    comp_program_pos = end;
    return;
  }
  CompMove m;
  m.kind = traverse ? CompMove::Traverse : CompMove::Feed;
  m.line = current_line;
  m.end = end;
  if (cutter_first_move) {
    // Entry: the tool ends beside the programmed end point, offset
    // perpendicular to the entry move (from where the tool is).
    if (std::hypot(px - cx, py - cy) <= r) fail("Length of cutter compensation entry move is not greater than the tool radius");
    const double alpha = static_cast<double>(std::atan2(py - cy, px - cx) + (left ? kHalfPiL : -kHalfPiL));
    m.end[a1] = px + r * std::cos(alpha);
    m.end[a2] = py + r * std::sin(alpha);
    m.dir1 = std::cos(alpha);
    m.dir2 = std::sin(alpha);
    comp_flush();
    comp_set_start(cx, cy);
    hold_move(m);
    cutter_first_move = false;
    comp_program_pos = end;
    pos = m.end;
    return;
  }
  const double opx = comp_program_pos[a1], opy = comp_program_pos[a2];
  if (px == opx && py == opy) {
    // No motion in the plane: other axes only, held back with the move
    // before it (a corner after it moves both ends).
    m.end[a1] = cx;
    m.end[a2] = cy;
    hold_move(m);
    comp_program_pos = end;
    pos = m.end;
    return;
  }
  // theta: from the programmed corner to the tool (the offset side of the
  // move before); alpha: the new move's direction; beta: how far the path
  // turns away from the tool side (0 straight on, pi a reversal).
  double theta = std::atan2(cy - opy, cx - opx);
  double alpha = std::atan2(py - opy, px - opx);
  double beta, gamma;
  if (left) {
    if (theta < alpha) theta = static_cast<double>(theta + 2 * kPiL);
    beta = static_cast<double>((theta - alpha) - kHalfPiL);
    gamma = static_cast<double>(kHalfPiL);
  } else {
    if (alpha < theta) alpha = static_cast<double>(alpha + 2 * kPiL);
    beta = static_cast<double>((alpha - theta) - kHalfPiL);
    gamma = static_cast<double>(-kHalfPiL);
  }
  const double end_x = px + r * std::cos(alpha + gamma);
  const double end_y = py + r * std::sin(alpha + gamma);
  const double mid_x = opx + r * std::cos(alpha + gamma);
  const double mid_y = opy + r * std::sin(alpha + gamma);
  const CompMove* prev = nullptr;
  for (const QueuedCall& c : queueing.queue()) {
    if (c.is_move) {
      prev = &c.move;
      break;
    }
  }
  const bool prev_arc = prev != nullptr && prev->kind == CompMove::Arc;
  bool concave = beta < -kCornerTolerance || beta > kPiL + kCornerTolerance;
  // A reversal after an arc that bends away from the tool side is concave.
  if (!concave && beta > kPiL - kCornerTolerance && prev_arc && ((!left && prev->rotation > 0) || (left && prev->rotation < 0))) {
    concave = true;
  }
  if (!concave && beta > kCornerTolerance) {
    // Convex: an arc (a traverse for G0) around the programmed corner to
    // where the new move starts; the normal axis stays.
    comp_move_end(cx, cy);
    CompMove a = m;
    a.end[a1] = mid_x;
    a.end[a2] = mid_y;
    a.end[a3] = pos[a3];
    if (!traverse) {
      a.kind = CompMove::Arc;
      a.first_end = mid_x;
      a.second_end = mid_y;
      a.center1 = opx;
      a.center2 = opy;
      a.rotation = left ? -1 : 1;
      a.axis_end = pos[a3];
    }
    comp_emit(a);
    comp_set_start(mid_x, mid_y);
  } else if (concave) {
    if (!prev_arc) {
      // Line to line: back off along the held line by the radius over the
      // tangent of half the corner.
      const double halfcorner = static_cast<double>((beta + kPiL) / 2.0);
      if (halfcorner == 0.0) fail("Zero degree inside corner is invalid for cutter compensation");
      const double retreat = r / std::tan(halfcorner);
      comp_move_end(cx + retreat * std::cos(theta + gamma), cy + retreat * std::sin(theta + gamma));
    } else {
      // Arc to line: where the held arc's offset circle meets the new
      // move's offset line.
      const double pc1 = prev->center1, pc2 = prev->center2;
      const int pturn = prev->rotation;
      const double oldrad = std::hypot(pc2 - prev->second_end, pc1 - prev->first_end);
      const double base_dir = std::atan2(py - opy, px - opx);
      const double th = static_cast<double>(pturn > 0 ? base_dir + kHalfPiL : base_dir - kHalfPiL);
      const double phi = std::atan2(pc2 - opy, pc1 - opx);
      const bool inside = tool_inside_arc(left, pturn);
      const double oldrad_uncomp = inside ? oldrad + r : oldrad - r;
      const double d = oldrad_uncomp * std::cos(th - phi);
      const double l = (inside ? d - r : d + r) / oldrad;
      if (l > 1.0 || l < -1.0) fail("Arc to straight motion makes a corner the compensated tool can't fit in without gouging");
      const bool minus = inside == (pturn > 0);
      const double angle = static_cast<double>((minus ? -std::acos(l) : std::acos(l)) + th + kPiL);
      comp_move_end(pc1 + oldrad * std::cos(angle), pc2 + oldrad * std::sin(angle));
    }
  } else {
    // Straight on (within the tolerance): the new move starts where the
    // held one ends.
    comp_flush();
    comp_set_start(cx, cy);
  }
  m.end[a1] = end_x;
  m.end[a2] = end_y;
  m.dir1 = px - opx;
  m.dir2 = py - opy;
  hold_move(m);
  comp_program_pos = end;
  pos = m.end;
}

void Interpreter::State::comp_arc(int g, const Pose& end, double c1, double c2, int turn) {
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const double r = cutter_radius;
  const bool left = cutter_side == 410;
  const bool inside = tool_inside_arc(left, turn);
  const double cx = pos[a1], cy = pos[a2];
  const double end_x = end[a1], end_y = end[a2];
  auto arc_move = [&](double e1, double e2, double k1, double k2, double original) {
    CompMove m;
    m.kind = CompMove::Arc;
    m.line = current_line;
    m.end = end;
    m.end[a1] = e1;
    m.end[a2] = e2;
    m.first_end = e1;
    m.second_end = e2;
    m.center1 = k1;
    m.center2 = k2;
    m.rotation = turn;
    m.axis_end = end[a3];
    m.original_sweep = original;
    return m;
  };
  if (!(r > 0.0)) {
    // zero radius: the arc as programmed (see comp_straight)
    comp_flush();
    canon.arc_feed(current_line, end_x, end_y, c1, c2, turn, end[a3], end);
    pos = end;
    comp_program_pos = end;
    return;
  }
  if (cutter_first_move) {
    // Entry arc: the programmed end moves out by the tool radius along the
    // radius; the centre moves along the same radius line until it is as
    // far from where the tool is as from the new end.
    if (std::hypot(end_x - cx, end_y - cy) <= r) fail("Radius of cutter compensation entry arc is not greater than the tool radius");
    const double gamma = inside ? std::atan2(c2 - end_y, c1 - end_x) : std::atan2(end_y - c2, end_x - c1);
    const double e1 = end_x + r * std::cos(gamma);
    const double e2 = end_y + r * std::sin(gamma);
    const double b_len = std::hypot(cy - e2, cx - e1) / 2.0;
    const double ab_ang = std::atan2(c2 - e2, c1 - e1);
    const double a_ang = std::atan2(cy - e2, cx - e1) - ab_ang;
    if (std::fabs(std::cos(a_ang)) < 0.0001) fail("Tool radius not less than arc radius with comp");
    const double c_len = b_len / std::cos(a_ang);
    const double k1 = e1 + c_len * std::cos(ab_ang);
    const double k2 = e2 + c_len * std::sin(ab_ang);
    if (std::fabs(std::hypot(k1 - e1, k2 - e2) - std::hypot(k1 - cx, k2 - cy)) > arc_tolerance()) {
      fail("Bug in tool radius comp");
    }
    comp_flush();
    if (cutter_orientation != 0 && cutter_orientation != 9) {
      // A lathe tool first moves its origin to where the arc starts
      // (otherwise the arc the origin follows is not an arc).
      CompMove f;
      f.kind = CompMove::Feed;
      f.line = current_line;
      f.end = end;
      f.end[a1] = cx;
      f.end[a2] = cy;
      f.end[a3] = pos[a3];
      hold_move(f);
      comp_set_start(cx, cy);
    }
    hold_move(arc_move(e1, e2, k1, k2, sweep(cx, cy, k1, k2, turn, e1, e2)));
    cutter_first_move = false;
    comp_program_pos = end;
    pos = end;
    pos[a1] = e1;
    pos[a2] = e2;
    return;
  }
  const double opx = comp_program_pos[a1], opy = comp_program_pos[a2];
  const double arc_radius = std::hypot(c1 - end_x, c2 - end_y);
  // theta: the held move's direction at the corner; alpha: the arc's
  // starting direction; beta: the turn between them away from the tool.
  double theta = std::atan2(cy - opy, cx - opx);
  theta = static_cast<double>(left ? theta - kHalfPiL : theta + kHalfPiL);
  double delta = std::atan2(c2 - opy, c1 - opx);
  const double alpha = static_cast<double>(g == 30 ? delta - kHalfPiL : delta + kHalfPiL);
  const double beta0 = left ? theta - alpha : alpha - theta;
  const double beta = static_cast<double>(beta0 > 1.5L * kPiL ? beta0 - 2 * kPiL : beta0 < -kHalfPiL ? beta0 + 2 * kPiL : beta0);
  double gamma;
  if ((left && g == 30) || (!left && g == 20)) {
    gamma = std::atan2(c2 - end_y, c1 - end_x);
    if (arc_radius <= r) fail("Tool radius not less than arc radius with comp");
  } else {
    gamma = std::atan2(end_y - c2, end_x - c1);
    delta = static_cast<double>(delta + kPiL);
  }
  const double new_x = end_x + r * std::cos(gamma);
  const double new_y = end_y + r * std::sin(gamma);
  const double original = sweep(opx, opy, c1, c2, turn, end_x, end_y);
  const CompMove* prev = nullptr;
  for (const QueuedCall& c : queueing.queue()) {
    if (c.is_move) {
      prev = &c.move;
      break;
    }
  }
  const bool prev_arc = prev != nullptr && prev->kind == CompMove::Arc;
  if (beta < -kCornerTolerance || beta > kPiL + kCornerTolerance ||
      // a tangent reversal onto an arc with the tool outside it (the middle
      // of an "m", the top of an "h") is concave too
      (std::fabs(beta - kPiL) < kCornerTolerance && !inside)) {
    if (!prev_arc) {
      // Line to arc: where the held line's offset meets the arc's offset
      // circle (through the programmed end).
      const double cyv = static_cast<double>(arc_radius * std::sin(beta - kHalfPiL));
      double dist, angle;
      if (inside) {
        dist = arc_radius - r;
        const double l = (cyv + r) / dist;
        if (l > 1.0 || l < -1.0) fail("Arc move in concave corner cannot be reached by the tool without gouging");
        angle = turn > 0 ? theta + std::asin(l) : theta - std::asin(l);
      } else {
        dist = arc_radius + r;
        const double l = (cyv - r) / dist;
        if (l > 1.0 || l < -1.0) fail("Arc move in concave corner cannot be reached by the tool without gouging");
        angle = static_cast<double>(turn > 0 ? theta + kPiL - std::asin(l) : theta + kPiL + std::asin(l));
      }
      comp_move_end(c1 + dist * std::cos(angle), c2 + dist * std::sin(angle));
    } else {
      // Arc to arc: where the two offset circles meet.
      const double pc1 = prev->center1, pc2 = prev->center2;
      const int pturn = prev->rotation;
      const double oldrad = std::hypot(pc2 - prev->second_end, pc1 - prev->first_end);
      const double newrad = inside ? arc_radius - r : arc_radius + r;
      const double arc_cc = std::hypot(pc2 - c2, pc1 - c1);
      if (oldrad == 0 || arc_cc == 0) fail("Arc to arc motion is invalid because the arcs have the same center");
      const double a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad) / (2 * oldrad * arc_cc);
      if (a > 1.0 || a < -1.0) fail("Arc to arc motion makes a corner the compensated tool can't fit in without gouging");
      const double pullback = std::acos(a);
      const double cc_dir = std::atan2(c2 - pc2, c1 - pc1);
      const bool plus = tool_inside_arc(left, pturn) == (turn > 0);
      const double dir = plus ? cc_dir + pullback : cc_dir - pullback;
      comp_move_end(pc1 + oldrad * std::cos(dir), pc2 + oldrad * std::sin(dir));
    }
  } else if (beta > kCornerTolerance) {
    // Convex: an arc around the programmed corner first (the normal axis
    // stays), then the arc.
    const double mid_x = opx + r * std::cos(delta);
    const double mid_y = opy + r * std::sin(delta);
    comp_flush();
    CompMove a = arc_move(mid_x, mid_y, opx, opy, 0.0);
    a.rotation = left ? -1 : 1;
    a.axis_end = pos[a3];
    a.end[a3] = pos[a3];
    comp_emit(a);
    comp_set_start(mid_x, mid_y);
  } else {
    comp_flush();
    comp_set_start(cx, cy);
  }
  hold_move(arc_move(new_x, new_y, c1, c2, original));
  comp_program_pos = end;
  pos = end;
  pos[a1] = new_x;
  pos[a2] = new_y;
}

}  // namespace cnc::interp
