// G70 / G71 / G72 lathe cycles (finishing, roughing along Z, roughing along
// X, with .1 / .2 variants) on a contour given by an O-word subroutine, as
// LinuxCNC 2.9 computes them.
//
// The contour is read by calling the subroutine named by Q and reading its
// blocks without executing them: G0/G1/G2/G3 with X Z (or U W relative), I K
// or R, and A (fillet radius) or C (chamfer size) at a corner. O-word flow
// and parameter assignments of the subroutine run as usual. The geometry
// works in the XZ plane as complex numbers (real part Z, imaginary part X);
// the profile is turned (flips, a quarter turn for G72) so that it always
// runs towards smaller Z and X, cut there, and the moves turned back on the
// way out. The output must be LinuxCNC's to the last printed digit, so every
// step is computed in LinuxCNC's order with std::complex as it does (signed
// zeros included).
#include <algorithm>
#include <cmath>
#include <complex>
#include <sstream>
#include <string>
#include <vector>

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {

using Cx = std::complex<double>;
constexpr Cx kI(0, 1);
constexpr double kTol = 1e-6;
// More identical moves in a row than this stop the cycle (see Machine).
constexpr int kMaxRepeats = 1000;

// A geometry failure: the cycle's error is "G7X error: <what>".
struct G7xError {
  std::string what;
};

// Where the cycle's moves go, in the profile's turned coordinates.
class PathSink {
 public:
  virtual ~PathSink() = default;
  virtual void feed(Cx end) = 0;
  virtual void rapid(Cx end) = 0;
  virtual void arc(bool ccw, Cx centre, Cx end) = 0;
};

// One element of the contour: a line, an arc, or a corner (fillet or
// chamfer) placed between two elements and resolved by finish_corners().
struct Seg {
  enum Kind : uint8_t { Line, Arc } kind = Line;
  enum Corner : uint8_t { NoCorner, Fillet, Chamfer } corner = NoCorner;
  Cx s, e, c;          // start, end, centre
  bool ccw = false;    // arcs: G3
  double finish = 0;   // corner size until resolved

  static Seg line(Cx s, Cx e) { return Seg{Line, NoCorner, s, e, Cx{}, false, 0}; }
  static Seg arc(bool ccw, Cx s, Cx c, Cx e) { return Seg{Arc, NoCorner, s, e, c, ccw, 0}; }
};

std::string point_text(Cx p) {
  std::ostringstream o;
  o << p;
  return o.str();
}

// The Z values where the element crosses X = x (both ends of a line along Z).
void crossings(const Seg& g, double x, std::vector<double>& out) {
  if (g.kind == Seg::Line) {
    if (std::min(g.s.imag(), g.e.imag()) > x + kTol || std::max(g.s.imag(), g.e.imag()) < x - kTol) return;
    if (std::abs(std::imag(g.s - g.e)) < kTol) {
      out.push_back(g.s.real());
      out.push_back(g.e.real());
    } else {
      out.push_back((x - g.s.imag()) / (g.e.imag() - g.s.imag()) * (g.e.real() - g.s.real()) + g.s.real());
    }
    return;
  }
  const Cx r = g.s - g.c;
  double q = -(x - std::abs(r) - g.c.imag()) * (x + std::abs(r) - g.c.imag());
  if (q < -kTol) return;
  if (q < 0) q = 0;
  q = std::sqrt(q);
  auto on_arc = [&](Cx p) {
    const double from_start = std::imag(std::conj(g.s - g.c) * (p - g.c));
    const double from_end = std::imag(std::conj(g.e - g.c) * (p - g.c));
    return g.ccw ? from_start >= -kTol && from_end <= kTol : from_start <= kTol && from_end >= -kTol;
  };
  const Cx p1(std::real(g.c + q), x);
  if (on_arc(p1)) out.push_back(std::real(p1));
  const Cx p2(std::real(g.c - q), x);
  if (on_arc(p2)) out.push_back(std::real(p2));
}

double seg_radius(const Seg& g) {
  if (g.kind == Seg::Line) return std::abs(g.s - g.e);
  return std::min(std::abs(g.s - g.e), std::abs(g.s - g.c));
}

// Runs towards smaller Z (and an arc stays on one side of its centre).
bool seg_monotonic(const Seg& g) {
  if (g.kind == Seg::Line) return std::real(g.e - g.s) <= 1e-3;
  if (g.finish != 0) return true;
  const double entry = std::imag(g.s - g.c);
  const double exit = std::imag(g.e - g.c);
  const double dz = std::real(g.e - g.s);
  if (g.ccw) return entry >= -1e-3 && exit >= -1e-3 && dz <= -1e-3;
  return entry <= 1e-3 && exit <= 1e-3 && dz <= -1e-3;
}

// Moves the element sideways by d (to the left of its direction for lines;
// arcs grow for G3, shrink for G2).
void seg_offset(Seg& g, double d) {
  if (g.kind == Seg::Line) {
    const Cx v = kI * d * (g.s - g.e) / std::abs(g.s - g.e);
    g.s += v;
    g.e += v;
    return;
  }
  const double factor = (std::abs(g.s - g.c) + (g.ccw ? 1 : -1) * d) / std::abs(g.s - g.c);
  g.s = factor * (g.s - g.c) + g.c;
  g.e = factor * (g.e - g.c) + g.c;
}

void seg_flip_x(Seg& g) {
  if (g.kind == Seg::Arc) g.ccw = !g.ccw;
  g.s = std::conj(g.s);
  g.e = std::conj(g.e);
  g.c = std::conj(g.c);
}

void seg_flip_z(Seg& g) {
  if (g.kind == Seg::Arc) g.ccw = !g.ccw;
  g.s = -std::conj(g.s);
  g.e = -std::conj(g.e);
  g.c = -std::conj(g.c);
}

void seg_quarter_turn(Seg& g) {
  g.s = -g.s * kI;
  g.e = -g.e * kI;
  if (g.kind == Seg::Arc) g.c = -g.c * kI;
}

void seg_shift(Seg& g, Cx d) {
  g.s += d;
  g.e += d;
  if (g.kind == Seg::Arc) g.c += d;
}

void seg_draw(const Seg& g, PathSink& out) {
  if (g.kind == Seg::Line) {
    out.feed(g.e);
  } else {
    out.arc(g.ccw, g.c, g.e);
  }
}

// Makes `a`'s end and `b`'s start the point where the two (offset) elements
// meet.
void join(Seg& a, Seg& b) {
  if (b.kind == Seg::Line && a.kind == Seg::Line) {
    const auto rot = std::conj(b.s - b.e) / std::abs(b.s - b.e);
    const auto ps = (a.s - b.e) * rot;
    const auto pe = (a.e - b.e) * rot;
    if (std::imag(ps - pe) == 0) throw G7xError{"Cannot intersect parallel lines"};
    const auto f = std::imag(ps) / std::imag(ps - pe);
    const auto at = (ps + f * (pe - ps)) / rot + b.e;
    b.s = a.e = at;
    return;
  }
  if (b.kind == Seg::Arc && a.kind == Seg::Arc) {
    const auto ra = std::abs(b.s - b.c);
    const auto rb = std::abs(a.s - a.c);
    const auto dc = std::abs(b.c - a.c);
    const auto cos_b = (dc * dc + ra * ra - rb * rb) / 2.0 / ra / dc;
    double cos_b2 = cos_b * cos_b;
    if (cos_b2 > 1) cos_b2 = 1;
    const Cx rot(cos_b, std::sqrt(1 - cos_b2));
    const auto at = rot * (a.c - b.c) / dc * ra + b.c;
    a.e = b.s = at;
    return;
  }
  // A line and an arc: the arc's circle cut by the line, the cut nearer to
  // the next element's start.
  if (std::abs(b.s - a.e) < kTol) return;
  const Seg& ln = b.kind == Seg::Line ? b : a;
  const Seg& ar = b.kind == Seg::Line ? a : b;
  const Cx base = ln.e;
  const auto rot = std::conj(ln.s - ln.e) / std::abs(ln.s - ln.e);
  const auto pe = (ar.e - base) * rot;
  const auto pc = (ar.c - base) * rot;
  double h = std::norm(pc - pe) - std::imag(pc) * std::imag(pc);
  if (h < 0) {
    h = 0;
  } else {
    h = std::sqrt(h);
  }
  const auto s1 = (std::real(pc) + h) / rot + base;
  const auto s2 = (std::real(pc) - h) / rot + base;
  if (std::abs(b.s - s1) < std::abs(b.s - s2)) {
    b.s = a.e = s1;
  } else {
    b.s = a.e = s2;
  }
}

// Resolves corner `h` between `prev` and `next`: both are offset by the
// corner's size (to the side where they meet), joined, and the corner spans
// the feet of the join on the unshifted elements. Returns the join's middle.
Cx resolve_corner(Seg& h, Seg& prev, Seg& next) {
  Seg p = prev, n = next;
  seg_offset(p, h.finish);
  seg_offset(n, h.finish);
  if (std::real(p.e - n.s) > 1e-2) {
    h.finish = -h.finish;
    p = prev;
    n = next;
    seg_offset(p, h.finish);
    seg_offset(n, h.finish);
  }
  if (std::real(p.e - n.s) > 1e-2) throw G7xError{"Corner finish failed at " + point_text(prev.e)};
  join(p, n);
  const Cx centre = (p.e + n.s) / 2.0;
  seg_offset(p, -h.finish);
  seg_offset(n, -h.finish);
  h.s = prev.e = p.e;
  h.e = next.s = n.s;
  return centre;
}

// The profile with its turn state (bit 0: Z negated, bit 1: X negated,
// bit 2: quarter turn).
class Profile {
 public:
  std::vector<Seg> segs;

  void g70(PathSink& out, double x, double z, double d, double e, double passes);
  void g71(PathSink& out, int variant, double x, double z, double u, double w, double d, double i, double r,
           bool quarter_turn);

 private:
  double delta_ = 0.5;
  Cx escape_{0.3, 0.3};
  int turn_ = 0;
  std::vector<Cx> pocket_starts_;

  // Moves out through the turn state back to the machine's XZ.
  class Unturned : public PathSink {
   public:
    Unturned(PathSink& out, int turn) : out_(out), turn_(turn) {}
    void feed(Cx end) override { out_.feed(map(end)); }
    void rapid(Cx end) override { out_.rapid(map(end)); }
    void arc(bool ccw, Cx centre, Cx end) override {
      const bool mirrored = turn_ == 1 || turn_ == 2 || turn_ == 5 || turn_ == 6;
      out_.arc(mirrored ? !ccw : ccw, map(centre), map(end));
    }

   private:
    Cx map(Cx p) const {
      switch (turn_) {
        case 1: return -std::conj(p);
        case 2: return std::conj(p);
        case 3: return -p;
        case 4: return kI * p;
        case 5: return std::conj(kI * p);
        case 6: return -std::conj(kI * p);
        case 7: return -kI * p;
        default: return p;
      }
    }
    PathSink& out_;
    int turn_;
  };

  void quarter_turn() {
    for (Seg& g : segs) seg_quarter_turn(g);
    turn_ ^= 4;
  }
  // Turns the profile so that it runs towards smaller X and Z.
  void orient() {
    const double dir_x = std::imag(segs.front().e - segs.back().e);
    const double dir_z = std::real(segs.front().e - segs.back().e);
    if (dir_x > 0) {
      for (Seg& g : segs) seg_flip_x(g);
      turn_ ^= 2;
    }
    if (dir_z < 0) {
      for (Seg& g : segs) seg_flip_z(g);
      turn_ ^= 1;
    }
  }
  void require_monotonic() {
    if (std::real(segs.front().e - segs.front().s) > 0) segs.front().s.real(std::real(segs.front().e));
    for (const Seg& g : segs) {
      if (!seg_monotonic(g)) throw G7xError{"Not monotonic"};
    }
  }
  void finish_corners() {
    for (std::size_t h = 1; h + 1 < segs.size(); ++h) {
      Seg& g = segs[h];
      if (g.corner == Seg::Fillet) {
        g.c = resolve_corner(g, segs[h - 1], segs[h + 1]);
        g.ccw = std::imag(g.s - g.c) > 0 || std::imag(g.e - g.c) > 0;
        g.finish = 0;
      } else if (g.corner == Seg::Chamfer) {
        resolve_corner(g, segs[h - 1], segs[h + 1]);
      }
    }
    for (std::size_t k = 0; k < segs.size();) {
      if (seg_radius(segs[k]) < 1e-3) {
        segs.erase(segs.begin() + static_cast<std::ptrdiff_t>(k));
      } else {
        ++k;
      }
    }
  }
  void add_distance(double distance);
  void pocket(int variant, Cx location, std::size_t p, PathSink& out);
};

// Offsets every element but the first (the approach) by `distance` towards
// the stock, in steps of at most half the smallest element so that elements
// that vanish on the way are dropped, and an arc bridges elements that part.
void Profile::add_distance(double distance) {
  const auto v1 = segs.front().e - segs.front().s;
  const auto v2 = segs.back().s - segs.front().s;
  const auto angle = v1 / v2;
  if (std::imag(angle) < 0) distance = -distance;
  Seg approach = segs.front();
  segs.erase(segs.begin());
  double done = 0;
  auto erase_at = [&](std::size_t k) { segs.erase(segs.begin() + static_cast<std::ptrdiff_t>(k)); };
  while (done != distance) {
    double step = 1e9;
    for (const Seg& g : segs) step = std::min(step, seg_radius(g) / 2);
    step = std::min(step, std::abs(distance - done));
    if (distance < 0) step = -step;

    for (std::size_t k = 0; k < segs.size();) {
      seg_offset(segs[k], step);
      if (seg_radius(segs[k]) < 1e-3) {
        erase_at(k);
      } else {
        ++k;
      }
    }
    for (std::size_t k = 0; k + 1 < segs.size(); ++k) {
      if (std::real(segs[k].e - segs[k + 1].s) > 1e-2) {
        Seg a = segs[k], b = segs[k + 1];
        seg_offset(a, -step);
        seg_offset(b, -step);
        const auto centre = (a.e + b.s) / 2.0;
        segs.insert(segs.begin() + static_cast<std::ptrdiff_t>(k + 1),
                    Seg::arc(distance > 0, segs[k].e, centre, segs[k + 1].s));
        ++k;
      }
    }
    for (std::size_t k = 0; k + 1 < segs.size(); ++k) {
      if (!seg_monotonic(segs[k])) {
        // LinuxCNC drops the smaller of this element and the one before.
        // (At the first element it would read before the list; not reached
        // by a profile that passed require_monotonic.)
        if (k == 0) throw G7xError{"Not monotonic"};
        if (seg_radius(segs[k]) < seg_radius(segs[k - 1])) {
          erase_at(k);
        } else {
          erase_at(k - 1);
        }
        k = 0;
        if (segs.size() < 2) break;
      }
      if (seg_radius(segs[k]) < 1e-3) {
        erase_at(k);
        k = 0;  // the loop goes on with the second element, as LinuxCNC's
        if (segs.size() < 2) break;
      } else {
        join(segs[k], segs[k + 1]);
      }
    }
    done += step;
  }
  for (std::size_t k = 0; k + 1 < segs.size(); ++k) {
    const auto mid = (segs[k].e + segs[k + 1].s) / 2.0;
    segs[k].e = segs[k + 1].s = mid;
  }
  approach.e = segs.front().s;
  segs.insert(segs.begin(), approach);
}

// Dives into the stock from `location` along element p and following,
// cutting passes along Z every delta_ in X; recursive for each pocket.
void Profile::pocket(int variant, Cx location, std::size_t p, PathSink& out) {
  double x = std::imag(pocket_starts_.back());
  std::vector<double> is;

  // Element p from `location`: false when it dived (to x or its end), true
  // when it climbs instead.
  auto dive = [&](std::size_t k, double to_x, bool fast) -> bool {
    const Seg& g = segs[k];
    if (g.kind == Seg::Line) {
      if (g.s.imag() <= g.e.imag() + kTol) return true;
      if (to_x < g.e.imag()) {
        if (fast) {
          out.rapid(g.e);
        } else {
          out.feed(g.e);
        }
        location = g.e;
        return false;
      }
      is.clear();
      crossings(g, to_x, is);
      if (is.empty()) throw G7xError{"x too large in straight dive"};
      const Cx ep(is.front(), to_x);
      if (fast) {
        out.rapid(ep);
      } else {
        out.feed(ep);
      }
      location = ep;
      return false;
    }
    if (std::abs(location - g.e) < kTol || std::real(location - g.e) <= kTol) {
      location = g.e;
      return false;
    }
    is.clear();
    crossings(g, to_x, is);
    if (is.empty()) crossings(g, to_x - kTol, is);
    if (g.ccw) {
      if (location.real() - kTol > g.c.real()) return true;
      if (is.empty() || is.back() > std::real(g.c)) {
        out.arc(g.ccw, g.c, g.e);
        location = g.e;
        return false;
      }
      const Cx ep(is.back(), to_x);
      out.arc(g.ccw, g.c, ep);
      location = ep;
      return false;
    }
    if (location.real() <= g.c.real()) return true;
    if (is.empty()) {
      out.arc(g.ccw, g.c, g.e);
      location = g.e;
      return false;
    }
    if (is.front() < std::real(g.c)) return false;  // only the far side is hit: the next pass goes deeper
    const Cx ep(is.front(), to_x);
    out.arc(g.ccw, g.c, ep);
    location = ep;
    return false;
  };
  // A counter-clockwise arc from `location`, up to its end or, when the
  // end lies past the centre, to the arc's top (where it stops climbing).
  auto ccw_arc_to_top = [&](const Seg& g) {
    Cx ep = g.e;
    if (g.e.real() < g.c.real()) {
      ep.real(g.c.real());
      ep.imag(g.c.imag() + std::abs(g.s - g.c));
    }
    if (std::abs(location - ep) > 1e-3) out.arc(g.ccw, g.c, ep);
    location = ep;
  };
  // Follows element k up the contour; true when it does not climb (a
  // pocket starts there).
  auto climb = [&](std::size_t k) -> bool {
    const Seg& g = segs[k];
    if (g.kind == Seg::Line) {
      if (g.e.imag() + kTol < g.s.imag()) return true;
      if (std::abs(location - g.s) > kTol) throw G7xError{"How did we get here?"};
      out.feed(g.e);
      location = g.e;
      return false;
    }
    if (!g.ccw) {
      if (location.real() > g.c.real()) return true;
      if (std::abs(location - g.e) > 1e-3) out.arc(g.ccw, g.c, g.e);
      location = g.e;
      return false;
    }
    if (location.real() < g.c.real()) return true;
    ccw_arc_to_top(g);
    return true;
  };
  // G71.1/G72.1: after the passes, only the climbing parts of the contour.
  auto climb_only = [&](std::size_t k) {
    const Seg& g = segs[k];
    is.clear();
    if (g.kind == Seg::Line) {
      if (g.e.imag() < g.s.imag()) return;
      crossings(g, location.imag(), is);
      if (is.empty()) return;
      location.real(is.front());
      out.feed(location);
      out.feed(g.e);
      location = g.e;
      return;
    }
    crossings(g, location.imag(), is);
    if (is.empty()) return;
    if (!g.ccw) {
      if (is.back() > g.c.real()) return;
      location.real(is.back());
      out.feed(location);
      if (std::abs(location - g.e) > 1e-3) out.arc(g.ccw, g.c, g.e);
      location = g.e;
      return;
    }
    if (is.front() < g.c.real()) return;
    location.real(is.front());
    out.feed(location);
    ccw_arc_to_top(g);
  };

  if (variant == 2) {
    // G71.2/G72.2: no first roughing passes, only the pockets.
    for (; p < segs.size(); ++p) {
      if (dive(p, -1e9, p == 0)) break;
    }
    variant = 3;
  }

  while (p < segs.size()) {
    while (x - kTol > std::imag(location)) x -= delta_;
    if (dive(p, x, p == 0)) {
      if (variant == 1) {
        for (; p < segs.size(); ++p) climb_only(p);
      } else {
        for (; p < segs.size(); ++p) {
          if (climb(p)) {
            if (variant == 3) {
              if (std::imag(location) > std::imag(pocket_starts_.back()) && pocket_starts_.size() > 1) {
                pocket_starts_.pop_back();
              }
              if (pocket_starts_.size() == 1) pocket_starts_.push_back(location);
            }
            pocket(variant, location, p, out);
            return;
          }
        }
      }
      return;
    }
    if (std::abs(std::imag(location) - x) > kTol) {
      ++p;  // this element ends above x: go on with the next
      continue;
    }
    for (std::size_t ip = p; ip < segs.size(); ++ip) {
      is.clear();
      crossings(segs[ip], location.imag(), is);
      if (is.empty()) continue;
      // The diving element itself can be hit again when it is an arc.
      const double dest_z = ip != p ? is.front() : is.back();
      const double distance = std::abs(dest_z - std::real(location));
      if (dest_z - kTol > std::real(location)) continue;
      if (distance < kTol) {
        if (p == ip) continue;
        if (std::abs(location - segs[ip].s) < kTol) {
          p = ip;  // another element starts here: dive along it
          break;
        }
        x -= delta_;  // a zero-length cut
        break;
      }
      Cx dest = location;
      dest.real(dest_z);
      out.feed(dest);
      // a short cut gets a proportionally short escape
      const double escape_scale = std::min(1.0, distance / 2 / std::real(escape_));
      dest += escape_scale * escape_;
      out.rapid(dest);
      dest = location - std::conj(escape_scale * escape_);
      out.rapid(dest);
      if (p == 0) {
        out.rapid(location);
      } else {
        out.feed(location);
      }
      x -= delta_;
      break;
    }
  }
}

// G70: `passes` passes along the contour, at distance d for the first and
// e for the last, each from a rapid to the contour's start.
void Profile::g70(PathSink& out, double x, double z, double d, double e, double passes) {
  segs.front().s = Cx(z, x);
  Profile check = *this;
  check.segs.erase(check.segs.begin());
  check.orient();
  for (const Seg& g : check.segs) {
    if (!seg_monotonic(g)) {
      check.quarter_turn();
      check.orient();
      break;
    }
  }
  check.require_monotonic();
  if (check.turn_ & 4) quarter_turn();
  orient();
  finish_corners();
  require_monotonic();
  Unturned turned(out, turn_);
  for (int pass = static_cast<int>(passes); pass > 0; pass--) {
    const double distance = (pass - 1) * (d - e) / passes + e;
    Profile path = *this;
    path.add_distance(distance);
    turned.rapid(path.segs.front().s);
    turned.rapid(path.segs.front().e);
    for (std::size_t k = 1; k < path.segs.size(); ++k) seg_draw(path.segs[k], turned);
  }
}

// G71 (G72 with quarter_turn): roughing down to distance d from the
// contour (shifted by u, w), cuts every i, retracting by r.
void Profile::g71(PathSink& out, int variant, double x, double z, double u, double w, double d, double i, double r,
                  bool quarter) {
  segs.front().s = Cx(z, x);
  if (quarter) quarter_turn();
  orient();
  finish_corners();
  require_monotonic();
  add_distance(d);
  const Cx displacement(w, u);
  for (Seg& g : segs) seg_shift(g, displacement);
  Unturned turned(out, turn_);
  delta_ = std::max(i, 2 * kTol);
  escape_ = r * Cx{1, 1};
  turned.rapid(segs.front().s);
  if (std::imag(segs.back().e) < std::imag(segs.front().s)) {
    Cx ep = segs.back().e;
    ep.imag(std::imag(segs.front().s));
    segs.push_back(Seg::line(segs.back().e, ep));
  }
  pocket_starts_.push_back(segs.front().s);
  pocket(variant, segs.front().s, 0, turned);
}

}  // namespace

