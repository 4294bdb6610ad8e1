// Motion: straight moves, arcs (IJK and R forms, P turns, three planes),
// probing, spindle-synchronised moves, G28/G30 helpers, canned cycles.
#include <cmath>
#include <cstdio>

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {


const char* plane_upper(int axis) {
  static constexpr const char* names[] = {"X", "Y", "Z", "A", "B", "C", "U", "V", "W"};
  return names[axis];
}
}  // namespace

const char* plane_name(Plane p) {
  switch (p) {
    case Plane::XY: return "XY";
    case Plane::YZ: return "YZ";
    case Plane::XZ: return "XZ";
    case Plane::UV: return "UV";
    case Plane::VW: return "VW";
    case Plane::UW: return "UW";
  }
  return "?";
}

void Interpreter::State::plane_axes(int& a1, int& a2, int& a3) const {
  switch (plane) {
    case Plane::XZ: a1 = 2; a2 = 0; a3 = 1; break;
    case Plane::YZ: a1 = 1; a2 = 2; a3 = 0; break;
    default: a1 = 0; a2 = 1; a3 = 2; break;
  }
}

double Interpreter::State::arc_tolerance() const {
  return units == Units::Inch ? config.center_arc_radius_tolerance_inch : config.center_arc_radius_tolerance_mm;
}

double Interpreter::State::radius_tolerance() const {
  // LinuxCNC's RADIUS_TOLERANCE_INCH (0.00005) and its metric equivalent:
  // the smallest arc radius, and how far an R arc may fall short.
  return units == Units::Inch ? 0.00005 : 0.00005 * kMmPerInch;
}

// Rotates (x, y) by `degrees` counter-clockwise about the origin (LinuxCNC's
// Interp::rotate).
void rotate_xy(double& x, double& y, double degrees) {
  const double t = degrees * kPi / 180.0;
  const double xx = x * std::cos(t) - y * std::sin(t);
  const double yy = x * std::sin(t) + y * std::cos(t);
  x = xx;
  y = yy;
}

// Where the current point is in coordinate system `system` (1-9) with the
// parameters' origin, rotation and G92 offset (LinuxCNC's
// find_current_in_system; `without_tool`: with the tool length offset taken
// off, find_current_in_system_without_tlo).
Pose Interpreter::State::current_in_system(int system, bool without_tool) const {
  Pose p = pos;
  for (int i = 0; i < kNumAxes; ++i) p[i] += axis_offset[i];
  rotate_xy(p[0], p[1], rotation);
  const int base = 5201 + 20 * system;
  for (int i = 0; i < kNumAxes; ++i) {
    p[i] += origin_offset[i] + (without_tool ? tool_offset[i] : 0.0);
    p[i] -= to_program_axis(i, params[static_cast<std::size_t>(base + i)]);
  }
  rotate_xy(p[0], p[1], -params[static_cast<std::size_t>(base + 9)]);
  if (params[5210] != 0.0) {
    for (int i = 0; i < kNumAxes; ++i) p[i] -= to_program_axis(i, params[static_cast<std::size_t>(5211 + i)]);
  }
  return p;
}

// Program coordinates (current units) to absolute machine coordinates in
// the same units: G92 first, then the XY rotation of the G5x system, then
// the G5x origin and the tool length offset.
Pose Interpreter::State::program_to_machine(const Pose& p) const {
  Pose m = p;
  for (int i = 0; i < kNumAxes; ++i) m[i] += axis_offset[i];
  rotate_xy(m[0], m[1], rotation);
  for (int i = 0; i < kNumAxes; ++i) m[i] += origin_offset[i] + tool_offset[i];
  return m;
}

Pose Interpreter::State::machine_to_program(const Pose& m) const {
  Pose p = m;
  for (int i = 0; i < kNumAxes; ++i) p[i] -= origin_offset[i] + tool_offset[i];
  rotate_xy(p[0], p[1], -rotation);
  for (int i = 0; i < kNumAxes; ++i) p[i] -= axis_offset[i];
  return p;
}

