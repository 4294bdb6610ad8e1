#include "commission/tuning.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "commission/config_writer.hpp"
#include "commission/steps.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::commission {

namespace {

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::vector<double> numbers_of(const std::string& line, const std::string& origin, int line_no,
                               const std::vector<std::string>& names) {
  std::vector<double> v;
  const auto w = split(line, ',');
  for (std::size_t i = 0; i < w.size(); ++i) {
    const auto d = parse_double(trim(w[i]));
    if (!d)
      throw std::runtime_error(origin + ":" + std::to_string(line_no) + ": column " +
                               (i < names.size() ? names[i] : std::to_string(i + 1)) + ": \"" + w[i] +
                               "\" is not a number");
    v.push_back(*d);
  }
  if (v.size() != names.size())
    throw std::runtime_error(origin + ":" + std::to_string(line_no) + ": " + std::to_string(v.size()) +
                             " columns, the header has " + std::to_string(names.size()));
  return v;
}

}  // namespace

// ---- records ----

std::string tuning_csv(const std::vector<TuningSample>& samples) {
  std::string out = std::string(kTuningCsvHeader) + "\n";
  char b[160];
  for (const TuningSample& s : samples) {
    std::snprintf(b, sizeof b, "%.6f,%.6f,%.6f,%.6f,%.4f,%.2f\n", s.time_s, s.command_mm, s.feedback_mm, s.ferror_mm,
                  s.velocity_mm_s, s.torque_pct);
    out += b;
  }
  return out;
}

std::vector<TuningSample> parse_tuning_csv(const std::string& text, const std::string& origin) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(origin + ": empty (expected the header " + kTuningCsvHeader + ")");
  const auto names = split(std::string(trim(line)), ',');
  const auto want = split(kTuningCsvHeader, ',');
  int col[6];
  for (std::size_t k = 0; k < want.size(); ++k) {
    const auto it = std::find(names.begin(), names.end(), want[k]);
    if (it == names.end()) throw std::runtime_error(origin + ":1: no column " + want[k]);
    col[k] = static_cast<int>(it - names.begin());
  }
  std::vector<TuningSample> out;
  int n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (trim(line).empty()) continue;
    const auto v = numbers_of(std::string(trim(line)), origin, n, names);
    TuningSample s;
    s.time_s = v[col[0]];
    s.command_mm = v[col[1]];
    s.feedback_mm = v[col[2]];
    s.ferror_mm = v[col[3]];
    s.velocity_mm_s = v[col[4]];
    s.torque_pct = v[col[5]];
    if (!out.empty() && s.time_s > out.back().time_s)
      s.vel_cmd_mm_s = (s.command_mm - out.back().command_mm) / (s.time_s - out.back().time_s);
    out.push_back(s);
  }
  return out;
}

std::vector<std::string> tuning_scope_pins(int joint, int drive) {
  const std::string j = "joint." + std::to_string(joint) + ".";
  char d[40];
  std::snprintf(d, sizeof d, "cia402.0.drive.%02d.", drive);
  return {j + "motor-pos-cmd", j + "motor-pos-fb", j + "f-error", std::string(d) + "vel-fb",
          std::string(d) + "torque", j + "vel-cmd", std::string(d) + "statusword"};
}

std::vector<std::vector<TuningSample>> parse_scope_csv_sides(const std::string& text, int sides) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error("scope csv: empty");
  const auto names = split(std::string(trim(line)), ',');
  const std::size_t want = 1 + kTuningPinsPerJoint * static_cast<std::size_t>(sides);
  if (names.size() != want || names[0] != "time_s")
    throw std::runtime_error("scope csv: unexpected header \"" + line + "\" (time_s and the " +
                             std::to_string(want - 1) + " tuning pins)");
  std::vector<std::vector<TuningSample>> out(static_cast<std::size_t>(sides));
  int n = 1;
  while (std::getline(in, line)) {
    ++n;
    if (trim(line).empty()) continue;
    const auto v = numbers_of(std::string(trim(line)), "scope csv", n, names);
    for (int k = 0; k < sides; ++k) {
      const double* p = v.data() + 1 + kTuningPinsPerJoint * k;
      TuningSample s;
      s.time_s = v[0];
      s.command_mm = p[0];
      s.feedback_mm = p[1];
      s.ferror_mm = p[2];
      s.velocity_mm_s = p[3];
      s.torque_pct = p[4];
      s.vel_cmd_mm_s = p[5];
      s.limit = ((static_cast<uint32_t>(p[6]) >> 11) & 1u) != 0;
      out[static_cast<std::size_t>(k)].push_back(s);
    }
  }
  return out;
}

