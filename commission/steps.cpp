#include "commission/steps.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace cnc::commission {

namespace {
std::string axis_name(char l) { return std::string("axis ") + l; }
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}
Axis& need_axis(State& s, char letter) {
  Axis* a = s.axis(letter);
  if (!a) throw std::invalid_argument(axis_name(letter) + " has no drive yet: assign one first (cnc-commission axis " +
                                      std::string(1, letter) + " assign --node N)");
  return *a;
}
// The scanned node `node`, which must be a CiA 402 drive with CSP, not in
// fault (`what`: "" the axis' drive, or which other drive it is).
const ScannedNode& check_drive(const State& s, char letter, int node, const std::string& what) {
  const std::string who = (what.empty() ? "" : axis_name(letter) + ": " + what + ", ") + "node " + std::to_string(node);
  const ScannedNode* n = s.node(node);
  if (!n) throw std::invalid_argument(who + " was not found by the bus scan: scan first, or check its node-ID");
  if (!n->cia402)
    throw std::invalid_argument(who + " (" + n->name + ") is not a CiA 402 drive with CSP: it cannot drive " + axis_name(letter));
  if (n->fault) throw std::invalid_argument(who + " (" + n->name + ") is in fault: clear the fault and scan again");
  return *n;
}

// The drives (node-IDs or slave positions, 0 none) and joints of axis
// `letter` and its gantry pair must not belong to another axis, nor the
// gantry's joint be the axis' own.
void check_free(const State& s, char letter, int joint, int node, int slave, const std::optional<GantryDrive>& gantry) {
  if (gantry && gantry->joint == joint)
    throw std::invalid_argument(axis_name(letter) + ": the gantry's second drive needs a joint of its own, not joint " +
                                std::to_string(joint));
  if (gantry && (gantry->joint < 0 || gantry->joint > 15))
    throw std::invalid_argument(axis_name(letter) + ": gantry joint " + std::to_string(gantry->joint) + " outside 0..15");
  for (const Axis& a : s.axes) {
    if (a.letter == letter) continue;
    const std::string other = "axis " + std::string(1, a.letter) + (a.gantry ? " (with its gantry pair)" : "");
    for (int n : {node, gantry ? gantry->node : 0}) {
      if (n > 0 && (a.node == n || (a.gantry && a.gantry->node == n)))
        throw std::invalid_argument("node " + std::to_string(n) + " already drives " + other);
    }
    for (int p : {slave, gantry ? gantry->slave : 0}) {
      if (p > 0 && (a.slave == p || (a.gantry && a.gantry->slave == p)))
        throw std::invalid_argument("EtherCAT slave " + std::to_string(p) + " already drives " + other);
    }
    for (int j : {joint, gantry ? gantry->joint : -1}) {
      if (j >= 0 && (a.joint == j || (a.gantry && a.gantry->joint == j)))
        throw std::invalid_argument("joint " + std::to_string(j) + " already belongs to " + other);
    }
  }
}
}  // namespace

Axis gantry_view(const Axis& a) {
  if (!a.gantry) throw std::invalid_argument(axis_name(a.letter) + " is not a gantry pair");
  const GantryDrive& g = *a.gantry;
  Axis v = a;
  v.joint = g.joint;
  v.node = g.node;
  v.slave = g.slave;
  v.scaling.reverse = a.scaling.reverse != g.reverse;
  v.scaling.correction = g.correction;
  v.scaling.dial_checked = g.dial_checked;
  v.direction = g.direction;
  if (g.switches) v.switches = g.switches;
  if (g.homing) v.homing = g.homing;
  return v;
}

std::vector<Axis> step_joints(const Axis& a) {
  if (!a.gantry) return {a};
  return {a, gantry_view(a)};
}

std::vector<MachineJoint> machine_joints(const State& s) {
  std::vector<MachineJoint> out;
  for (const Axis& a : s.axes) {
    out.push_back({a, false});
    if (a.gantry) out.push_back({gantry_view(a), true});
  }
  std::stable_sort(out.begin(), out.end(), [](const MachineJoint& x, const MachineJoint& y) { return x.axis.joint < y.axis.joint; });
  return out;
}

