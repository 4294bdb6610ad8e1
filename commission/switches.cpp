#include "commission/switches.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace cnc::commission {

namespace {

std::string mm(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

// Which bit of 0x60FD each input is (CiA 402): what to check in the drive.
const char* kBit[] = {"bit 0 (negative limit)", "bit 1 (positive limit)", "bit 2 (home switch)"};

std::string never_changed(char letter, const char* which, const std::string& pin, double search_mm, int bit) {
  return std::string("axis ") + letter + ": the " + which + " never changed within " + mm(search_mm) +
         " mm of the start (" + pin + "): check its wiring and supply, its polarity (normally open or closed), "
         "and the drive's input mapping (0x60FD " + kBit[bit] + ")";
}

}  // namespace

std::string drive_pin_prefix(const Axis& a) {
  char b[48];
  std::snprintf(b, sizeof b, "cia402.0.drive.%02d.", a.joint);
  return b;
}

bool first_change(const std::vector<SwitchSample>& samples, bool SwitchSample::*input, double& position) {
  for (std::size_t i = 1; i < samples.size(); ++i) {
    if (samples[i].*input != samples[0].*input) {
      position = 0.5 * (samples[i - 1].position + samples[i].position);
      return true;
    }
  }
  return false;
}

AxisSwitches analyse_switch_search(char letter, const std::vector<SwitchSample>& towards_neg,
                                   const std::vector<SwitchSample>& towards_pos, double search_mm, double velocity,
                                   const std::string& pin_prefix) {
  AxisSwitches r;
  r.search_mm = search_mm;
  r.velocity = velocity;
  if (towards_neg.empty() || towards_pos.empty())
    throw std::invalid_argument(std::string("axis ") + letter + ": no samples of the switch search");
  r.start = towards_neg.front().position;
  r.neg_limit.pin = pin_prefix + "neg-lim-sw";
  r.pos_limit.pin = pin_prefix + "pos-lim-sw";
  r.home.pin = pin_prefix + "home-sw";

  // Limits: inactive at the start; active is the level changed to.
  r.neg_limit.seen = first_change(towards_neg, &SwitchSample::neg, r.neg_limit.position);
  r.neg_limit.active_high = !towards_neg.front().neg;
  if (!r.neg_limit.seen) r.problems.push_back(never_changed(letter, "negative limit switch", r.neg_limit.pin, search_mm, 0));
  r.pos_limit.seen = first_change(towards_pos, &SwitchSample::pos, r.pos_limit.position);
  r.pos_limit.active_high = !towards_pos.front().pos;
  if (!r.pos_limit.seen) r.problems.push_back(never_changed(letter, "positive limit switch", r.pos_limit.pin, search_mm, 1));
  // Each limit must stay quiet on the way to the other end.
  double p = 0;
  if (first_change(towards_pos, &SwitchSample::neg, p))
    r.problems.push_back(std::string("axis ") + letter + ": the negative limit switch (" + r.neg_limit.pin +
                         ") changed at " + mm(p) + " mm on the way to the positive end: are the limit inputs swapped, "
                         "or is REVERSE wrong (run the direction test)?");
  if (first_change(towards_neg, &SwitchSample::pos, p))
    r.problems.push_back(std::string("axis ") + letter + ": the positive limit switch (" + r.pos_limit.pin +
                         ") changed at " + mm(p) + " mm on the way to the negative end: are the limit inputs swapped, "
                         "or is REVERSE wrong (run the direction test)?");

  // Home: the whole travel searched, in position order.
  std::vector<SwitchSample> line(towards_neg.rbegin(), towards_neg.rend());
  line.insert(line.end(), towards_pos.begin(), towards_pos.end());
  std::stable_sort(line.begin(), line.end(), [](const SwitchSample& a, const SwitchSample& b) { return a.position < b.position; });
  std::vector<double> edges;
  double len_high = 0, len_low = 0;
  for (std::size_t i = 1; i < line.size(); ++i) {
    const double d = line[i].position - line[i - 1].position;
    if (line[i].home != line[i - 1].home) {
      edges.push_back(0.5 * (line[i].position + line[i - 1].position));
      len_high += 0.5 * d;
      len_low += 0.5 * d;
    } else {
      (line[i].home ? len_high : len_low) += d;
    }
  }
  r.home.seen = !edges.empty();
  if (r.home.seen) {
    r.home.active_high = len_high <= len_low;
    r.home.position = edges.front();
    if (edges.size() >= 2) {
      r.home.has_high = true;
      r.home.position_high = edges.back();
    }
  } else {
    r.problems.push_back(never_changed(letter, "home switch", r.home.pin, search_mm, 2));
  }
  return r;
}

void soft_limits_from_switches(Axis& a, double margin_mm) {
  const std::string ax = std::string("axis ") + a.letter;
  if (!a.switches) throw std::invalid_argument(ax + ": no switch search yet: run `cnc-commission axis " + a.letter + " switches` first");
  if (!(margin_mm >= 0)) throw std::invalid_argument(ax + ": the margin must be >= 0");
  const AxisSwitches& s = *a.switches;
  if (!s.neg_limit.seen || !s.pos_limit.seen)
    throw std::invalid_argument(ax + ": the " + std::string(!s.neg_limit.seen ? "negative" : "positive") +
                                " limit switch was not found: soft limits need both (see the switch search's problems)");
  const double lo = s.neg_limit.position + margin_mm, hi = s.pos_limit.position - margin_mm;
  if (!(lo < hi))
    throw std::invalid_argument(ax + ": a margin of " + mm(margin_mm) + " mm leaves no travel between the switches at " +
                                mm(s.neg_limit.position) + " and " + mm(s.pos_limit.position) + " mm");
  a.min_limit = lo;
  a.max_limit = hi;
  a.limits_source = "switches";
}

// ---------------------------------------------------------------------------
// The motion.

namespace {

struct Poll {
  SwitchSample s;
  bool enabled = false;   // the machine is on
  double pos_cmd = 0;
};

bool truth(const std::string& v) { return v == "TRUE" || v == "1" || v == "true"; }

struct ShownPin {
  std::string name, value, signal;  // signal "" when not linked
};

// The pins of `halcmd show pin PREFIX`.
std::vector<ShownPin> shown_pins(const Controller& c, const std::string& prefix) {
  std::vector<ShownPin> out;
  std::istringstream in(c.halcmd({"show", "pin", prefix}));
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream w(line);
    std::vector<std::string> t;
    for (std::string x; w >> x;) t.push_back(x);
    for (std::size_t i = 1; i < t.size(); ++i)
      if (t[i].rfind(prefix, 0) == 0) {
        out.push_back({t[i], t[i - 1], i + 3 == t.size() ? t[i + 2] : ""});  // name [arrow signal]
        break;
      }
  }
  return out;
}

Poll poll(const Controller& c, const Axis& a, const std::string& prefix) {
  Poll p;
  const auto j = nlohmann::json::parse(c.cnc({"status", "--json"}));
  const auto& jt = j.at("joints").at(a.joint);
  // The position comes from the same halcmd read as the inputs (the
  // drive's pos-fb, which is the joint's motor position), so both are of
  // one instant; the status gives the joint's offset to it (homing).
  const double joint_offset = jt.at("pos_fb").get<double>() - jt.at("motor_pos_fb").get<double>();
  p.s.position = jt.at("pos_fb").get<double>();
  p.pos_cmd = jt.at("pos_cmd").get<double>();
  p.enabled = j.at("motion").value("enabled", false);
  int found = 0;
  for (const ShownPin& pin : shown_pins(c, prefix)) {
    if (pin.name == prefix + "neg-lim-sw") p.s.neg = truth(pin.value), ++found;
    else if (pin.name == prefix + "pos-lim-sw") p.s.pos = truth(pin.value), ++found;
    else if (pin.name == prefix + "home-sw") p.s.home = truth(pin.value), ++found;
    else if (pin.name == prefix + "pos-fb") {
      try {
        p.s.position = std::stod(pin.value) + joint_offset;
      } catch (const std::exception&) {
        // Not a number: the status' position (some ms older) serves.
      }
    }
  }
  if (found != 3) throw std::runtime_error(std::string("axis ") + a.letter + ": the controller has no pins " + prefix +
                                           "neg-lim-sw, pos-lim-sw, home-sw (is it a cia402 drive on joint " +
                                           std::to_string(a.joint) + "?)");
  return p;
}

void abort_check(const Controller& c, const Axis& a, const Poll& p) {
  if (!abort_requested()) return;
  try {
    c.cnc({"jog-stop", std::to_string(a.joint)});
  } catch (const std::exception&) {
  }
  throw std::runtime_error(std::string("axis ") + a.letter + ": the switch search was aborted at " + mm(p.s.position) + " mm");
}

// Jogs by `dist` and samples until it ends, the stop input changes (then
// a jog stop), the machine goes off (the controller stopped it), or the
// time limit. Returns the samples.
// `armed` (may be null): the latch armed on `stop_on`, which stopped the
// jog in the servo cycle the input changed; where the polls missed the
// change (the machine switched off, or the axis stopped short of the
// target, standing on the edge with the input back at its old level),
// the latch's change ends the leg as a last sample where it happened.
std::vector<SwitchSample> leg(const Controller& c, const Axis& a, const std::string& prefix, double dist, double vel,
                              bool SwitchSample::*stop_on, const SwitchLatches* armed = nullptr) {
  if (!(vel > 0)) throw std::invalid_argument("jog: no speed given");
  const std::string joint = std::to_string(a.joint);
  std::vector<SwitchSample> out;
  Poll p = poll(c, a, prefix);
  out.push_back(p.s);
  const double target = p.pos_cmd + dist;  // a jog by a distance starts at the command
  if (std::fabs(dist) < 1e-6) return out;
  c.cnc({"jog", joint, std::to_string(vel), std::to_string(dist)});
  const auto limit = std::chrono::duration<double>(2 * std::fabs(dist) / vel + 5.0);
  const auto start = std::chrono::steady_clock::now();
  int still = 0, stopped = 0;
  double last = p.s.position;
  const auto latched_stop = [&]() {
    double at = 0;
    if (!stop_on || !armed || !armed->armed_change(at)) return false;
    SwitchSample s = out.back();
    s.position = at;
    s.*stop_on = !(out.front().*stop_on);
    out.push_back(s);
    return true;
  };
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    p = poll(c, a, prefix);
    out.push_back(p.s);
    abort_check(c, a, p);
    if (stop_on && p.s.*stop_on != out.front().*stop_on) {
      try {
        c.cnc({"jog-stop", joint});
      } catch (const std::exception&) {
        // The controller may have switched off already (its own stop).
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      out.push_back(poll(c, a, prefix).s);
      return out;
    }
    if (!p.enabled) {
      if (latched_stop()) return out;
      // Switched off with no switch changed: not a switch stop (E-stop, a
      // stalled servo thread, a following error on the way).
      if (stop_on)
        throw std::runtime_error(std::string("axis ") + a.letter + ": the controller switched the machine off at " +
                                 mm(p.s.position) + " mm before the limit switch changed (see its messages: "
                                 "E-stop, following error, a stalled servo thread)");
      return out;
    }
    if (std::fabs(p.s.position - target) < 0.01 && std::fabs(p.s.position - last) < 1e-4) {
      if (++still >= 2) return out;
    } else {
      still = 0;
    }
    stopped = std::fabs(p.s.position - last) < 1e-4 ? stopped + 1 : 0;
    if (stopped >= 3 && latched_stop()) return out;
    last = p.s.position;
    if (std::chrono::steady_clock::now() - start > limit) {
      c.cnc({"jog-stop", joint});
      throw std::runtime_error(std::string("axis ") + a.letter + ": the jog did not end within " + mm(limit.count()) +
                               " s (at " + mm(p.s.position) + " mm, target " + mm(target) + "): stopped");
    }
  }
}

void on_again(const Controller& c) { machine_on(c, false); }

const char* const kLatchNames[] = {"commission-latch-neg", "commission-latch-pos", "commission-latch-home"};
const char* const kLatchInputs[] = {"neg-lim-sw", "pos-lim-sw", "home-sw"};
const char* const kJogStopSignal = "commission-jog-stop";
// The command stops in the cycle (no deceleration ramp): a drive halts at
// its limit switch itself, and a ramp of v^2/2a past it (0.25 mm at
// 10 mm/s and 200 mm/s^2) trips the following-error limit.
const std::string kJogStopPin = "motion.jog-stop-immediate";

// The functions of `halcmd show funct PREFIX` and how many threads call
// each (its Users column).
std::vector<std::pair<std::string, int>> shown_functions(const Controller& c, const std::string& prefix) {
  std::vector<std::pair<std::string, int>> out;
  std::istringstream in(c.halcmd({"show", "funct", prefix}));
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream w(line);
    std::vector<std::string> t;
    for (std::string x; w >> x;) t.push_back(x);
    // Owner FP Users Time(ns) Max(ns) Name
    if (t.size() == 6 && t[5].rfind(prefix, 0) == 0) out.emplace_back(t[5], std::stoi(t[2]));
  }
  return out;
}

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  return s;
}

}  // namespace