std::vector<TuningSample> parse_scope_csv(const std::string& text) { return parse_scope_csv_sides(text, 1).front(); }

// ---- analysis ----

void analyse_test(TuningTest& t, const std::vector<TuningSample>& samples, const SaturationRule& rule,
                  double reference_ferror_per_velocity) {
  t.max_ferror = t.max_torque = t.reached_velocity = t.reached_acceleration = 0;
  t.ferror_per_velocity = t.standstill_ferror = 0;
  t.limit_cycles = 0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const TuningSample& s = samples[i];
    t.max_ferror = std::max(t.max_ferror, std::fabs(s.ferror_mm));
    t.max_torque = std::max(t.max_torque, std::fabs(s.torque_pct));
    t.reached_velocity = std::max(t.reached_velocity, std::fabs(s.vel_cmd_mm_s));
    if (s.limit) ++t.limit_cycles;
    if (i > 0 && s.time_s > samples[i - 1].time_s)
      t.reached_acceleration = std::max(t.reached_acceleration, std::fabs(s.vel_cmd_mm_s - samples[i - 1].vel_cmd_mm_s) /
                                                                    (s.time_s - samples[i - 1].time_s));
  }
  // Following error against velocity: above a quarter of the peak the
  // ratio (the loop's lag, mostly the transport delay of the bus); below
  // it the standstill and low-speed error.
  const double quarter = 0.25 * t.reached_velocity;
  for (const TuningSample& s : samples) {
    const double v = std::fabs(s.vel_cmd_mm_s), e = std::fabs(s.ferror_mm);
    if (v >= quarter && v > 0) t.ferror_per_velocity = std::max(t.ferror_per_velocity, e / v);
    else t.standstill_ferror = std::max(t.standstill_ferror, e);
  }
  t.saturated = t.fault;
  if (t.fault) return;  // the finding says what happened
  t.finding.clear();
  const double torque_at = rule.torque_share * rule.torque_limit_pct;
  if (t.max_torque >= torque_at) {
    t.saturated = true;
    t.finding = "torque " + fmt("%.0f", t.max_torque) + " % reached " + fmt("%.0f", rule.torque_share * 100) +
                " % of the drive's limit (" + fmt("%.0f", rule.torque_limit_pct) + " % of rated)";
  } else if (t.limit_cycles >= rule.limit_cycles) {
    t.saturated = true;
    t.finding = "the drive reported an internal limit (statusword bit 11: torque, current or velocity) in " +
                std::to_string(t.limit_cycles) + " cycles";
  } else if (reference_ferror_per_velocity > 0 &&
             t.ferror_per_velocity > rule.ferror_growth * reference_ferror_per_velocity &&
             t.max_ferror > rule.ferror_floor_mm) {
    t.saturated = true;
    t.finding = "the following error grew out of proportion: " + fmt("%.2f", t.ferror_per_velocity * 1000) +
                " ms of lag against " + fmt("%.2f", reference_ferror_per_velocity * 1000) +
                " ms in the first test (peak " + fmt("%.3f", t.max_ferror) + " mm)";
  }
}

TuningTest worse_side(const TuningTest& first, const TuningTest& second) {
  TuningTest w = first;
  w.max_ferror = std::max(first.max_ferror, second.max_ferror);
  w.max_torque = std::max(first.max_torque, second.max_torque);
  w.ferror_per_velocity = std::max(first.ferror_per_velocity, second.ferror_per_velocity);
  w.standstill_ferror = std::max(first.standstill_ferror, second.standstill_ferror);
  w.limit_cycles = std::max(first.limit_cycles, second.limit_cycles);
  w.reached_velocity = std::min(first.reached_velocity, second.reached_velocity);
  w.reached_acceleration = std::min(first.reached_acceleration, second.reached_acceleration);
  w.fault = first.fault || second.fault;
  w.saturated = first.saturated || second.saturated;
  if (!first.saturated && second.saturated) {
    w.finding = "the gantry's second drive: " + second.finding;
    w.csv = second.csv;
  }
  return w;
}