Axis& assign_axis(State& s, char letter, int joint, int node, std::optional<GantryDrive> gantry) {
  const std::string valid = "XYZABCUVW";
  if (valid.find(letter) == std::string::npos)
    throw std::invalid_argument(std::string("axis \"") + letter + "\": expected one of X Y Z A B C U V W");
  if (joint < 0 || joint > 15) throw std::invalid_argument(axis_name(letter) + ": joint " + std::to_string(joint) + " outside 0..15");
  const ScannedNode* n = &check_drive(s, letter, node, "");
  if (gantry) {
    check_drive(s, letter, gantry->node, "the gantry's second drive");
    if (gantry->node == node)
      throw std::invalid_argument(axis_name(letter) + ": the gantry's second drive is node " + std::to_string(node) +
                                  ", the first one's: give the other drive's node-ID");
  }
  check_free(s, letter, joint, node, 0, gantry);
  Axis* a = s.axis(letter);
  if (!a) {
    s.axes.push_back(Axis{});
    a = &s.axes.back();
    a->letter = letter;
  }
  if (a->node != node) {
    a->direction.reset();
    a->scaling = AxisScaling{};
  }
  a->joint = joint;
  a->node = node;
  a->gantry = gantry;
  if (a->scaling.encoder_counts <= 0 && n->encoder_increments) {
    const double revs = n->encoder_motor_revs.value_or(1) ? n->encoder_motor_revs.value_or(1) : 1;
    a->scaling.encoder_counts = *n->encoder_increments / revs;
  }
  return *a;
}

Axis& assign_axis_ethercat(State& s, char letter, int joint, int position, std::optional<GantryDrive> gantry) {
  const std::string valid = "XYZABCUVW";
  if (valid.find(letter) == std::string::npos)
    throw std::invalid_argument(std::string("axis \"") + letter + "\": expected one of X Y Z A B C U V W");
  if (joint < 0 || joint > 15) throw std::invalid_argument(axis_name(letter) + ": joint " + std::to_string(joint) + " outside 0..15");
  const ScannedSlave* sl = nullptr;
  for (const ScannedSlave& x : s.slaves)
    if (static_cast<int>(x.position) == position) sl = &x;
  if (!sl)
    throw std::invalid_argument("EtherCAT slave " + std::to_string(position) +
                                " was not found by the segment scan: scan-ethercat first, or check its position");
  if (!sl->coe)
    throw std::invalid_argument("EtherCAT slave " + std::to_string(position) + " (" + sl->name +
                                ") has no CoE mailbox: it is not a CiA 402 drive and cannot drive " + axis_name(letter));
  if (gantry) {
    const ScannedSlave* g = nullptr;
    for (const ScannedSlave& x : s.slaves)
      if (static_cast<int>(x.position) == gantry->slave) g = &x;
    if (!g || !g->coe)
      throw std::invalid_argument(axis_name(letter) + ": the gantry's second drive, EtherCAT slave " +
                                  std::to_string(gantry->slave) +
                                  (g ? " has no CoE mailbox: it is not a CiA 402 drive" : " was not found by the segment scan"));
    if (gantry->slave == position)
      throw std::invalid_argument(axis_name(letter) + ": the gantry's second drive is slave " + std::to_string(position) +
                                  ", the first one's: give the other drive's position");
  }
  check_free(s, letter, joint, 0, position, gantry);
  Axis* a = s.axis(letter);
  if (!a) {
    s.axes.push_back(Axis{});
    a = &s.axes.back();
    a->letter = letter;
  }
  if (a->slave != position || a->node != 0) {
    a->direction.reset();
    a->scaling = AxisScaling{};
  }
  a->joint = joint;
  a->node = 0;
  a->slave = position;
  a->gantry = gantry;
  if (a->scaling.encoder_counts <= 0 && sl->encoder_increments) {
    const double revs = sl->encoder_motor_revs.value_or(1) ? sl->encoder_motor_revs.value_or(1) : 1;
    a->scaling.encoder_counts = *sl->encoder_increments / revs;
  }
  return *a;
}

namespace {
// The factor group the scan read from an axis' drive, a CANopen node or an
// EtherCAT slave (0x608F encoder increments per motor revolutions, 0x6091
// gear), as set_scaling uses it.
struct DriveFactors {
  std::optional<uint32_t> encoder_increments, encoder_motor_revs, gear_motor_revs, gear_shaft_revs;
};
template <class N>
DriveFactors factors_of(const N* n) {
  if (!n) return {};
  return {n->encoder_increments, n->encoder_motor_revs, n->gear_motor_revs, n->gear_shaft_revs};
}
DriveFactors factors_of(const State& s, const Axis& a) {
  return a.slave ? factors_of(s.slave(a.slave)) : factors_of(s.node(a.node));
}
}  // namespace