bool latched_change(const std::vector<SwitchSample>& samples, bool SwitchSample::*input, const LatchedEdges& latch,
                    double& edge) {
  constexpr double kMargin = 0.05;  // mm: the polls' own skew between position and inputs
  // The change of the polls that `edge` stands for: the one around it.
  std::size_t at = 0;
  double best = 0;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    if (samples[i].*input == samples[i - 1].*input) continue;
    const double lo = std::min(samples[i - 1].position, samples[i].position) - kMargin;
    const double hi = std::max(samples[i - 1].position, samples[i].position) + kMargin;
    if (edge < lo || edge > hi) continue;
    const double d = std::fabs(0.5 * (samples[i - 1].position + samples[i].position) - edge);
    if (at == 0 || d < best) at = i, best = d;
  }
  if (at == 0) return false;
  const bool rising = samples[at].*input;
  bool first = true;
  for (std::size_t i = 1; i < at; ++i) first = first && samples[i].*input == samples[0].*input;
  double p = 0;
  if (latch.changed && first) p = latch.changed_position;
  else if ((rising ? latch.rises : latch.falls) == 1) p = rising ? latch.rise_position : latch.fall_position;
  else return false;
  const double lo = std::min(samples[at - 1].position, samples[at].position) - kMargin;
  const double hi = std::max(samples[at - 1].position, samples[at].position) + kMargin;
  if (!(p >= lo && p <= hi)) return false;
  edge = p;
  return true;
}