AxisTuning recommend_tuning(const std::vector<TuningTest>& tests, double margin_pct, double counts_per_mm) {
  if (!(margin_pct >= 0 && margin_pct < 100)) throw std::invalid_argument("margin " + fmt("%g", margin_pct) + " %: expected 0 to 100");
  AxisTuning r;
  r.tests = tests;
  r.margin_pct = margin_pct;
  double v_ok = 0, a_ok = 0, j_ok = 0, standstill = 0, lag = 0;
  for (const TuningTest& t : tests) {
    if (t.saturated || t.fault) continue;
    v_ok = std::max(v_ok, std::min(t.velocity, t.reached_velocity));
    a_ok = std::max(a_ok, std::min(t.acceleration, t.reached_acceleration));
    j_ok = std::max(j_ok, t.jerk);
    standstill = std::max(standstill, t.standstill_ferror);
    lag = std::max(lag, t.ferror_per_velocity);
  }
  if (!(v_ok > 0) || !(a_ok > 0)) {
    std::string why = tests.empty() ? "no test ran" : "the first test already saturated: " + tests.front().finding;
    throw std::invalid_argument("no clean test (" + why + "): lower --max-velocity and --max-acceleration");
  }
  const double f = 1.0 - margin_pct / 100.0;
  r.max_velocity = f * v_ok;
  r.max_acceleration = f * a_ok;
  r.max_jerk = f * j_ok;
  // Never below 0.05 mm (nor 10 encoder counts): a limit of a few
  // hundredths trips on a late cycle or two of the host (the EtherCAT
  // netns test: 0.0232 mm at 4 mm/s against 0.0196 mm, after tests whose
  // clean peaks were 1 ms of travel). The tests' figures stay in the state
  // for a builder who wants to tighten it on a realtime host.
  const double floor = std::max(0.05, counts_per_mm > 0 ? 10.0 / counts_per_mm : 0.0);
  // Motion's limit is max(MIN_FERROR, FERROR x |v| / MAX_VELOCITY) with v
  // the commanded velocity now, while the following error lags the
  // command by the loop's lag: while braking it still holds the velocity
  // of one lag earlier, up to A x lag faster, so MIN_FERROR also covers
  // A x lag of velocity at that lag (twice, as the rest).
  r.min_ferror = std::max(floor, 2.0 * (standstill + lag * lag * 1.1 * r.max_acceleration));
  r.ferror = std::max(r.min_ferror, 2.0 * lag * 1.05 * r.max_velocity);
  // What bounded each series: its lowest saturated test, else its ceiling.
  for (const bool velocity : {true, false}) {
    const std::string series = velocity ? "velocity" : "acceleration";
    const TuningTest* low = nullptr;
    double highest = 0;
    for (const TuningTest& t : tests) {
      if (t.series != series) continue;
      const double x = velocity ? t.velocity : t.acceleration;
      if ((t.saturated || t.fault) && (!low || x < (velocity ? low->velocity : low->acceleration))) low = &t;
      if (!t.saturated && !t.fault) highest = std::max(highest, x);
    }
    std::string& out = velocity ? r.velocity_limit : r.acceleration_limit;
    if (low)
      out = "saturation at " + fmt("%.0f", low->velocity) + " mm/s, " + fmt("%.0f", low->acceleration) + " mm/s2: " + low->finding;
    else
      out = "no saturation up to the highest test (" + fmt("%.0f", highest) + (velocity ? " mm/s)" : " mm/s2)");
  }
  return r;
}

// ---- the tests on a controller ----