double set_scaling(State& s, char letter, double screw_lead, double encoder_counts, double gear_motor_revs,
                   double gear_load_revs) {
  Axis& a = need_axis(s, letter);
  const DriveFactors f = factors_of(s, a);
  const DriveFactors* n = &f;
  if (!(screw_lead > 0)) throw std::invalid_argument(axis_name(letter) + ": screw lead " + num(screw_lead) + " mm: expected > 0");
  AxisScaling& sc = a.scaling;
  std::string src;
  if (encoder_counts > 0) {
    sc.encoder_counts = encoder_counts;
    src = "entered counts/rev";
  } else if (n && n->encoder_increments && *n->encoder_increments > 0) {
    const uint32_t revs = n->encoder_motor_revs.value_or(1) ? n->encoder_motor_revs.value_or(1) : 1;
    sc.encoder_counts = static_cast<double>(*n->encoder_increments) / revs;
    src = std::string("counts/rev from the drive (0x608F") + (a.slave ? " over CoE)" : ")");
  } else {
    throw std::invalid_argument(axis_name(letter) + ": the drive (" +
                                (a.slave ? "EtherCAT slave " + std::to_string(a.slave) : "node " + std::to_string(a.node)) +
                                ") does not give its encoder resolution (0x608F): enter --counts");
  }
  if (gear_motor_revs > 0 || gear_load_revs > 0) {
    sc.gear_motor_revs = gear_motor_revs > 0 ? gear_motor_revs : 1;
    sc.gear_load_revs = gear_load_revs > 0 ? gear_load_revs : 1;
    src += ", entered gear";
  } else if (n && n->gear_motor_revs && n->gear_shaft_revs && *n->gear_shaft_revs > 0) {
    sc.gear_motor_revs = *n->gear_motor_revs;
    sc.gear_load_revs = *n->gear_shaft_revs;
    src += a.slave ? ", gear from the drive (0x6091 over CoE)" : ", gear from the drive (0x6091)";
  } else {
    sc.gear_motor_revs = sc.gear_load_revs = 1;
    src += ", no gear";
  }
  sc.screw_lead = screw_lead;
  sc.correction = 1.0;  // a new nominal scaling: earlier measurements no longer apply
  sc.dial_checked = false;
  sc.source = src + ", entered lead";
  a.direction.reset();
  if (a.gantry) {  // the same screw and gear on both sides: a new nominal scaling for both
    a.gantry->correction = 1.0;
    a.gantry->dial_checked = false;
    a.gantry->direction.reset();
  }
  return sc.counts_per_mm();
}

const DirectionTest& apply_direction_test(State& s, char letter, double commanded_mm, double feedback_mm,
                                          double dial_mm, bool has_dial, bool gantry_second) {
  Axis& a = need_axis(s, letter);
  if (gantry_second && !a.gantry) throw std::invalid_argument(axis_name(letter) + " is not a gantry pair: it has one drive");
  // The side tested: the axis' own drive, or the gantry's second drive.
  GantryDrive* g = gantry_second ? &*a.gantry : nullptr;
  std::optional<DirectionTest>& stored = g ? g->direction : a.direction;
  double& correction = g ? g->correction : a.scaling.correction;
  bool& dial_checked = g ? g->dial_checked : a.scaling.dial_checked;
  const std::string who = axis_name(letter) + (g ? " (the gantry's second drive, joint " + std::to_string(g->joint) + ")" : "");
  if (!(std::fabs(commanded_mm) > 0))
    throw std::invalid_argument(who + ": the test commanded no travel");
  DirectionTest t;
  t.commanded_mm = commanded_mm;
  t.feedback_mm = feedback_mm;
  t.dial_mm = dial_mm;
  t.has_dial = has_dial;
  // The controller closes the loop on the encoder: its travel must follow
  // the command within a few percent, else the drive did not move as told.
  if (std::fabs(feedback_mm - commanded_mm) > 0.05 * std::fabs(commanded_mm) + 0.01) {
    t.verdict = who + ": the drive's encoder moved " + num(feedback_mm) + " mm for " + num(commanded_mm) +
                " mm commanded: the drive did not follow (fault, torque limit, brake?); nothing changed";
    stored = t;
    throw std::invalid_argument(t.verdict);
  }
  if (!has_dial) {
    t.verdict = who + ": encoder travel " + num(feedback_mm) + " mm as commanded; enter the dial reading to check direction and scaling";
    stored = t;
    return *stored;
  }
  if (std::fabs(dial_mm) < 0.01 * std::fabs(commanded_mm)) {
    t.verdict = who + ": the dial showed " + num(dial_mm) + " mm for " + num(commanded_mm) +
                " mm commanded: the table did not move (coupling, brake, dial not touching?); nothing changed";
    stored = t;
    throw std::invalid_argument(t.verdict);
  }
  const bool against = (dial_mm > 0) != (commanded_mm > 0);
  t.correction = std::fabs(feedback_mm) / std::fabs(dial_mm);
  if (against) {
    if (g) {
      g->reverse = !g->reverse;  // its REVERSE is the axis' flipped by this
    } else {
      a.scaling.reverse = !a.scaling.reverse;
      if (a.gantry) a.gantry->reverse = !a.gantry->reverse;  // the second drive keeps its direction
    }
    t.reversed = true;
  }
  const bool reverse_now = g ? a.scaling.reverse != g->reverse : a.scaling.reverse;
  correction *= t.correction;
  dial_checked = true;
  AxisScaling now = a.scaling;
  now.correction = correction;
  t.verdict = who + ": " + (against ? "the table moved against the command: REVERSE flipped to " +
                                          std::string(reverse_now ? "YES" : "NO")
                                    : std::string("direction right")) +
              "; scale " + (std::fabs(t.correction - 1) < 1e-3 ? "right" : "corrected by " + num(t.correction)) +
              ", now " + num(now.counts_per_mm()) + " counts/mm";
  stored = t;
  return *stored;
}