bool SwitchLatches::attach(const Controller& c, const Axis& a, std::string& why) {
  detach();
  c_ = &c;
  // Links `pin` (an output) to the latch input `latch_pin` through the
  // signal the output is on, or a new one named `signal` (deleted again
  // by detach()).
  const auto link = [&](const std::string& pin, const std::string& latch_pin, const std::string& signal) {
    std::string sig;
    for (const ShownPin& p : shown_pins(c, pin))
      if (p.name == pin && !p.signal.empty()) sig = p.signal;
    c.halcmd({"unlinkp", latch_pin});
    c.halcmd({"net", sig.empty() ? signal : sig, pin, latch_pin});
    linked_pins_.push_back(latch_pin);
    // Ours also when a killed search or the homing check left it.
    if ((sig.empty() || sig == signal) && std::find(made_signals_.begin(), made_signals_.end(), signal) == made_signals_.end())
      made_signals_.push_back(signal);
  };
  try {
    if (shown_pins(c, std::string(kLatchNames[0]) + ".").empty()) {
      std::string names;
      for (const char* n : kLatchNames) names += (names.empty() ? "" : ",") + std::string(n);
      c.halcmd({"loadrt", "latch", "names=" + names});
    }
    // Loaded by an earlier search (no unloadrt): in no thread since it
    // detached, or still in servo-thread after the homing check.
    for (const auto& [function, users] : shown_functions(c, "commission-latch-")) {
      if (users > 0) continue;
      c.halcmd({"addf", function, "servo-thread"});
      added_functions_.push_back(function);
    }
    const std::string j = std::to_string(a.joint);
    const std::string drive = drive_pin_prefix(a), pos = "joint." + j + ".pos-fb";
    for (int i = 0; i < 3; ++i) {
      const std::string l = kLatchNames[i];
      link(drive + kLatchInputs[i], l + ".in", "commission-j" + j + "-" + kLatchInputs[i]);
      link(pos, l + ".position", "commission-j" + j + "-pos-fb");
      // A CANopen drive's inputs come in an event-driven TPDO (as the
      // writer maps 0x60FD), ahead of its SYNC-sampled position by up to a
      // cycle; on EtherCAT both are of one frame.
      c.halcmd({"setp", l + ".input-lead-cycles", a.slave > 0 ? "0" : "1"});
    }
    // Relinking (and a latch back in the thread, which compares with the
    // input of its last run) may count an edge: some cycles pass before a
    // reading.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    return true;
  } catch (const std::exception& e) {
    why = trimmed(e.what());
    const std::string left = detach();
    if (!left.empty()) why += "; " + left;
    return false;
  }
}