Pose Interpreter::State::find_ends(bool g53) const {
  // Under compensation axes not named keep their programmed (not the
  // offset tool's) position (after G40 the position is the programmed one).
  const Pose& base = cutter_side != 400 ? comp_program_pos : pos;
  Pose end = base;
  auto word = [&](int i, double& v) {
    if (!((config.axis_mask >> i) & 1u) || !block.has_word(kLetters[i])) return false;
    v = block.get(kLetters[i]);
    if (i == 0 && diameter_mode) v /= 2.0;
    return true;
  };
  if (g53) {
    // LinuxCNC's find_ends for G53: X and Y through the rotation (the other
    // one keeps its place on the machine), the rest without it; A B C
    // without the tool offset.
    double cx = pos[0] + axis_offset[0], cy = pos[1] + axis_offset[1];
    rotate_xy(cx, cy, rotation);
    double v = 0;
    double px = word(0, v) ? v - origin_offset[0] - tool_offset[0] : cx;
    double py = word(1, v) ? v - origin_offset[1] - tool_offset[1] : cy;
    rotate_xy(px, py, -rotation);
    end[0] = px - axis_offset[0];
    end[1] = py - axis_offset[1];
    for (int i = 2; i < kNumAxes; ++i) {
      if (!word(i, v)) continue;
      const bool rotary = i >= 3 && i <= 5;
      end[i] = v - origin_offset[i] - axis_offset[i] - (rotary ? 0.0 : tool_offset[i]);
    }
    return end;
  }
  for (int i = 0; i < kNumAxes; ++i) {
    double v = 0;
    if (!word(i, v)) continue;
    end[i] = absolute ? v : base[i] + v;
  }
  if ((block.has_polar_r || block.has_polar_a) && !g53) {
    end[0] = polar_end_x;
    end[1] = polar_end_y;
  }
  return end;
}

void Interpreter::State::convert_polar() {
  // @ radius and ^ angle in the XY plane become X and Y words before the
  // motion (so canned cycles repeat them too). G90: from the origin, a
  // missing radius or angle is the current one. G91: the radius step, then
  // the angle step, around the origin from the current point.
  if (block.g[kGNonModal] == 530) fail("Cannot use polar coordinates with G53");
  if (block.has_word('x')) fail("Cannot specify both polar coordinate and X word");
  if (block.has_word('y')) fail("Cannot specify both polar coordinate and Y word");
  auto d2r = [](double deg) { return deg * kPi / 180.0; };
  double px = pos[0], py = pos[1];
  if (absolute) {
    if (block.has_polar_r && block.has_polar_a) {
      px = block.polar_r * std::cos(d2r(block.polar_a));
      py = block.polar_r * std::sin(d2r(block.polar_a));
    } else if (block.has_polar_r) {
      if (px == 0.0 && py == 0.0) fail("Must specify angle in polar coordinate if at the origin");
      const double theta = std::atan2(py, px);
      px = block.polar_r * std::cos(theta);
      py = block.polar_r * std::sin(theta);
    } else {
      const double radius = std::hypot(py, px);
      px = radius * std::cos(d2r(block.polar_a));
      py = radius * std::sin(d2r(block.polar_a));
    }
    block.set('x', px);
    block.set('y', py);
  } else {
    if (block.has_polar_r) {
      if (px == 0.0 && py == 0.0) fail("Incremental motion with polar coordinates is indeterminate when at the origin");
      const double theta = std::atan2(py, px);
      const double radius = std::hypot(py, px) + block.polar_r;
      px = radius * std::cos(theta);
      py = radius * std::sin(theta);
    }
    if (block.has_polar_a) {
      if (px == 0.0 && py == 0.0) fail("G91 motion with polar coordinates is indeterminate when at the origin");
      const double theta = std::atan2(py, px) + d2r(block.polar_a);
      const double radius = std::hypot(py, px);
      px = radius * std::cos(theta);
      py = radius * std::sin(theta);
    }
    block.set('x', px - pos[0]);
    block.set('y', py - pos[1]);
  }
  polar_end_x = px;  // exact end (pos + (px - pos) may lose the sign of a zero)
  polar_end_y = py;
  // has_polar_* stay set: incremental canned cycles repeat the polar step.
}

void Interpreter::State::emit_traverse(const Pose& p) {
  canon.straight_traverse(current_line, p);
  pos = p;
}

void Interpreter::State::emit_feed(const Pose& p) {
  canon.straight_feed(current_line, p);
  pos = p;
}