// The cycle's moves as G0/G1/G2/G3 blocks of the interpreter (position,
// cutter compensation, feed checks as for programmed moves).
void Interpreter::State::convert_g7x(int g) {
  const int cycle = g / 10;
  const int variant = g % 10;
  char buf[128];
  if (!block.has_word('q')) fail("G7x.x  requires a Q word");
  if (cutter_side != 400 && cycle != 70) {
    std::snprintf(buf, sizeof buf, "G%d.%d cannot be used with cutter compensation enabled", cycle, variant);
    fail(buf);
  }
  if (plane != Plane::XZ) {
    std::snprintf(buf, sizeof buf, "G%d.%d can only be used in XZ plane (G18)", cycle, variant);
    fail(buf);
  }
  // Distance modes are absolute while the cycle runs (the contour's own
  // words are read in the modes of the G7x block).
  const bool was_absolute = absolute, was_ijk_absolute = ijk_absolute;
  struct Restore {
    State& st;
    bool abs, ijk;
    ~Restore() {
      st.absolute = abs;
      st.ijk_absolute = ijk;
    }
  } restore{*this, was_absolute, was_ijk_absolute};
  absolute = true;
  ijk_absolute = true;

  const Block cycle_block = block;
  double x = pos[0], z = pos[2];
  if (!was_absolute) {
    if (block.has_word('x')) x += block.get('x');
    if (block.has_word('z')) z += block.get('z');
  } else {
    if (block.has_word('x')) x = block.get('x');
    if (block.has_word('z')) z = block.get('z');
  }
  // A rapid to the block's X Z first (its words read as absolute).
  motion_mode = 0;
  straight(0, find_ends(false));

  // Read the contour: call the subroutine, take its blocks' moves.
  const int line_at = current_line;
  const std::string text_at = line_text;
  const int n_at = n_number;
  Profile path;
  Cx start(z, x);
  {
    const double q = block.get('q');
    block.o_type = OType::Call;
    block.o_name = std::to_string(round_to_int(q));
    block.call_args.clear();
    const int depth = static_cast<int>(frames.size());
    do_call();
    capture_depth = depth;
    struct EndCapture {
      int& d;
      ~EndCapture() { d = -1; }
    } end_capture{capture_depth};
    for (;;) {
      const ReadResult r = read_block();
      if (r == ReadResult::Yield) {
        lines_this_read = 0;
        continue;
      }
      if (r == ReadResult::End) break;  // the subroutine returned
      Cx end = was_absolute ? start : Cx(0, 0);
      Cx centre(0, 0);
      if (block.has_word('u')) {
        if (!was_absolute) fail("G7x error: Cannot use U in incremental mode (G91)");
        if (block.has_word('x')) fail("G7x error: Cannot use U and X in the same block");
        double u = block.get('u');
        if (diameter_mode) u /= 2;
        end.imag(end.imag() + u);
      } else if (block.has_word('x')) {
        end.imag(block.get('x'));
      }
      if (block.has_word('w')) {
        if (!was_absolute) fail("G7x error: Cannot use W in incremental mode (G91)");
        if (block.has_word('z')) fail("G7x error: Cannot use W and Z in the same block");
        end.real(end.real() + block.get('w'));
      } else if (block.has_word('z')) {
        end.real(block.get('z'));
      }
      if (block.has_word('i')) centre.imag(block.get('i'));
      if (block.has_word('k')) centre.real(block.get('k'));
      if (!was_absolute) end += start;
      if (block.g[kGMotion] != -1) motion_mode = block.g[kGMotion];
      if (start == end) continue;
      const int m = motion_mode;
      if (m == 0 || m == 10) {
        path.segs.push_back(Seg::line(start, end));
      } else if (m == 20 || m == 30) {
        if (block.has_word('r')) {
          if (block.has_word('i') || block.has_word('k')) fail("G7X error: both R and I or K flag used for arc");
          const double rr = block.get('r');
          centre = (start + end) / 2.0;
          const auto dv = kI * std::sqrt((rr * rr - std::norm(end - start) / 4) / std::norm(end - start)) * (end - start);
          if (m == 30) {
            centre += dv;
          } else {
            centre -= dv;
          }
        } else {
          if (!block.has_word('i') && !block.has_word('k')) fail("G7X error: either I or K must be present for arc");
          if (!was_ijk_absolute) centre += start;
        }
        path.segs.push_back(Seg::arc(m == 30, start, centre, end));
      }
      if (m == 0 || m == 10 || m == 20 || m == 30) {
        if (block.has_word('a') && block.has_word('c')) fail("G7X error: Both A and C parameters on a corner");
        if (block.has_word('a')) {
          Seg f = Seg::arc(false, end, end, end);
          f.corner = Seg::Fillet;
          f.finish = block.get('a');
          path.segs.push_back(f);
        }
        if (block.has_word('c')) {
          Seg f = Seg::line(end, end);
          f.corner = Seg::Chamfer;
          f.finish = block.get('c');
          path.segs.push_back(f);
        }
      }
      pos[0] = end.imag();
      pos[2] = end.real();
      start = end;
    }
  }
  current_line = line_at;
  line_text = text_at;
  n_number = n_at;
  // The rest of the cycle's block (M0, M2 ... on the same line) runs after
  // it; LinuxCNC 2.9 goes on with the subroutine's last block instead and
  // drops them.
  struct RestoreBlock {
    Block& b;
    const Block& saved;
    ~RestoreBlock() { b = saved; }
  } restore_block{block, cycle_block};
  if (path.segs.size() <= 1) return;

  auto word = [&](char c, double dflt) { return cycle_block.has_word(c) ? cycle_block.get(c) : dflt; };
  const double d = word('d', 0), e = word('e', 0), i = word('i', 1), p = word('p', 1), r = word('r', 0.5),
               u = word('u', 0), w = word('w', 0);
  if (i <= 0) fail("G7X error: I must be greater than zero.");

  // The moves are blocks of their own words only (LinuxCNC reuses the
  // subroutine's last block, which has none).
  class Machine : public PathSink {
   public:
    explicit Machine(State& st) : st_(st) {}
    void feed(Cx end) override { line(10, end); }
    void rapid(Cx end) override { line(0, end); }
    void arc(bool ccw, Cx centre, Cx end) override {
      set_xz(end);
      st_.block.set('i', centre.imag());
      st_.block.set('k', centre.real());
      if (std::fabs(st_.pos[2] - end.real()) < 0.0001 && std::fabs(st_.pos[0] - end.imag()) < 0.0001) return;
      const int g = ccw ? 30 : 20;
      st_.motion_mode = g;
      st_.convert_arc(g, st_.find_ends(false));
    }

   private:
    void set_xz(Cx end) {
      // A bound LinuxCNC 2.9 does not have: on some contours (its test
      // interp/g71-endless-loop) its G71.2 repeats one move for ever.
      if (end == last_) {
        if (++repeats_ > kMaxRepeats) {
          throw G7xError{"the cycle makes no progress: the same move more than " + std::to_string(kMaxRepeats) +
                         " times in a row"};
        }
      } else {
        repeats_ = 0;
        last_ = end;
      }
      st_.block.set('x', end.imag());
      st_.block.set('z', end.real());
    }
    Cx last_{std::nan(""), 0};
    int repeats_ = 0;
    void line(int g, Cx end) {
      set_xz(end);
      st_.motion_mode = g;
      st_.straight(g, st_.find_ends(false));
    }
    State& st_;
  } machine(*this);
  block.clear();
  block.line = cycle_block.line;
  try {
    switch (cycle) {
      case 70: path.g70(machine, x, z, d, e, p); break;
      case 71: path.g71(machine, variant, x, z, u, w, d, i, r, false); break;
      default: path.g71(machine, variant, x, z, u, w, d, i, r, true); break;
    }
  } catch (const G7xError& err) {
    fail("G7X error: " + err.what);
  }
}

}  // namespace cnc::interp