std::string SwitchLatches::detach() noexcept {
  if (!c_) return {};
  const Controller& c = *c_;
  c_ = nullptr;
  std::string failed;
  try {
    const auto run = [&](const std::vector<std::string>& args) {
      try {
        c.halcmd(args);
      } catch (const std::exception& e) {
        if (!failed.empty()) return;
        for (const auto& w : args) failed += w + " ";
        failed += "failed: " + trimmed(e.what());
      }
    };
    if (!armed_.empty()) {
      run({"setp", armed_ + ".arm", "0"});
      run({"delsig", kJogStopSignal});
      run({"setp", kJogStopPin, jog_stop_value_});
      armed_.clear();
    }
    // Out of the thread first: nothing runs while the links go.
    for (const auto& f : added_functions_) run({"delf", f, "servo-thread"});
    for (const auto& p : linked_pins_) run({"unlinkp", p});
    for (const auto& s : made_signals_) run({"delsig", s});
  } catch (...) {
    if (failed.empty()) failed = "out of memory";
  }
  added_functions_.clear();
  linked_pins_.clear();
  made_signals_.clear();
  if (failed.empty()) return {};
  return "the switch latches (commission-latch-*) may still be linked in the controller's HAL (halcmd " + failed + ")";
}

bool SwitchLatches::stop_jogs_on_change(int which) {
  if (!c_ || which < 0 || which > 2) return false;
  release_jog_stop();
  const Controller& c = *c_;
  std::string value;
  for (const ShownPin& p : shown_pins(c, kJogStopPin))
    if (p.name == kJogStopPin) {
      if (p.signal == kJogStopSignal) {
        // Left by a search that was killed: taken back.
        c.halcmd({"delsig", kJogStopSignal});
        c.halcmd({"setp", kJogStopPin, "0"});
        value = "FALSE";
      } else if (!p.signal.empty()) {
        return false;  // the configuration's (a pendant's stop button)
      } else {
        value = p.value;
      }
    }
  if (value.empty()) return false;
  const std::string l = kLatchNames[which];
  // The reference level is the input's while disarmed: here, at rest.
  c.halcmd({"setp", l + ".arm", "0"});
  armed_ = l;
  jog_stop_value_ = truth(value) ? "1" : "0";
  c.halcmd({"net", kJogStopSignal, l + ".changed", kJogStopPin});
  c.halcmd({"setp", l + ".arm", "1"});
  return true;
}