void Interpreter::State::inverse_time_feed_straight(const Pose& from, const Pose& to) {
  // XYZ length if XYZ move, else UVW, else ABC (LinuxCNC's rule)
  auto moved = [&](int a, int b, int c) {
    return std::fabs(to[a] - from[a]) > 1e-7 || std::fabs(to[b] - from[b]) > 1e-7 || std::fabs(to[c] - from[c]) > 1e-7;
  };
  auto dist = [&](int a, int b, int c) {
    return std::sqrt((to[a] - from[a]) * (to[a] - from[a]) + (to[b] - from[b]) * (to[b] - from[b]) +
                     (to[c] - from[c]) * (to[c] - from[c]));
  };
  const double length = moved(0, 1, 2) ? dist(0, 1, 2) : moved(6, 7, 8) ? dist(6, 7, 8) : dist(3, 4, 5);
  const double rate = length * block.get('f');
  feed = rate < 0.1 ? 0.1 : rate;
  canon.set_feed_rate(feed);
}

void Interpreter::State::inverse_time_feed_arc(double length) {
  const double rate = length * block.get('f');
  feed = rate < 0.1 ? 0.1 : rate;
  canon.set_feed_rate(feed);
}

void Interpreter::State::convert_motion(int g, Status& st) {
  const bool g53 = block.g[kGNonModal] == 530;
  if (g53) {
    if (g != 0 && g != 10) fail("Must use g0 or g1 with g53");
    if (!absolute) fail("Cannot use g53 incremental");
    if (cutter_side != 400) fail("Cannot use g53 with cutter radius comp");
  }
  if (block.has_polar_r || block.has_polar_a) convert_polar();
  const bool is_cycle = g == 730 || g == 740 || (g >= 810 && g <= 890);
  if (!is_cycle) cycle_il_valid = false;
  if (nurbs_active && g != 52 && g != 53) {
    nurbs_active = false;  // another motion abandons an unfinished NURBS list
    nurbs_points.clear();
  }
  // Cycles, splines and the rest start from the tool: they end a G40 exit
  // too (lines, probes and threads end it after taking their end point).
  if (g != 0 && g != 10 && g != 20 && g != 30 && g != 800 && !(g >= 382 && g <= 385) && g != 330 && g != 331) comp_exit_move = false;
  switch (g) {
    case 0:
    case 10: {
      motion_mode = g;
      const Pose e = find_ends(g53);
      comp_exit_move = false;
      straight(g, e);
      return;
    }
    case 20:
    case 30:
      // The exit move goes from the offset tool to the programmed point; an
      // arc cannot (LinuxCNC refuses it too).
      if (comp_exit_move) fail("The move just after exiting cutter compensation mode must be straight, not an arc");
      motion_mode = g;
      convert_arc(g, find_ends(false));
      return;
    case 382: case 383: case 384: case 385:
      motion_mode = g;
      {
        const Pose e = find_ends(false);
        comp_exit_move = false;
        convert_probe(g, e, st);
      }
      return;
    case 330:
    case 331:
      motion_mode = g;
      {
        const Pose e = find_ends(false);
        comp_exit_move = false;
        convert_threading(g, e);
      }
      return;
    case 800:
      if (config.linuxcnc_comments) canon.comment("interpreter: motion mode set to none");
      motion_mode = -1;
      return;
    case 760:
      convert_g76(find_ends(false));
      motion_mode = g;
      return;
    case 730: case 740: case 810: case 820: case 830: case 840: case 850: case 860: case 870: case 880: case 890:
      convert_cycle(g, pos);
      motion_mode = g;
      return;
    case 700: case 710: case 711: case 712: case 720: case 721: case 722:
      convert_g7x(g);
      return;
    case 50:
    case 51:
      motion_mode = g;
      convert_spline(g, find_ends(false));
      return;
    case 52:
    case 53:
      convert_nurbs(g);
      return;
    default:
      fail("Bug unknown motion code");
  }
}

