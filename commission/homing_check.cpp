#include "commission/homing_check.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "commission/steps.hpp"
#include "commission/switches.hpp"

namespace cnc::commission {

namespace {
std::string mm(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.4f", v);
  return b;
}
}  // namespace

const std::vector<HomingMethod>& homing_methods() {
  static const std::vector<HomingMethod> m = {
      {"controller", "the controller's sequence: search onto the home switch, back off, latch on leaving it slowly, "
                     "move to HOME (HOME_SEARCH_VEL, HOME_LATCH_VEL)"},
      {"drive:1", "negative limit switch, then the first index pulse moving off it (+)"},
      {"drive:2", "positive limit switch, then the first index pulse moving off it (-)"},
      {"drive:3", "home switch active on the + side: index pulse just - of its edge"},
      {"drive:4", "home switch active on the + side: index pulse just + of its edge"},
      {"drive:5", "home switch active on the - side: index pulse just + of its edge"},
      {"drive:6", "home switch active on the - side: index pulse just - of its edge"},
      {"drive:17", "negative limit switch: its edge, leaving it (+), no index"},
      {"drive:18", "positive limit switch: its edge, leaving it (-), no index"},
      {"drive:19", "home switch active on the + side: its edge, approached from the + side, no index"},
      {"drive:20", "home switch active on the + side: its edge, approached from the - side, no index"},
      {"drive:21", "home switch active on the - side: its edge, approached from the - side, no index"},
      {"drive:22", "home switch active on the - side: its edge, approached from the + side, no index"},
      {"drive:33", "the next index pulse in - direction"},
      {"drive:34", "the next index pulse in + direction"},
      {"drive:35", "the current position is the reference (no motion)"},
      {"drive:37", "the current position is the reference (no motion; the newer number of 35)"},
  };
  return m;
}

int drive_method(const std::string& method) {
  if (method.rfind("drive:", 0) != 0) return 0;
  try {
    std::size_t n = 0;
    const int v = std::stoi(method.substr(6), &n);
    return n == method.size() - 6 ? v : -1;
  } catch (const std::exception&) {
    return -1;
  }
}

double spread(const std::vector<double>& v) noexcept {
  if (v.size() < 2) return 0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

double home_switch_reference(const AxisSwitches& s, double search_velocity) {
  // Searching towards minus the switch lies below the start: its upper
  // edge (if both were seen) is the one met first.
  if (search_velocity < 0 && s.home.has_high) return s.home.position_high;
  return s.home.position;
}

AxisHoming plan_homing(const Axis& a, const std::string& method) {
  const std::string ax = std::string("axis ") + a.letter;
  bool known = false;
  for (const auto& m : homing_methods()) known = known || m.id == method;
  if (!known)
    throw std::invalid_argument(ax + ": homing method \"" + method +
                                "\" is not one of cnc-commission homing-methods (controller, drive:N)");
  if (!a.switches || !a.switches->home.seen)
    throw std::invalid_argument(ax + ": the home switch was not found: run `cnc-commission axis " + a.letter +
                                " switches` first (the homing check needs the home switch, also to measure drive methods)");
  const AxisSwitches& s = *a.switches;
  const int dm = drive_method(method);
  if ((dm == 1 || dm == 17 || dm == 2 || dm == 18) && !(s.neg_limit.seen && s.pos_limit.seen))
    throw std::invalid_argument(ax + ": " + method + " homes on a limit switch: the switch search must have found both");
  // A drive's methods speak of its own direction: with REVERSE the
  // table's minus is the drive's plus (and its negative limit input is the
  // table's positive switch). A home switch method must name the side the
  // switch is on, seen from where the search started.
  const double table_side = s.home.position < s.start ? -1.0 : 1.0;
  const double drive_side = a.scaling.reverse ? -table_side : table_side;
  const int base = dm > 16 && dm < 33 ? dm - 16 : dm;
  if (base >= 3 && base <= 6) {
    const double method_side = base <= 4 ? 1.0 : -1.0;
    if (method_side != drive_side) {
      const int other = (base == 3 ? 5 : base == 4 ? 6 : base == 5 ? 3 : 4) + (dm > 16 ? 16 : 0);
      throw std::invalid_argument(ax + ": " + method + " looks for the home switch on the drive's " +
                                  (method_side > 0 ? "+" : "-") + " side, but it is on the drive's " +
                                  (drive_side > 0 ? "+" : "-") + " side" + (a.scaling.reverse ? " (the axis is REVERSE)" : "") +
                                  ": use drive:" + std::to_string(other));
    }
  }
  AxisHoming h;
  h.method = method;
  // Towards the home switch from where the switch search started, at the
  // search speed (at most 10 mm/s); latch on leaving at a tenth of it.
  const double dir = s.home.position < s.start ? -1.0 : 1.0;
  const double v = std::clamp(s.velocity, 1.0, 10.0);
  h.search_velocity = dir * v;
  h.latch_velocity = -dir * std::max(0.1, v / 10);
  h.home_offset = home_switch_reference(s, h.search_velocity);
  const bool drive_neg = (dm == 1 || dm == 17) != a.scaling.reverse;  // the drive's limit, in table terms
  if (dm == 1 || dm == 17 || dm == 2 || dm == 18) h.home_offset = drive_neg ? s.neg_limit.position : s.pos_limit.position;
  if (dm == 35 || dm == 37) h.home_offset = 0;
  // HOME: 5 mm off the home switch towards the start, inside the limits.
  const double edge = home_switch_reference(s, h.search_velocity);
  h.home = std::clamp(edge - dir * 5.0, a.min_limit, a.max_limit);
  h.measured = dm == 0 ? "motor position of the latched home switch edge (mm)"
                       : "home switch edge in the frame the drive set (mm), latched in the servo thread crossing it at 1 mm/s";
  return h;
}

AxisHoming plan_gantry_homing(const Axis& a, const AxisHoming& first, const std::string& method, double squaring_mm) {
  const Axis second = gantry_view(a);
  if (!a.gantry->switches)
    throw std::invalid_argument(std::string("axis ") + a.letter + ": the gantry's second drive (joint " +
                                std::to_string(second.joint) + ") has no switch search of its own: run `cnc-commission axis " +
                                a.letter + " switches` again (it searches both sides)");
  AxisHoming h;
  try {
    h = plan_homing(second, method);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(e.what()) + " (the gantry's second drive, joint " + std::to_string(second.joint) + ")");
  }
  h.home = first.home;
  h.home_offset += squaring_mm;
  return h;
}

double measure_racking(const Controller& c, const Axis& a, const std::string& first_pin, const std::string& second_pin) {
  clear_abort();
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(std::string("axis ") + a.letter + ": the E-stop chain is open: close it before homing");
  double d = 0;
  try {
    machine_on(c);
    c.cnc({"--timeout", "150", "home", std::to_string(a.joint)});
    const double home = a.homing ? std::clamp(a.homing->home, a.min_limit, a.max_limit) : 0.0;
    for (int i = 0; i < 100; ++i) {
      const auto jt = nlohmann::json::parse(c.cnc({"status", "--json"})).at("joints").at(a.joint);
      if (jt.value("homed", false) && jt.value("inpos", false) && std::fabs(jt.at("pos_fb").get<double>() - home) < 0.01) break;
      if (abort_requested()) throw std::runtime_error(std::string("axis ") + a.letter + ": aborted while homing");
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    d = c.getp(second_pin) - c.getp(first_pin);
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what() + switch_off_after_failure(c));
  }
  c.cnc({"off"});
  return d;
}

std::vector<double> run_homing(const Controller& c, const Axis& a, int repeat, double away_mm, std::FILE* progress) {
  if (!a.homing) throw std::invalid_argument(std::string("axis ") + a.letter + ": no homing method chosen");
  if (!a.switches || !a.switches->home.seen) throw std::invalid_argument(std::string("axis ") + a.letter + ": the home switch was not found");
  const AxisHoming& h = *a.homing;
  const bool drive = drive_method(h.method) != 0;
  const std::string joint = std::to_string(a.joint);
  const double dir = h.search_velocity < 0 ? -1.0 : 1.0;  // towards the switch
  const double home = std::clamp(h.home, a.min_limit, a.max_limit);  // as the writer writes it
  std::vector<double> refs;
  clear_abort();
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(std::string("axis ") + a.letter + ": the E-stop chain is open: close it before homing");
  SwitchLatches latches;  // detached after the machine is off, whatever happens
  try {
    machine_on(c);
    // Drive methods: the home switch's edge where the servo thread latched
    // it (1 um a cycle at 1 mm/s); without the latch, crossed again slowly.
    std::string why;
    const bool latched = drive && latches.attach(c, a, why);
    if (drive && !latched && progress) std::fprintf(progress, "axis %c: no servo-thread latch (%s)\n", a.letter, why.c_str());
    for (int k = 0; k < repeat; ++k) {
      if (progress) {
        std::fprintf(progress, "progress: %d/%d axis %c: homing run %d (%s)\n", k + 1, repeat, a.letter, k + 1, h.method.c_str());
        std::fflush(progress);
      }
      if (abort_requested()) throw std::runtime_error(std::string("axis ") + a.letter + ": homing aborted before run " + std::to_string(k + 1));
      c.cnc({"--timeout", "150", "home", joint});
      if (abort_requested()) throw std::runtime_error(std::string("axis ") + a.letter + ": homing aborted after run " + std::to_string(k + 1));
      // At rest at HOME.
      nlohmann::json jt;
      for (int i = 0; i < 100; ++i) {
        jt = nlohmann::json::parse(c.cnc({"status", "--json"})).at("joints").at(a.joint);
        if (jt.value("inpos", false) && std::fabs(jt.at("pos_fb").get<double>() - home) < 0.01) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      if (!jt.value("homed", false)) throw std::runtime_error(std::string("axis ") + a.letter + ": run " + std::to_string(k + 1) + " ended but the joint is not homed");
      double ref = 0;
      if (!drive) {
        ref = jt.at("motor_pos_fb").get<double>() - jt.at("pos_fb").get<double>() + h.home_offset;
      } else {
        // Towards the switch at 1 mm/s until the home input changes.
        const double reach = std::fabs(home - h.home_offset) + 3.0;
        const SwitchLatchReading before = latched ? read_switch_latches(c) : SwitchLatchReading{};
        const auto s = jog_and_sample(c, a, dir * reach, 1.0, &SwitchSample::home);
        if (!first_change(s, &SwitchSample::home, ref))
          throw std::runtime_error(std::string("axis ") + a.letter + ": the home switch did not change within " + mm(reach) +
                                   " mm of HOME after run " + std::to_string(k + 1) + ": is the drive's reference far from it?");
        const bool found = latched && latched_change(s, &SwitchSample::home, latch_difference(before, read_switch_latches(c)).home, ref);
        if (!found)
          ref = cross_edge(c, a, &SwitchSample::home, "home switch", ref, dir, std::max(1.0, std::fabs(h.search_velocity)), 0.25, 0.01);
      }
      refs.push_back(ref);
      if (progress) std::fprintf(progress, "axis %c: run %d: reference %s mm\n", a.letter, k + 1, mm(ref).c_str());
      // Away from the switch (towards the start), forget the home.
      const double now = nlohmann::json::parse(c.cnc({"status", "--json"})).at("joints").at(a.joint).at("pos_cmd").get<double>();
      jog_and_sample(c, a, (home - now) - dir * away_mm, std::max(1.0, std::fabs(h.search_velocity)), nullptr);
      c.cnc({"unhome", joint});
    }
  } catch (const std::exception& e) {
    const std::string off = switch_off_after_failure(c);
    const std::string left = latches.detach();
    throw std::runtime_error(e.what() + off + (left.empty() ? "" : "; " + left));
  }
  c.cnc({"off"});
  const std::string left = latches.detach();
  if (!left.empty() && progress) {
    std::fprintf(progress, "axis %c: warning: %s\n", a.letter, left.c_str());
    std::fflush(progress);
  }
  return refs;
}

}  // namespace cnc::commission

namespace cnc::commission {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}
}  // namespace