namespace {

struct JointNow {
  double pos = 0, vel = 0;
  bool enabled = false, fault = false, on = false;
};

JointNow joint_now(const Controller& c, int joint) {
  const auto j = nlohmann::json::parse(c.cnc({"status", "--json"}));
  const auto& js = j.at("joints").at(joint);
  JointNow n;
  n.pos = js.at("pos_cmd").get<double>();
  n.vel = js.at("velocity").get<double>();
  n.fault = js.value("fault", false);
  n.enabled = j.at("motion").value("enabled", false);
  n.on = j.at("task").value("state", std::string()) == "ON";
  return n;
}

std::string axis_name(const Axis& a) { return std::string("axis ") + a.letter; }

// What the tests move: one joint in free mode (jogged by its number), or
// a homed gantry pair in teleop mode (jogged by the axis letter, both
// sides together, each side's pins recorded).
struct Moved {
  const Axis* axis = nullptr;
  std::vector<int> joints;  // the first is the one whose position is followed
  bool pair = false;
  std::string jog;          // `cnc jog` target: the joint number or the axis letter
  int axis_index = -1;      // a pair: the axis' index in XYZABCUVW (its limits are set too)
};

Moved moved_of(const Axis& a) {
  Moved m;
  m.axis = &a;
  m.joints = {a.joint};
  m.jog = std::to_string(a.joint);
  if (a.gantry) {
    m.pair = true;
    m.joints.push_back(a.gantry->joint);
    m.jog = std::string(1, static_cast<char>(std::tolower(a.letter)));
    m.axis_index = static_cast<int>(std::string("XYZABCUVW").find(a.letter));
  }
  return m;
}

// The run-time limits in force before the tests (restored after them).
struct Limits {
  double v = 0, a = 0, j = 0;
};
struct LimitsBefore {
  std::vector<Limits> joints;
  Limits axis;
};

LimitsBefore limits_now(const Controller& c, const Moved& m) {
  const auto j = nlohmann::json::parse(c.cnc({"status", "--json"}));
  LimitsBefore b;
  for (int k : m.joints) {
    const auto& js = j.at("joints").at(k);
    b.joints.push_back({js.value("max_velocity", 0.0), js.value("max_acceleration", 0.0), js.value("max_jerk", 0.0)});
  }
  if (m.pair)
    for (const auto& ax : j.at("axes"))
      if (ax.value("axis", std::string()) == std::string(1, m.axis->letter))
        b.axis = {ax.value("max_velocity", 0.0), ax.value("max_acceleration", 0.0), ax.value("max_jerk", 0.0)};
  return b;
}

// Jogs by `distance` and waits until the command stands at the target.
// Returns false when motion stopped (a fault, the machine off); throws on
// abort and time-out.
bool move(const Controller& c, const Moved& m, double velocity, double distance, double limit_s) {
  const Axis& a = *m.axis;
  const std::string& joint = m.jog;
  const double target = joint_now(c, m.joints.front()).pos + distance;
  c.cnc({"jog", joint, fmt("%.6f", velocity), fmt("%.6f", distance)});
  const auto start = std::chrono::steady_clock::now();
  int still = 0;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    const JointNow n = joint_now(c, m.joints.front());
    if (!n.enabled || !n.on || n.fault) return false;
    if (std::fabs(n.pos - target) < 1e-4 && std::fabs(n.vel) < 1e-6) {
      if (++still >= 2) return true;
    } else {
      still = 0;
    }
    if (abort_requested()) {
      c.cnc({"jog-stop", joint});
      throw std::runtime_error(axis_name(a) + ": the tuning test was aborted");
    }
    if (std::chrono::steady_clock::now() - start > std::chrono::duration<double>(limit_s)) {
      c.cnc({"jog-stop", joint});
      throw std::runtime_error(axis_name(a) + ": a test move did not end within " + fmt("%.1f", limit_s) + " s: stopped");
    }
  }
}

void set_limits(const Controller& c, int joint, double v, double a, double j) {
  const std::string n = std::to_string(joint);
  c.cnc({"set", "joint.max-velocity", n, fmt("%.6f", v)});
  c.cnc({"set", "joint.max-acceleration", n, fmt("%.6f", a)});
  c.cnc({"set", "joint.max-jerk", n, fmt("%.6f", j)});
}

// The test's limits on every joint moved and, for a pair, on its axis
// (teleop jogs obey the axis' limits).
void set_axis_limits(const Controller& c, int axis, const Limits& l) {
  const std::string n = std::to_string(axis);
  c.cnc({"set", "axis.max-velocity", n, fmt("%.6f", l.v)});
  c.cnc({"set", "axis.max-acceleration", n, fmt("%.6f", l.a)});
  c.cnc({"set", "axis.max-jerk", n, fmt("%.6f", l.j)});
}