bool SwitchLatches::armed_change(double& position) const {
  if (!c_ || armed_.empty()) return false;
  bool changed = false;
  for (const ShownPin& p : shown_pins(*c_, armed_ + ".changed")) {
    if (p.name == armed_ + ".changed") changed = truth(p.value);
    else if (p.name == armed_ + ".changed-position") position = std::stod(p.value);
  }
  return changed;
}

void SwitchLatches::release_jog_stop() {
  if (!c_ || armed_.empty()) return;
  const Controller& c = *c_;
  // Unlinked, motion.jog-stop keeps the signal's last value: set as it was.
  c.halcmd({"setp", armed_ + ".arm", "0"});
  c.halcmd({"delsig", kJogStopSignal});
  c.halcmd({"setp", kJogStopPin, jog_stop_value_});
  armed_.clear();
}

SwitchLatchReading read_switch_latches(const Controller& c) {
  SwitchLatchReading r;
  LatchedEdges* edges[] = {&r.neg, &r.pos, &r.home};
  int found = 0;
  for (const ShownPin& shown : shown_pins(c, "commission-latch-")) {
    const std::string& name = shown.name;
    const std::string& value = shown.value;
    for (int i = 0; i < 3; ++i) {
      const std::string l = std::string(kLatchNames[i]) + ".";
      if (name.rfind(l, 0) != 0) continue;
      const std::string k = name.substr(l.size());
      LatchedEdges& e = *edges[i];
      if (k == "rise-count") e.rises = std::stoi(value), ++found;
      else if (k == "fall-count") e.falls = std::stoi(value), ++found;
      else if (k == "rise-position") e.rise_position = std::stod(value), ++found;
      else if (k == "fall-position") e.fall_position = std::stod(value), ++found;
      else if (k == "changed") e.changed = truth(value), ++found;
      else if (k == "changed-position") e.changed_position = std::stod(value), ++found;
    }
  }
  if (found != 18) throw std::runtime_error("the switch latches (commission-latch-*) are not all in the controller's HAL");
  return r;
}

