// Canned cycles G73, G74, G81-G89 with G98/G99 retract, L repeats and
// incremental positioning, in any of the three main planes.
#include <cmath>

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {

}

void Interpreter::State::convert_cycle(int g, Pose) {
  if (cutter_side != 400) fail("Cannot use canned cycles with cutter compensation on");
  if (feed == 0.0) fail("Cannot feed with zero feed rate");
  if (feed_mode == FeedMode::InverseTime) fail("Cannot use inverse time feed with canned cycles");
  if (block.has_word('a')) fail("Cannot put an a in canned cycle");
  if (block.has_word('b')) fail("Cannot put a b in canned cycle");
  if (block.has_word('c')) fail("Cannot put a c in canned cycle");
  if (plane == Plane::UV || plane == Plane::UW || plane == Plane::VW) fail("Canned cycles in planes G17.1, G18.1 or G19.1 are not supported");
  int a1, a2, a3;
  plane_axes(a1, a2, a3);
  const char l1 = kLetters[a1], l2 = kLetters[a2], l3 = kLetters[a3];
  const bool same = motion_mode == g;
  int repeats = 1;
  if (block.has_word('l')) {
    repeats = static_cast<int>(block.get('l'));
    if (repeats == 0) fail("Cannot do zero repeats of cycle");
  }
  if (block.has_word('r')) {
    cycle_r = block.get('r');
  } else if (!same) {
    fail("R clearance plane unspecified in cycle");
  }
  if (block.has_word(l3)) {
    cycle_cc = block.get(l3);
  } else if (!same) {
    static constexpr const char* msgs[] = {"Z value unspecified in xy plane canned cycle", "X value unspecified in yz plane canned cycle",
                                           "Y value unspecified in xz plane canned cycle"};
    fail(msgs[plane == Plane::XY ? 0 : plane == Plane::YZ ? 1 : 2]);
  }
  if (block.has_word('p')) cycle_p = block.get('p');
  if (block.has_word('q')) cycle_q = block.get('q');
  if (block.has_word('i')) cycle_i = block.get('i');
  if (block.has_word('j')) cycle_j = block.get('j');
  if (block.has_word('k')) cycle_k = block.get('k');
  // The "initial level" of a run of cycle blocks: where the first one
  // started, lowered when a G99 retract left the tool below it (this
  // reproduces LinuxCNC 2.9's observable behaviour; other motion ends a run).
  double current_cc = pos[a3];
  if (!cycle_il_valid || current_cc < cycle_il) {
    cycle_il = current_cc;
    cycle_il_valid = true;
  }
  double old_cc = cycle_il;
  double r = cycle_r, bottom = cycle_cc;
  double clear = 0;
  double aa = pos[a1], bb = pos[a2];
  double aa_inc = 0, bb_inc = 0;
  if (absolute) {
    clear = retract_old_z ? std::max(r, old_cc) : r;
    if (block.has_word(l1)) aa = block.get(l1);
    if (block.has_word(l2)) bb = block.get(l2);
  } else {
    r = cycle_r + old_cc;
    bottom = r + cycle_cc;
    clear = retract_old_z ? std::max(r, old_cc) : r;
    aa_inc = block.has_word(l1) ? block.get(l1) : 0.0;
    bb_inc = block.has_word(l2) ? block.get(l2) : 0.0;
  }
  // Guard against programs that would never end (LinuxCNC would loop):
  // a peck depth too small to make progress, or absurd counts.
  constexpr double kMaxMoves = 1e5;
  if ((g == 730 || g == 830) && cycle_q > 0 && ((r - bottom) / cycle_q > kMaxMoves || r - cycle_q == r)) {
    fail("Canned cycle would need more than 100000 pecks");
  }
  if (repeats > kMaxMoves) fail("Canned cycle L repeat count too large");
  if (r < bottom) {
    static constexpr const char* msgs[] = {"R less than z in cycle in xy plane", "R less than x in cycle in yz plane",
                                           "R less than y in cycle in xz plane"};
    fail(msgs[plane == Plane::XY ? 0 : plane == Plane::YZ ? 1 : 2]);
  }
  auto at = [&](double a, double b, double c) {
    Pose p = pos;
    p[a1] = a;
    p[a2] = b;
    p[a3] = c;
    return p;
  };
  auto trav = [&](double a, double b, double c) { emit_traverse(at(a, b, c)); };
  auto feedto = [&](double a, double b, double c) { emit_feed(at(a, b, c)); };
  const double rapid_delta = units == Units::Inch ? 0.010 : 0.254;

  if (old_cc < r) {
    trav(pos[a1], pos[a2], r);
    old_cc = r;
    current_cc = old_cc;
  }
  // Cycles run in exact path mode; the block's mode comes back after.
  const MotionMode saved_control = control;
  if (control != MotionMode::ExactPath) canon.set_motion_control_mode(MotionMode::ExactPath, 0);
  switch (g) {
    case 820: case 860: case 880: case 890:
      if (!block.has_word('p') && !same) {
        fail(g == 820 ? "Dwell time p word missing with g82" : g == 860 ? "Dwell time p word missing with g86"
             : g == 880 ? "Dwell time p word missing with g88" : "Dwell time p word missing with g89");
      }
      break;
    case 870:
      if (!block.has_word('i') && !same) fail("I word missing with g87");
      if (!block.has_word('j') && !same) fail("J word missing with g87");
      if (!block.has_word('k') && !same) fail("K word missing with g87");
      break;
    case 730: case 830:
      if (!block.has_word('q') && !same) fail(g == 730 ? "Q word missing with g73" : "Q word missing with g83");
      if (cycle_q <= 0) fail("Negative or zero q value used");
      break;
    default:
      break;
  }
  if (g == 840 && spindle == Direction::CounterClockwise) fail("Spindle turning counterclockwise in G84");
  if (g == 740 && spindle == Direction::Clockwise) fail("Spindle turning clockwise in G74");


  for (int rep = 0; rep < repeats; ++rep) {
    if (!absolute && (block.has_polar_r || block.has_polar_a)) {
      // a polar step is repeated around the origin, not along a line:
      // radius step, then angle step
      if (aa == 0.0 && bb == 0.0) fail("Incremental motion with polar coordinates is indeterminate when at the origin");
      if (block.has_polar_r) {
        const double theta = std::atan2(bb, aa);
        const double radius = std::hypot(bb, aa) + block.polar_r;
        aa = radius * std::cos(theta);
        bb = radius * std::sin(theta);
      }
      if (block.has_polar_a) {
        const double theta = std::atan2(bb, aa) + block.polar_a * kPi / 180.0;
        const double radius = std::hypot(bb, aa);
        aa = radius * std::cos(theta);
        bb = radius * std::sin(theta);
      }
    } else if (!absolute) {
      aa += aa_inc;
      bb += bb_inc;
    }
    trav(aa, bb, current_cc);
    if (g == 860 && spindle == Direction::Stopped) fail("Spindle not turning in g86");
    if (g == 880 && spindle == Direction::Stopped) fail("Spindle not turning in g88");
    if (g == 870 && spindle == Direction::Stopped) fail("Spindle not turning in g87");
    if (old_cc != r) trav(aa, bb, r);
    switch (g) {
      case 810:
        feedto(aa, bb, bottom);
        trav(aa, bb, clear);
        break;
      case 820:
        feedto(aa, bb, bottom);
        canon.dwell(cycle_p);
        trav(aa, bb, clear);
        break;
      case 730:
      case 830: {
        for (double depth = r - cycle_q; depth > bottom; depth -= cycle_q) {
          feedto(aa, bb, depth);
          if (g == 830) {
            trav(aa, bb, r);
            trav(aa, bb, depth + rapid_delta);
          } else {
            trav(aa, bb, depth + rapid_delta);
          }
        }
        feedto(aa, bb, bottom);
        trav(aa, bb, clear);
        break;
      }
      case 740:
      case 840: {
        // Floating-holder tapping as LinuxCNC 2.9: overrides off, reverse
        // the spindle at the bottom, feed out, restore.
        canon.disable_feed_override();
        canon.disable_speed_override(0);
        feedto(aa, bb, bottom);
        canon.stop_spindle_turning(0);
        g == 840 ? canon.start_spindle_counterclockwise(0) : canon.start_spindle_clockwise(0);
        canon.dwell(cycle_p);
        feedto(aa, bb, clear);
        canon.stop_spindle_turning(0);
        g == 840 ? canon.start_spindle_clockwise(0) : canon.start_spindle_counterclockwise(0);
        canon.enable_feed_override();
        canon.enable_speed_override(0);
        break;
      }
      case 850:
        feedto(aa, bb, bottom);
        feedto(aa, bb, r);
        trav(aa, bb, clear);
        break;
      case 860:
        feedto(aa, bb, bottom);
        canon.dwell(cycle_p);
        canon.stop_spindle_turning(0);
        trav(aa, bb, clear);
        if (spindle == Direction::Clockwise) {
          canon.start_spindle_clockwise(0);
        } else {
          canon.start_spindle_counterclockwise(0);
        }
        break;
      case 870: {
        // Back boring: in beside the bore with the spindle oriented, down,
        // over, bore up to K and back, out the same way.
        const double oa = aa + cycle_i, ob = bb + cycle_j;
        auto restart = [&] {
          spindle == Direction::Clockwise ? canon.start_spindle_clockwise(0) : canon.start_spindle_counterclockwise(0);
        };
        trav(oa, ob, r);
        canon.stop_spindle_turning(0);
        canon.orient_spindle(0, 0.0, 2);
        trav(oa, ob, bottom);
        trav(aa, bb, bottom);
        restart();
        feedto(aa, bb, cycle_k);
        feedto(aa, bb, bottom);
        canon.stop_spindle_turning(0);
        canon.orient_spindle(0, 0.0, 2);
        trav(oa, ob, bottom);
        trav(oa, ob, clear);
        trav(aa, bb, clear);
        restart();
        break;
      }
      case 880:
        // Boring with a manual way out: the operator jogs after M0.
        feedto(aa, bb, bottom);
        canon.dwell(cycle_p);
        canon.stop_spindle_turning(0);
        canon.program_stop();
        spindle == Direction::Clockwise ? canon.start_spindle_clockwise(0) : canon.start_spindle_counterclockwise(0);
        break;
      case 890:
        feedto(aa, bb, bottom);
        canon.dwell(cycle_p);
        feedto(aa, bb, clear);
        break;
      default:
        break;
    }
    current_cc = clear;
    old_cc = clear;  // later repeats start from the retract plane
  }
  if (saved_control != MotionMode::ExactPath) {
    canon.set_motion_control_mode(saved_control, tolerance);
    if (saved_control == MotionMode::Continuous) canon.set_naivecam_tolerance(naive_tolerance);
  }
}

}  // namespace cnc::interp