double written_home(const Axis& a) noexcept {
  return a.homing ? std::clamp(a.homing->home, a.min_limit, a.max_limit) : 0.0;
}

std::string joint_homing_keys(const Axis& a) {
  if (!a.homing) return "HOME = 0\nHOME_OFFSET = 0\nHOME_SEQUENCE = 0\n";
  const AxisHoming& h = *a.homing;
  const double home = written_home(a);
  std::string s = "# Homing commissioned (" + h.method + "), spread " + num(h.spread) + " mm over " +
                  std::to_string(h.references.size()) + " runs.\n";
  const int m = drive_method(h.method);
  if (m != 0) {
    s += "HOME_MODE = DRIVE\n";
    if (m == 1 || m == 2 || m == 17 || m == 18) s += "HOME_IGNORE_LIMITS = YES\n";  // it homes on one
  } else {
    s += "HOME_SEARCH_VEL = " + num(h.search_velocity) + "\nHOME_LATCH_VEL = " + num(h.latch_velocity) + "\n";
  }
  s += "HOME_OFFSET = " + num(h.home_offset) + "\nHOME = " + num(home) + "\nHOME_SEQUENCE = 0\n";
  return s;
}

std::string drive_homing_keys(const Axis& a) {
  if (!a.homing) return "";
  const int m = drive_method(a.homing->method);
  if (m <= 0) return "";
  return "HOME_METHOD = " + std::to_string(m) + "\nHOME_SEARCH_VEL = " + num(std::fabs(a.homing->search_velocity)) +
         "\nHOME_LATCH_VEL = " + num(std::fabs(a.homing->latch_velocity)) +
         "\nHOME_ACCEL = " + num(a.max_acceleration) + "\n";
}