SwitchLatchReading latch_difference(const SwitchLatchReading& before, const SwitchLatchReading& after) noexcept {
  auto d = [](const LatchedEdges& b, const LatchedEdges& a) {
    LatchedEdges e = a;  // s32 counters that may wrap
    e.rises = static_cast<int32_t>(static_cast<uint32_t>(a.rises) - static_cast<uint32_t>(b.rises));
    e.falls = static_cast<int32_t>(static_cast<uint32_t>(a.falls) - static_cast<uint32_t>(b.falls));
    return e;
  };
  return {d(before.neg, after.neg), d(before.pos, after.pos), d(before.home, after.home)};
}

void machine_on(const Controller& c, bool override_limits) {
  c.cnc({"estop-reset"});
  c.cnc({"on"});
  c.cnc({"mode", "manual"});
  if (override_limits) c.cnc({"override-limits"});
}

std::vector<SwitchSample> jog_and_sample(const Controller& c, const Axis& a, double dist, double vel,
                                         bool SwitchSample::*stop_on) {
  return leg(c, a, drive_pin_prefix(a), dist, vel, stop_on);
}

double cross_edge(const Controller& c, const Axis& a, bool SwitchSample::*input, const char* name, double edge,
                  double dir, double fast, double slow, double tolerance) {
  const std::string prefix = drive_pin_prefix(a);
  double at = edge;
  double backoff = 1.0;  // then twice the last gap: each try is short
  for (int attempt = 0; attempt < 3; ++attempt, slow /= 4) {
    // Crossing a limit switch again, the drive halts at it and the
    // controller may stop on following error a poll later (the machine off,
    // in E-stop): the try is made again once with the machine on.
    std::vector<SwitchSample> s;
    for (int again = 0;; ++again) {
      try {
        Poll p = poll(c, a, prefix);
        if (!p.enabled) machine_on(c, true);
        else c.cnc({"override-limits"});
        p = poll(c, a, prefix);
        leg(c, a, prefix, (at - dir * backoff) - p.pos_cmd, fast, nullptr);
        s = leg(c, a, prefix, dir * (2.5 * backoff), slow, input);
        break;
      } catch (const std::runtime_error& e) {
        if (again > 0 || abort_requested() || std::string(e.what()).find("the machine is not on") == std::string::npos) throw;
      }
    }
    double gap = 0;
    for (std::size_t i = 1; i < s.size(); ++i)
      if (s[i].*input != s[0].*input) {
        gap = std::fabs(s[i].position - s[i - 1].position);
        break;
      }
    if (!first_change(s, input, at))
      throw std::runtime_error(std::string("axis ") + a.letter + ": the " + name + " did not change again near " + mm(edge) +
                               " mm: a loose contact or a bouncing switch? check its wiring");
    if (gap <= tolerance) break;
    backoff = std::clamp(2 * gap, 0.05, 1.0);
  }
  return at;
}