void Interpreter::State::convert_nurbs(int g) {
  // G5.2 starts (and continues) a list of control points X Y with weight P
  // and order L; G5.3 sends the curve. Other motion abandons the list.
  if (g == 53) {
    if (!nurbs_active) fail("Cannot use G5.3 without G5.2 first");
    if (static_cast<int>(nurbs_points.size()) < nurbs_order) {
      fail("You must specify a number of control points at least equal to the order L = " +
           std::to_string(nurbs_order));
    }
    Pose end = pos;
    end[0] = nurbs_points.back().x;
    end[1] = nurbs_points.back().y;
    canon.nurbs_feed(current_line, nurbs_order, nurbs_points, end);
    pos = end;
    nurbs_active = false;
    nurbs_points.clear();
    motion_mode = kMotionNone;  // LinuxCNC leaves no motion mode (reads -1)
    return;
  }
  if (cutter_side != 400) fail("Cannot convert spline with cutter radius compensation");
  if (plane != Plane::XY) fail("Splines must be in the XY plane");
  const bool hx = block.has_word('x'), hy = block.has_word('y');
  auto coord = [&](char c, int axis) { return absolute ? block.get(c) : pos[axis] + block.get(c); };
  if (!nurbs_active) {
    if (hx != hy) fail("You must specify both X and Y coordinates for Control Points");
    nurbs_active = true;
    nurbs_order = block.has_word('l') ? static_cast<int>(block.get('l')) : 3;
    nurbs_points.clear();
    nurbs_points.push_back({pos[0], pos[1], block.has_word('p') ? block.get('p') : 1.0});
    if (hx) nurbs_points.push_back({coord('x', 0), coord('y', 1), block.has_word('p') ? block.get('p') : 1.0});
  } else {
    if (!hx && !hy && block.has_word('p')) fail("Can specify P without X and Y only for the first control point");
    if (hx != hy) fail("You must specify both X and Y coordinates for Control Points");
    if (!block.has_word('p') || block.get('p') <= 0) fail("Must specify positive weight P for every Control Point");
    nurbs_points.push_back({coord('x', 0), coord('y', 1), block.get('p')});
  }
  motion_mode = 52;
}

void Interpreter::State::convert_spline(int g, const Pose& end) {
  // G5: cubic Bezier, first control point current + (I,J) (or the previous
  // G5's last tangent mirrored), second end + (P,Q). G5.1: quadratic with
  // control point current + (I,J).
  if (cutter_side != 400) fail("Cannot convert spline with cutter radius compensation");
  if (plane != Plane::XY) fail("Splines must be in the XY plane");
  for (char c : {'z', 'a', 'b', 'c'}) {
    if (block.has_word(c) && block.get(c) != (absolute ? pos[axis_index(c)] : 0.0)) {
      fail("Splines may not have motion in Z, A, B, or C");
    }
  }
  if (feed == 0.0 && feed_mode == FeedMode::UnitsPerMinute) fail("Cannot make a NURBS with 0 feedrate");
  const bool has_i = block.has_word('i'), has_j = block.has_word('j');
  std::vector<Canon::ControlPoint> pts;
  pts.push_back({pos[0], pos[1], 1.0});
  if (g == 50) {
    if (!block.has_word('p') || !block.has_word('q')) fail("Must specify both P and Q with G5");
    if (has_i != has_j) fail("Must specify both I and J, or neither");
    double i = block.get('i'), j = block.get('j');
    if (!has_i) {
      i = -spline_last_p;
      j = -spline_last_q;
    }
    pts.push_back({pos[0] + i, pos[1] + j, 1.0});
    pts.push_back({end[0] + block.get('p'), end[1] + block.get('q'), 1.0});
    spline_last_p = block.get('p');
    spline_last_q = block.get('q');
  } else {
    if (!has_i || !has_j) fail("Must specify both I and J with G5.1");
    pts.push_back({pos[0] + block.get('i'), pos[1] + block.get('j'), 1.0});
  }
  pts.push_back({end[0], end[1], 1.0});
  canon.nurbs_feed(current_line, g == 50 ? 4 : 3, pts, end);
  pos = end;
}