std::string switch_nets(const std::vector<const Axis*>& axes) {
  struct Net {
    std::string name, from, to;
    bool invert;
  };
  std::vector<Net> nets;
  // Net names start with the axis letter; a letter's second joint (a
  // gantry's second drive) adds "2", as the writer names its drive.
  const auto name_of = [&axes](const Axis* a) {
    std::string l(1, static_cast<char>(std::tolower(static_cast<unsigned char>(a->letter))));
    for (const Axis* x : axes) {
      if (x == a) break;
      if (x->letter == a->letter) return l + "2";
    }
    return l;
  };
  for (const Axis* a : axes) {
    if (!a->switches || !a->enabled) continue;
    const std::string l = name_of(a);
    const std::string d = drive_pin_prefix(*a), j = "joint." + std::to_string(a->joint) + ".";
    const AxisSwitches& s = *a->switches;
    if (s.neg_limit.seen) nets.push_back({l + "-neg-lim", d + "neg-lim-sw", j + "neg-lim-sw-in", !s.neg_limit.active_high});
    if (s.pos_limit.seen) nets.push_back({l + "-pos-lim", d + "pos-lim-sw", j + "pos-lim-sw-in", !s.pos_limit.active_high});
    if (s.home.seen) nets.push_back({l + "-home-sw", d + "home-sw", j + "home-sw-in", !s.home.active_high});
  }
  // Drive homing: motion's handshake with the drive.
  std::string handshake;
  for (const Axis* a : axes) {
    if (!a->homing || drive_method(a->homing->method) <= 0 || !a->enabled) continue;
    const std::string l = name_of(a);
    const std::string d = drive_pin_prefix(*a), j = "joint." + std::to_string(a->joint) + ".";
    handshake += "net " + l + "-home-start " + j + "drive-home-start => " + d + "home-start\n";
    for (const char* k : {"busy", "done", "error"})
      handshake += "net " + l + "-home-" + k + " " + d + "home-" + k + " => " + j + "drive-home-" + k + "\n";
  }
  if (!handshake.empty()) handshake = "\n# Drive homing (HOME_MODE = DRIVE): motion starts it, the drive reports.\n" + handshake;
  if (nets.empty()) return handshake;
  std::string out = handshake + "\n# Limit and home switches as the switch search found them (cnc-commission axis L\n"
                    "# switches); an input active low (a normally closed switch) goes through a not.\n";
  std::string inverted;
  for (const Net& n : nets)
    if (n.invert) inverted += (inverted.empty() ? "" : ",") + n.name + "-inv";
  if (!inverted.empty()) out += "loadrt not names=" + inverted + "\n";
  for (const Net& n : nets) {
    if (n.invert) {
      out += "addf " + n.name + "-inv servo-thread\n";
      out += "net " + n.name + "-in " + n.from + " => " + n.name + "-inv.in\n";
      out += "net " + n.name + " " + n.name + "-inv.out => " + n.to + "\n";
    } else {
      out += "net " + n.name + " " + n.from + " => " + n.to + "\n";
    }
  }
  return out;
}

}  // namespace cnc::commission