AxisSwitches find_switches(const Controller& c, const Axis& a, double search_mm, double velocity, std::FILE* progress) {
  const double vel = std::min(std::fabs(velocity), kMaxSwitchVelocity);
  const double search = std::fabs(search_mm);
  if (!(vel > 0) || !(search > 0)) throw std::invalid_argument("switches: --search and --velocity must be > 0");
  const std::string prefix = drive_pin_prefix(a);
  const std::string joint = std::to_string(a.joint);
  auto say = [&](int i, const std::string& text) {
    if (progress) {
      std::fprintf(progress, "progress: %d/5 %s\n", i, text.c_str());
      std::fflush(progress);
    }
  };
  clear_abort();
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(std::string("axis ") + a.letter + ": the E-stop chain is open: close it before the switch search");
  std::vector<SwitchSample> neg, pos;
  AxisSwitches r;
  SwitchLatches latches;  // detached after the machine is off, whatever happens
  try {
    on_again(c);
    const double start = poll(c, a, prefix).s.position;
    // Back to the start at up to three times the search speed (known ground).
    auto back = [&]() {
      Poll p = poll(c, a, prefix);
      if (!p.enabled) {
        machine_on(c, true);
        p = poll(c, a, prefix);
      } else {
        c.cnc({"override-limits"});
      }
      leg(c, a, prefix, start - p.pos_cmd, std::min(3 * vel, std::max(vel, a.max_velocity)), nullptr);
      if (!poll(c, a, prefix).enabled)
        throw std::runtime_error(std::string("axis ") + a.letter + ": the controller stopped the axis on its way back to the start");
    };
    // Each leg between two readings of the servo-thread latches: where
    // each input changed, to a servo cycle of travel, however far apart
    // the polls are.
    std::string why;
    const bool latched = latches.attach(c, a, why);
    if (!latched && progress) {
      std::fprintf(progress, "axis %c: no servo-thread latch (%s): each edge will be crossed again slowly\n", a.letter,
                   why.c_str());
    }
    SwitchLatchReading on_neg, on_pos;
    // The limit the leg looks for stops the jog in the servo cycle it
    // changes (motion.jog-stop through the latch), not at the next poll.
    auto latched_leg = [&](double dist, bool SwitchSample::*stop_on, int which, SwitchLatchReading& seen) {
      const bool hal_stop = latched && latches.stop_jogs_on_change(which);
      const SwitchLatchReading before = latched ? read_switch_latches(c) : SwitchLatchReading{};
      auto s = leg(c, a, prefix, dist, vel, stop_on, hal_stop ? &latches : nullptr);
      if (latched) seen = latch_difference(before, read_switch_latches(c));  // `changed` still armed
      if (hal_stop) latches.release_jog_stop();
      return s;
    };
    say(1, std::string("axis ") + a.letter + ": towards minus, up to " + mm(search) + " mm at " + mm(vel) + " mm/s");
    neg = latched_leg(-search, &SwitchSample::neg, 0, on_neg);
    say(2, std::string("axis ") + a.letter + ": back to the start");
    back();
    say(3, std::string("axis ") + a.letter + ": towards plus, up to " + mm(search) + " mm at " + mm(vel) + " mm/s");
    pos = latched_leg(search, &SwitchSample::pos, 1, on_pos);
    r = analyse_switch_search(a.letter, neg, pos, search, vel, prefix);
    // An edge the latch did not give unambiguously (none loaded, a bounce:
    // more than one edge of the kind in the leg) is crossed again slowly,
    // in the direction the search crossed it.
    const double fast = std::min(3 * vel, std::max(vel, a.max_velocity)), slow = std::min(1.0, vel / 4);
    const auto settle = [&](double& position, bool SwitchSample::*input, const LatchedEdges& in_neg,
                            const LatchedEdges& in_pos, const char* name) {
      if (latched && (latched_change(neg, input, in_neg, position) || latched_change(pos, input, in_pos, position))) return;
      if (progress) {
        std::fprintf(progress, "axis %c: the %s's edge at %s mm again at %s mm/s (%s)\n", a.letter, name, mm(position).c_str(),
                     mm(slow).c_str(), latched ? "the latch saw no single edge there" : "no latch");
        std::fflush(progress);
      }
      position = cross_edge(c, a, input, name, position, position < r.start ? -1 : 1, fast, slow);
    };
    say(4, std::string("axis ") + a.letter + ": the edges " + (latched ? "as the servo thread latched them" : "again slowly"));
    if (r.neg_limit.seen)
      settle(r.neg_limit.position, &SwitchSample::neg, on_neg.neg, on_pos.neg, "negative limit switch");
    if (r.pos_limit.seen)
      settle(r.pos_limit.position, &SwitchSample::pos, on_neg.pos, on_pos.pos, "positive limit switch");
    if (r.home.seen) {
      settle(r.home.position, &SwitchSample::home, on_neg.home, on_pos.home, "home switch");
      if (r.home.has_high) settle(r.home.position_high, &SwitchSample::home, on_neg.home, on_pos.home, "home switch");
    }
    say(5, std::string("axis ") + a.letter + ": back to the start");
    back();
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
  return r;
}

}  // namespace cnc::commission