std::optional<double> drive_max_torque_pct(const State& s, const Axis& a) {
  std::optional<uint16_t> t;
  if (a.slave) {
    if (const ScannedSlave* x = s.slave(a.slave)) t = x->max_torque;
  } else if (const ScannedNode* n = s.node(a.node)) {
    t = n->max_torque;
  }
  if (!t || *t == 0) return std::nullopt;
  return *t / 10.0;
}

double direction_test_travel_limit(const Axis& a) noexcept {
  return a.scaling.dial_checked ? kMaxTestTravel : kFirstTestTravel;
}

Travel clear_of_switches(const Axis& a, Travel t) {
  char b[96];
  const AxisSwitches* sw = a.switches ? &*a.switches : nullptr;
  if (sw && sw->neg_limit.seen && t.min < sw->neg_limit.position + kSwitchClearance) {
    t.min = sw->neg_limit.position + kSwitchClearance;
    std::snprintf(b, sizeof b, ", above the negative limit switch at %.3f mm", sw->neg_limit.position);
    t.source += b;
  }
  if (sw && sw->pos_limit.seen && t.max > sw->pos_limit.position - kSwitchClearance) {
    t.max = sw->pos_limit.position - kSwitchClearance;
    std::snprintf(b, sizeof b, ", below the positive limit switch at %.3f mm", sw->pos_limit.position);
    t.source += b;
  }
  return t;
}

Travel known_travel(const Axis& a) {
  const std::string ax = std::string("axis ") + a.letter;
  char b[160];
  Travel t;
  const bool given = !a.limits_source.empty();
  if (given) {
    t = {a.min_limit, a.max_limit,
         a.limits_source == "switches" ? "the soft limits from the limit switches" : "the soft limits given (axis limits)"};
  }
  const AxisSwitches* sw = a.switches ? &*a.switches : nullptr;
  const bool neg = sw && sw->neg_limit.seen, pos = sw && sw->pos_limit.seen;
  if (!given && !(neg && pos))
    throw std::invalid_argument(ax + ": the travel is not known: find the limit switches and set the soft limits from them "
                                "(cnc-commission axis " + a.letter + " switches, then soft-limits), or give provisional "
                                "limits inside the machine's travel (cnc-commission axis " + a.letter +
                                " limits --min MM --max MM)");
  if (!given) t = {sw->neg_limit.position, sw->pos_limit.position, "the limit switches found"};
  t = clear_of_switches(a, t);
  if (!(t.min < t.max)) {
    std::snprintf(b, sizeof b, ": no travel left between %.3f and %.3f mm (", t.min, t.max);
    throw std::invalid_argument(ax + b + t.source + "): check the limits and the switch search");
  }
  return t;
}

}  // namespace cnc::commission