void set_limits(const Controller& c, const Moved& m, double v, double a, double j) {
  for (int k : m.joints) set_limits(c, k, v, a, j);
  if (m.pair) set_axis_limits(c, m.axis_index, {v, a, j});
}

void restore_limits(const Controller& c, const Moved& m, const LimitsBefore& b) {
  for (std::size_t k = 0; k < m.joints.size(); ++k)
    set_limits(c, m.joints[k], b.joints[k].v, b.joints[k].a, b.joints[k].j);
  if (m.pair) set_axis_limits(c, m.axis_index, b.axis);
}

}  // namespace

AxisTuning run_tuning(const Controller& c, const Axis& a, const TuneOptions& o) {
  if (!(o.max_velocity > 0) || !(o.max_acceleration > 0))
    throw std::invalid_argument(axis_name(a) + ": --max-velocity and --max-acceleration must be > 0");
  if (!(o.margin_pct >= 10 && o.margin_pct < 90))
    throw std::invalid_argument(axis_name(a) + ": --margin " + fmt("%g", o.margin_pct) +
                                ": expected 10 to 90 % (the joint's limits are written 5-10 % above the axis')");
  if (o.steps < 2 || o.steps > 20) throw std::invalid_argument("tune: 2 to 20 steps per series");
  // The tests move inside the known travel (soft limits, the switches found).
  const Travel travel = known_travel(a);
  const double span = travel.max - travel.min;
  const double keep = std::max(1.0, 0.05 * span);
  const double lo = travel.min + keep, hi = travel.max - keep;
  if (!(hi - lo >= 2.0))
    throw std::invalid_argument(axis_name(a) + ": the travel " + fmt("%g", travel.min) + ".." + fmt("%g", travel.max) +
                                " mm (" + travel.source + ") leaves no room for test moves: set the limits first");
  auto progress = [&](const std::string& s) { if (o.progress) o.progress(s); };
  auto report = [&](const std::string& s) { if (o.report) o.report(s); };
  std::filesystem::create_directories(o.record_dir);

  const Moved m = moved_of(a);
  if (m.pair && !(a.homing && a.gantry->homing))
    throw std::invalid_argument(axis_name(a) + " is a gantry pair: its two sides move together only once homed: run the "
                                "homing step first (cnc-commission axis " + std::string(1, a.letter) +
                                " homing), then tune the pair");
  clear_abort();
  c.cnc({"estop-reset"});
  if (!c.estop_chain_ok())
    throw std::runtime_error(axis_name(a) + ": the E-stop chain is open: close it before the tuning tests");
  const LimitsBefore limits_before = limits_now(c, m);
  std::vector<TuningTest> tests;
  AxisTuning result;
  try {
    c.cnc({"on"});
    c.cnc({"mode", "manual"});
    const double period = c.servo_period_s();
    if (m.pair) {
      // The pair moves as its axis only on a homed machine (teleop): home
      // all joints, as the configuration says (the pair's sides together,
      // on their own switches; a joint without a search homes where it
      // stands).
      progress("homing the machine (the gantry pair's joints " + std::to_string(m.joints[0]) + " and " +
               std::to_string(m.joints[1]) + " together) before the tests");
      c.cnc({"--timeout", "150", "home", "all"});
      const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(150);
      for (;;) {
        const auto st = nlohmann::json::parse(c.cnc({"status", "--json"}));
        bool homed = true;
        for (const auto& js : st.at("joints")) homed = homed && js.value("homed", false) && js.value("inpos", false);
        if (homed) break;
        if (!st.at("motion").value("enabled", false))
          throw std::runtime_error(axis_name(a) + ": motion stopped while homing the machine for the gantry's tuning");
        if (abort_requested()) throw std::runtime_error(axis_name(a) + ": the tuning was aborted while homing");
        if (std::chrono::steady_clock::now() > until)
          throw std::runtime_error(axis_name(a) + ": the machine was not homed within 150 s: check the homing keys");
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
    JointNow now = joint_now(c, a.joint);
    if (now.pos < travel.min || now.pos > travel.max)
      throw std::runtime_error(axis_name(a) + " stands at " + fmt("%.3f", now.pos) + " mm, outside its travel " +
                               fmt("%g", travel.min) + ".." + fmt("%g", travel.max) + " mm (" + travel.source +
                               "): jog it inside first");
    // The ceilings must be allowed by the running configuration (runtime
    // limits may only be lowered below the INI's).
    // The jerk: the test's acceleration over four servo periods, never
    // above what the running configuration allows.
    double jerk_cap = 1e300;
    for (const Limits& l : limits_before.joints)
      if (l.j > 0) jerk_cap = std::min(jerk_cap, l.j);
    if (m.pair && limits_before.axis.j > 0) jerk_cap = std::min(jerk_cap, limits_before.axis.j);
    try {
      set_limits(c, m, o.max_velocity, o.max_acceleration, std::min(o.max_acceleration / (4 * period), jerk_cap));
    } catch (const std::exception& e) {
      throw std::runtime_error(axis_name(a) + ": the running configuration does not allow the ceilings (" +
                               std::string(e.what()) +
                               "): lower --max-velocity / --max-acceleration, or tune with --bring-up DIR");
    }
    // The velocity series accelerates at a quarter of the acceleration
    // ceiling (more where the travel needs it); the acceleration series
    // runs at the highest clean velocity. The jerk lets the acceleration
    // swing across its range in eight servo periods (the free planner
    // allows four).
    const int total = 2 * o.steps + 10;  // at most: both series, their refinements and repeats
    int index = 0;
    const double window = hi - lo;
    std::vector<double> side_reference;  // each side's first clean test's ferror per velocity
    auto run_one = [&](const std::string& series, double v, double acc) -> const TuningTest* {
      // From where the joint stands towards the farther end of the window
      // (first into the window when it stands between it and a limit, or
      // where a fault left it: at the first test's speed and acceleration).
      double p0 = joint_now(c, m.joints.front()).pos;
      if (p0 < lo - 1e-3 || p0 > hi + 1e-3) {
        const double edge = p0 < lo ? lo : hi;
        const double v_in = std::min(v, o.max_velocity / 16), a_in = std::min(acc, o.max_acceleration / 4);
        set_limits(c, m, v_in, a_in, std::min(a_in / (4 * period), jerk_cap));
        if (!move(c, m, v_in, edge - p0, 2 * std::fabs(edge - p0) / v_in + 5))
          throw std::runtime_error(axis_name(a) + ": motion stopped on the way into the test travel");
        p0 = joint_now(c, m.joints.front()).pos;
      }
      const double sign = hi - p0 >= p0 - lo ? 1.0 : -1.0;
      const double room = std::max(0.0, sign > 0 ? hi - p0 : p0 - lo);
      const double cruise = 0.1;
      double j = std::min(acc / (4 * period), jerk_cap);
      double need = v * v / acc + v * acc / j + cruise * v;
      if (need > room) {
        const double left = room - cruise * v - v * acc / j;
        if (left <= 0 || v * v / left > o.max_acceleration) return nullptr;  // travel too short
        acc = v * v / left;
        j = std::min(acc / (4 * period), jerk_cap);
        need = room;
      }
      const double dist = sign * std::min(need, room);
      ++index;
      TuningTest t;
      t.series = series;
      t.velocity = v;
      t.acceleration = acc;
      t.jerk = j;
      progress(std::to_string(index) + "/" + std::to_string(total) + " " + series + " test: " + fmt("%.0f", v) +
               " mm/s, " + fmt("%.0f", acc) + " mm/s2 over " + fmt("%.1f", dist) + " mm");
      set_limits(c, m, v, acc, j);
      const double t_move = std::fabs(dist) / v + v / acc + acc / j + 0.3;
      // At most the buffer the written configuration loads (loadrt scope samples=60000).
      const auto samples = std::min(60000L, static_cast<long>(std::ceil((2 * t_move * 1.2 + 0.5) / period)));
      std::string list;
      for (int k : m.joints)
        for (const auto& p : tuning_scope_pins(k, k)) list += (list.empty() ? "" : ",") + p;
      c.halcmd({"scope", "stop"});
      c.halcmd({"scope", "setup", list, "samples=" + std::to_string(samples), "pre=0", "mode=single"});
      c.halcmd({"scope", "arm"});
      bool ok = move(c, m, v, dist, 2 * t_move + 3);
      if (ok) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        ok = move(c, m, v, -dist, 2 * t_move + 3);
      }
      // The scope runs on to its end (a fault is recorded too).
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(samples * period * 3 + 5);
      while (std::string(trim(c.halcmd({"scope", "state"}))).rfind("done", 0) != 0) {
        if (std::chrono::steady_clock::now() > until) throw std::runtime_error("the scope did not finish its capture");
        if (abort_requested()) throw std::runtime_error(axis_name(a) + ": the tuning test was aborted");
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
      const auto records = parse_scope_csv_sides(c.halcmd({"scope", "csv"}), static_cast<int>(m.joints.size()));
      std::vector<std::string> files;
      for (std::size_t k = 0; k < records.size(); ++k) {
        char name[112];
        std::snprintf(name, sizeof name, "%c-%02d-%s-v%.0f-a%.0f%s.csv", static_cast<char>(std::tolower(a.letter)), index,
                      series.c_str(), v, acc, k == 0 ? "" : "-second-drive");
        files.push_back((o.record_dir / name).string());
        write_file_atomically(files.back(), tuning_csv(records[k]));
      }
      t.csv = files.front();
      if (!ok) {
        t.fault = true;
        t.finding = "the drive faulted or motion stopped during the test (a following-error trip or an amplifier fault)";
        // Reset: off, E-stop reset and on once (enabling resets the drive's fault).
        c.cnc({"off"});
        std::string reset = "reset: the drive is enabled again";
        try {
          c.cnc({"estop-reset"});
          c.cnc({"on"});
          if (!joint_now(c, a.joint).enabled) reset = "reset failed: motion is not enabled";
          c.cnc({"mode", "manual"});
        } catch (const std::exception& e) {
          reset = std::string("reset failed: ") + e.what();
        }
        t.finding += "; " + reset;
        if (reset.rfind("reset failed", 0) == 0) {
          analyse_test(t, records.front(), o.rule, 0);
          tests.push_back(t);
          throw std::runtime_error(axis_name(a) + ": " + t.finding + ": check the drive (its display, the error code in `cnc messages`)");
        }
      }
      // Each side against its own first clean test; a pair's test is the
      // worse of its two sides.
      std::vector<TuningTest> sides;
      for (std::size_t k = 0; k < records.size(); ++k) {
        TuningTest x = t;
        x.csv = files[k];
        analyse_test(x, records[k], o.rule, k < side_reference.size() ? side_reference[k] : 0);
        sides.push_back(x);
      }
      t = sides.size() == 2 ? worse_side(sides[0], sides[1]) : sides.front();
      if (!t.saturated && !t.fault && side_reference.empty())
        for (const TuningTest& x : sides) side_reference.push_back(x.ferror_per_velocity);
      std::string peaks = fmt("%.4f", sides[0].max_ferror);
      if (sides.size() == 2) peaks += " / " + fmt("%.4f", sides[1].max_ferror) + " (each side)";
      report("test " + std::to_string(index) + " (" + series + "): " + fmt("%.0f", v) + " mm/s, " + fmt("%.0f", acc) +
             " mm/s2: peak following error " + peaks + " mm, torque " + fmt("%.0f", t.max_torque) +
             " %, " + (t.saturated ? "SATURATED: " + t.finding : std::string("clean")) + " (" + t.csv + ")");
      tests.push_back(t);
      return &tests.back();
    };

    // A saturation without a fault is confirmed by repeating the test: a
    // host stall (a late servo cycle jolts the drive) must not end a
    // series. One that does not repeat is dropped (its file stays).
    auto run_checked = [&](const std::string& series, double v, double acc) -> const TuningTest* {
      const TuningTest* t = run_one(series, v, acc);
      if (!t || !t->saturated || t->fault) return t;
      const TuningTest first = *t;
      const TuningTest* again = run_one(series, v, acc);
      if (!again || again->saturated) return again;
      tests.erase(tests.end() - 2);
      report("the saturation of " + first.csv + " did not repeat: that test is ignored");
      return &tests.back();
    };
    // Each series: geometric from a sixteenth of its ceiling to the
    // ceiling, then two tests halving the gap (geometrically) between the
    // last clean and the saturated one.
    std::string velocity_note;
    const double a_v = o.max_acceleration / 4;
    double v_clean = 0, v_bad = 0;
    for (int k = 0; k < o.steps; ++k) {
      const double v = o.max_velocity * std::pow(16.0, -static_cast<double>(o.steps - 1 - k) / (o.steps - 1));
      const TuningTest* t = run_checked("velocity", v, a_v);
      if (!t) {
        velocity_note = "the travel (" + fmt("%.0f", window) + " mm between the soft limits less 5 %) is too short to test " +
                        fmt("%.0f", v) + " mm/s";
        break;
      }
      if (t->saturated) {
        v_bad = v;
        break;
      }
      v_clean = std::max(v_clean, std::min(t->velocity, t->reached_velocity));
    }
    if (v_clean <= 0) throw std::runtime_error(axis_name(a) + ": the first velocity test is not clean: " +
                                               (tests.empty() ? velocity_note : tests.back().finding) +
                                               ": lower the ceilings");
    for (int r = 0; r < 2 && v_bad > 0; ++r) {
      const double v = std::sqrt(v_clean * v_bad);
      const TuningTest* t = run_checked("velocity", v, a_v);
      if (!t) break;
      if (t->saturated) v_bad = v;
      else v_clean = std::max(v_clean, std::min(t->velocity, t->reached_velocity));
    }
    const double a_start = std::max(a_v, o.max_acceleration / 16);
    double a_clean = a_v, a_bad = 0;
    for (int k = 0; k < o.steps; ++k) {
      const double acc = a_start * std::pow(o.max_acceleration / a_start, static_cast<double>(k) / (o.steps - 1));
      if (acc <= a_v * 1.0001 && k + 1 < o.steps) continue;  // tested in the velocity series
      const TuningTest* t = run_checked("acceleration", v_clean, acc);
      if (!t) break;
      if (t->saturated) {
        a_bad = acc;
        break;
      }
      a_clean = acc;
    }
    for (int r = 0; r < 2 && a_bad > 0; ++r) {
      const double acc = std::sqrt(a_clean * a_bad);
      const TuningTest* t = run_checked("acceleration", v_clean, acc);
      if (!t) break;
      if (t->saturated) a_bad = acc;
      else a_clean = acc;
    }
    result = recommend_tuning(tests, o.margin_pct, a.scaling.counts_per_mm());
    if (!velocity_note.empty() && result.velocity_limit.rfind("saturation", 0) != 0) result.velocity_limit = velocity_note;
  } catch (const std::exception& e) {
    // Whatever stopped the tests: the machine off, the joint's limits back.
    std::string off = switch_off_after_failure(c);
    try {
      restore_limits(c, m, limits_before);
    } catch (const std::exception&) {
      off += " (the joint's run-time limits were not restored: restart the controller)";
    }
    // Ctrl-C reaches the halcmd or cnc child too: its failure means the abort.
    std::string why = e.what();
    if (abort_requested() && why.find("aborted") == std::string::npos)
      why = axis_name(a) + ": the tuning tests were aborted (" + why + ")";
    throw std::runtime_error(why + off);
  }
  c.cnc({"off"});
  try {
    restore_limits(c, m, limits_before);
  } catch (const std::exception& e) {
    report(std::string("warning: the joint's limits were not restored: ") + e.what());
  }
  return result;
}

State tuning_configuration(const State& s, char letter, const TuneOptions& o) {
  State t = s;
  Axis* a = t.axis(letter);
  if (!a) throw std::invalid_argument(std::string("axis ") + letter + " has no drive yet");
  AxisTuning cfg;
  cfg.margin_pct = 0;  // the ceilings themselves
  cfg.max_velocity = o.max_velocity;
  cfg.max_acceleration = o.max_acceleration;
  // The free planner caps the jerk itself (four periods per swing).
  cfg.max_jerk = o.max_acceleration * 1000;
  // Wide enough for the bus's transport delay at the ceiling (a few servo
  // periods of travel) several times over: the drive's own limits and the
  // analysis decide, motion's check only catches a runaway.
  const double period = static_cast<double>(servo_period_ns(machine_joints(t).size())) * 1e-9;
  cfg.ferror = std::max(2.0, o.max_velocity * 10 * period);
  cfg.min_ferror = 1.0;
  a->tuning = cfg;
  return t;
}

}  // namespace cnc::commission