void Interpreter::State::straight(int g, const Pose& end) {
  if (g == 10) {
    if (feed_mode == FeedMode::UnitsPerMinute && feed == 0.0) fail("Cannot do g1 with zero feed rate");
    if (feed_mode == FeedMode::InverseTime && !block.has_word('f')) fail("F word missing with inverse time g1 move");
    if (feed_mode == FeedMode::UnitsPerRev && active_speed() == 0.0) fail("Cannot feed with zero spindle speed in feed per rev mode");
  }
  // Under cutter compensation the inverse-time rate comes from the
  // programmed move, so it is the same with compensation on or off
  // (LinuxCNC's interp/inverse-time-with-comp); the rate waits in the queue
  // behind the held-back move.
  if (g != 0 && feed_mode == FeedMode::InverseTime) inverse_time_feed_straight(cutter_side != 400 ? comp_program_pos : pos, end);
  if (cutter_side != 400) {
    comp_straight(g == 0, end);
    return;
  }
  if (g == 0) {
    emit_traverse(end);
  } else {
    emit_feed(end);
  }
}

void Interpreter::State::convert_arc(int g, const Pose& end) {
  if (plane == Plane::UV || plane == Plane::VW || plane == Plane::UW) fail("Cannot do an arc in planes G17.1, G18.1, or G19.1");
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const char l1 = kLetters[a1], l2 = kLetters[a2];
  // centre offsets: I J K go with X Y Z
  const char o1 = static_cast<char>('i' + a1), o2 = static_cast<char>('i' + a2);
  const bool has_r = block.has_word('r');
  const bool has_ij = block.has_word(o1) || block.has_word(o2);
  if (has_r && has_ij) fail("Mixed radius ijk format for arc");
  if (!has_r && !has_ij) fail("R i j k words all missing for arc");
  if (has_r && !block.has_word(l1) && !block.has_word(l2)) {
    static constexpr const char* msgs[] = {"X and y words missing for arc in xy plane", "Y and z words missing for arc in yz plane",
                                           "X and z words missing for arc in xz plane"};
    fail(msgs[plane == Plane::XY ? 0 : plane == Plane::YZ ? 1 : 2]);
  }
  if (feed_mode == FeedMode::UnitsPerMinute && feed == 0.0) fail("Cannot make arc with zero feed rate");
  if (feed_mode == FeedMode::InverseTime && !block.has_word('f')) fail("F word missing with inverse time arc move");
  if (feed_mode == FeedMode::UnitsPerRev && active_speed() == 0.0) fail("Cannot feed with zero spindle speed in feed per rev mode");
  int turns = 1;
  if (block.has_word('p')) {
    const double p = block.get('p');
    turns = round_to_int((p));
    if (std::fabs(p - turns) > 0.0001) fail("P value not an integer with M19 G2 or G3");
    if (turns < 1) fail("P value should be 1 or greater with G2 or G3");
  }
  const Pose& start = cutter_side != 400 ? comp_program_pos : pos;
  const double s1 = start[a1], s2 = start[a2];
  const double e1 = end[a1], e2 = end[a2];
  const double tol = radius_tolerance();
  const double spiral_tol = arc_tolerance();
  double c1 = 0, c2 = 0;
  char buf[512];
  if (has_r) {
    const double radius = block.get('r');
    if (s1 == e1 && s2 == e2) fail("Current point same as end point of arc");
    const double abs_r = std::fabs(radius);
    const double m1 = (e1 + s1) / 2.0, m2 = (e2 + s2) / 2.0;
    double half = std::hypot(m1 - e1, m2 - e2);
    if (half - abs_r > tol) fail("Arc radius too small to reach end point");
    if (half / abs_r > (1.0 - kTiny)) half = abs_r;
    // As LinuxCNC computes it (the tiny residue of cos(asin(1)) decides the
    // sign of a zero in the printed centre): perpendicular from the chord's
    // midpoint, quarter turn in long double.
    constexpr long double kHalfPiL = 1.570796326794896619231321691639751442L;
    const long double chord = std::atan2(e2 - s2, e1 - s1);
    const double theta = static_cast<double>(((g == 20 && radius > 0) || (g == 30 && radius < 0)) ? chord - kHalfPiL
                                                                                                    : chord + kHalfPiL);
    const double offset = abs_r * std::cos(std::asin(half / abs_r));
    c1 = m1 + offset * std::cos(theta);
    c2 = m2 + offset * std::sin(theta);
  } else {
    if (ijk_absolute) {
      if (!block.has_word(o1) || !block.has_word(o2)) {
        std::snprintf(buf, sizeof buf, "%c word missing in absolute center arc",
                      static_cast<char>((block.has_word(o1) ? o2 : o1) - 32));
        fail(buf);
      }
      c1 = block.get(o1);
      c2 = block.get(o2);
    } else {
      c1 = s1 + (block.has_word(o1) ? block.get(o1) : 0.0);
      c2 = s2 + (block.has_word(o2) ? block.get(o2) : 0.0);
    }
    const double r1 = std::hypot(s1 - c1, s2 - c2);
    const double r2 = std::hypot(e1 - c1, e2 - c2);
    const char* n1 = plane_upper(a1);
    const char* n2 = plane_upper(a2);
    if (r1 < tol || r2 < tol) {
      std::snprintf(buf, sizeof buf, "Zero-radius arc: start=(%s%.4f,%s%.4f) center=(%s%.4f,%s%.4f) end=(%s%.4f,%s%.4f) r1=%.4f r2=%.4f",
                    n1, s1, n2, s2, n1, c1, n2, c2, n1, e1, n2, e2, r1, r2);
      fail(buf);
    }
    const double abs_err = std::fabs(r1 - r2);
    const double rel_err = abs_err / std::max(r1, r2);
    if (abs_err > spiral_tol * 100.0 || (abs_err > spiral_tol && rel_err > 0.001)) {
      std::snprintf(buf, sizeof buf,
                    "Radius to end of arc differs from radius to start: start=(%s%.4f,%s%.4f) center=(%s%.4f,%s%.4f) "
                    "end=(%s%.4f,%s%.4f) r1=%.4f r2=%.4f abs_err=%.4g rel_err=%.4f%%",
                    n1, s1, n2, s2, n1, c1, n2, c2, n1, e1, n2, e2, r1, r2, abs_err, rel_err * 100.0);
      fail(buf);
    }
  }
  const int rotation = g == 20 ? -turns : turns;
  if (feed_mode == FeedMode::InverseTime) {
    // helix length: planar arc length and the normal travel
    double a_start = std::atan2(s2 - c2, s1 - c1), a_end = std::atan2(e2 - c2, e1 - c1);
    double sweep = a_end - a_start;
    if (rotation > 0) {
      if (sweep <= 0) sweep += 2 * kPi;
      sweep += 2 * kPi * (rotation - 1);
    } else {
      if (sweep >= 0) sweep -= 2 * kPi;
      sweep -= 2 * kPi * (-rotation - 1);
    }
    const double r = std::hypot(s1 - c1, s2 - c2);
    inverse_time_feed_arc(std::hypot(std::fabs(sweep) * r, end[a3] - start[a3]));
  }
  if (cutter_side != 400) {
    comp_arc(g, end, c1, c2, rotation);
    return;
  }
  canon.arc_feed(current_line, e1, e2, c1, c2, rotation, end[a3], end);
  pos = end;
}

void Interpreter::State::convert_probe(int g, const Pose& end, Status& st) {
  if (cutter_side != 400) fail("Cannot probe with cutter radius comp on");
  if (feed_mode == FeedMode::UnitsPerRev) fail("Cannot probe with feed per rev mode");
  if (feed == 0.0) fail("Cannot probe with zero feed rate");
  if (!block.any_axis(config.axis_mask)) fail("All axes missing with motion code");
  double moved = 0;
  for (int i = 0; i < kNumAxes; ++i) moved += std::fabs(end[i] - pos[i]);
  if (moved == 0.0 && (g == 382 || g == 383)) fail("Start point too close to probe point");
  canon.turn_probe_on();
  const ProbeKind kind = g == 382 ? ProbeKind::TowardStopOnContact
                       : g == 383 ? ProbeKind::TowardNoError
                       : g == 384 ? ProbeKind::AwayStopOnLoss
                                  : ProbeKind::AwayNoError;
  canon.straight_probe(current_line, end, kind);
  canon.turn_probe_off();
  pos = end;
  probe_pending = true;
  st = Status::ExecuteFinish;
}

void Interpreter::State::convert_threading(int g, const Pose& end) {
  if (!block.has_word('k')) fail("K word missing with g33/g33.1");
  if (block.has_dollar) active_spindle = chosen_spindle(g == 330 ? "G33" : "G33.1");
  if (active_direction() == Direction::Stopped) fail(g == 330 ? "Spindle not turning in G33" : "Spindle not turning in G33.1");
  if (cutter_side != 400 && g == 331) fail("G33.1 cannot be used with cutter compensation enabled");
  canon.start_speed_feed_synch(active_spindle, block.get('k'), false);
  if (g == 330) {
    if (cutter_side != 400) {
      comp_straight(false, end);
    } else {
      emit_feed(end);
    }
  } else {
    canon.rigid_tap(current_line, end, 1.0);
    // the tap returns to where it started
  }
  canon.stop_speed_feed_synch();
}

void Interpreter::State::convert_g76(const Pose& end) {
  // Lathe threading in the XZ plane, passes of depth J * n^(1/R) until the
  // full depth K, then H spring passes; Q compound angle, E/L tapers.
  if (cutter_side != 400) fail("Cannot use G76 threading cycle with cutter radius compensation on");
  if (!block.has_word('p')) fail("P word missing with G76");
  if (!block.has_word('i') || !block.has_word('j') || !block.has_word('k')) fail("I J or K words missing with G76");
  if (block.has_word('a') || block.has_word('b') || block.has_word('c')) fail("Cannot move rotary axes with G76");
  const double pitch = block.get('p');
  const double i = block.get('i'), j = block.get('j'), k = block.get('k');
  if (i == 0.0) fail("In G76, I must not be 0");
  if (j <= 0.0) fail("In G76, J must be greater than 0");
  if (k <= j) fail("In G76, K must be greater than J");
  if (block.has_dollar) active_spindle = chosen_spindle("G76");
  if (active_direction() == Direction::Stopped) {
    fail("Chosen spindle (" + std::to_string(active_spindle) + ") not turning in G76");
  }
  const double degression = block.has_word('r') ? block.get('r') : 1.0;
  const double t = std::tan((block.has_word('q') ? block.get('q') : 0.0) * kPi / 180.0);
  const int spring = block.has_word('h') ? round_to_int(block.get('h')) : 0;
  const double e = block.has_word('e') ? block.get('e') : 0.0;
  const int l = block.has_word('l') ? round_to_int(block.get('l')) : 0;
  const bool entry_taper = e > 0 && (l == 1 || l == 3);
  const bool exit_taper = e > 0 && (l == 2 || l == 3);
  const double s = i < 0 ? -1.0 : 1.0;
  const double start_x = pos[0], zs = pos[2], ze = end[2];
  const double dir = ze < zs ? -1.0 : 1.0;
  const double peak_x = start_x + i;
  const double taper_pitch = e > 0 ? pitch * std::hypot(e, k) / e : pitch;
  auto at = [&](double x, double z) {
    Pose p = pos;
    p[0] = x;
    p[2] = z;
    return p;
  };
  auto pass = [&](double depth) {
    const double cut_x = peak_x + s * depth;
    const double safe_x = start_x - s * (k - depth);
    const double zs_pass = zs + dir * depth * t;
    const double ze_pass = ze - dir * (k - depth) * t;
    emit_traverse(at(safe_x, zs_pass));
    if (!entry_taper) emit_traverse(at(cut_x, zs_pass));
    canon.disable_feed_override();
    if (entry_taper) {
      canon.start_speed_feed_synch(active_spindle, taper_pitch, false);
      emit_feed(at(cut_x - s * k, zs_pass));
      emit_feed(at(cut_x, zs_pass + dir * e));
    }
    canon.start_speed_feed_synch(active_spindle, pitch, false);
    if (exit_taper) {
      emit_feed(at(cut_x, ze_pass - dir * e));
      canon.start_speed_feed_synch(active_spindle, taper_pitch, false);
      emit_feed(at(cut_x - s * k, ze_pass));
    } else {
      emit_feed(at(cut_x, ze_pass));
    }
    canon.stop_speed_feed_synch();
    emit_traverse(at(safe_x, ze_pass));
    canon.enable_feed_override();
  };
  for (int n = 1;; ++n) {
    const double depth = j * std::pow(static_cast<double>(n), 1.0 / degression);
    if (depth >= k) break;
    if (n > 10000) fail("G76 would need more than 10000 passes (check J, K and R)");
    pass(depth);
  }
  if (spring > 10000) fail("G76 would need more than 10000 passes (check J, K and R)");
  for (int h = 0; h <= spring; ++h) pass(k);
  emit_traverse(at(start_x, pos[2]));
}

}  // namespace cnc::interp
