#include "commission/state.hpp"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "core/util/atomic_file.hpp"

namespace cnc::commission {

using nlohmann::json;

double AxisScaling::nominal_counts_per_mm() const noexcept {
  if (screw_lead <= 0 || gear_load_revs <= 0) return 0;
  return encoder_counts * (gear_motor_revs / gear_load_revs) / screw_lead;
}

const ScannedNode* State::node(int id) const noexcept {
  for (const auto& n : nodes)
    if (n.node_id == id) return &n;
  return nullptr;
}
Axis* State::axis(char letter) noexcept {
  for (auto& a : axes)
    if (a.letter == letter) return &a;
  return nullptr;
}
const ScannedSlave* State::slave(int position) const noexcept {
  for (const auto& n : slaves)
    if (static_cast<int>(n.position) == position) return &n;
  return nullptr;
}
const Axis* State::axis(char letter) const noexcept { return const_cast<State*>(this)->axis(letter); }

namespace {

template <class T>
void put_opt(json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}
template <class T>
void get_opt(const json& j, const char* key, std::optional<T>& v) {
  if (j.contains(key) && !j[key].is_null()) v = j[key].get<T>();
}
template <class T>
void get(const json& j, const char* key, T& v) {
  if (j.contains(key)) v = j[key].get<T>();
}
// The factor group (0x608F, 0x6091, 0x6092) of a scanned node or slave.
template <class N>
void put_factors(json& j, const N& n) {
  put_opt(j, "encoder_increments", n.encoder_increments);
  put_opt(j, "encoder_motor_revs", n.encoder_motor_revs);
  put_opt(j, "gear_motor_revs", n.gear_motor_revs);
  put_opt(j, "gear_shaft_revs", n.gear_shaft_revs);
  put_opt(j, "feed", n.feed);
  put_opt(j, "feed_shaft_revs", n.feed_shaft_revs);
  put_opt(j, "max_torque", n.max_torque);  // 0x6072, read with the factor group
}
template <class N>
void get_factors(const json& j, N& n) {
  get_opt(j, "encoder_increments", n.encoder_increments);
  get_opt(j, "encoder_motor_revs", n.encoder_motor_revs);
  get_opt(j, "gear_motor_revs", n.gear_motor_revs);
  get_opt(j, "gear_shaft_revs", n.gear_shaft_revs);
  get_opt(j, "feed", n.feed);
  get_opt(j, "feed_shaft_revs", n.feed_shaft_revs);
  get_opt(j, "max_torque", n.max_torque);
}

json node_json(const ScannedNode& n) {
  json j = {{"node_id", n.node_id}, {"device_type", n.device_type}, {"vendor_id", n.vendor_id},
            {"product_code", n.product_code}, {"revision", n.revision}, {"serial", n.serial},
            {"name", n.name}, {"firmware", n.firmware}, {"eds", n.eds}, {"cia402", n.cia402},
            {"fault", n.fault}, {"problems", n.problems}};
  put_opt(j, "supported_modes", n.supported_modes);
  put_opt(j, "statusword", n.statusword);
  put_opt(j, "error_code", n.error_code);
  put_factors(j, n);
  return j;
}

ScannedNode node_from(const json& j) {
  ScannedNode n;
  get(j, "node_id", n.node_id);
  get(j, "device_type", n.device_type);
  get(j, "vendor_id", n.vendor_id);
  get(j, "product_code", n.product_code);
  get(j, "revision", n.revision);
  get(j, "serial", n.serial);
  get(j, "name", n.name);
  get(j, "firmware", n.firmware);
  get(j, "eds", n.eds);
  get(j, "cia402", n.cia402);
  get(j, "fault", n.fault);
  get(j, "problems", n.problems);
  get_opt(j, "supported_modes", n.supported_modes);
  get_opt(j, "statusword", n.statusword);
  get_opt(j, "error_code", n.error_code);
  get_factors(j, n);
  return n;
}

json slave_json(const ScannedSlave& n) {
  json j = {{"position", n.position}, {"vendor_id", n.vendor_id}, {"product_code", n.product_code},
          {"revision", n.revision}, {"serial", n.serial}, {"name", n.name}, {"order", n.order},
          {"coe", n.coe}, {"dc", n.dc}, {"esi", n.esi}, {"problems", n.problems}};
  put_opt(j, "supported_modes", n.supported_modes);
  put_factors(j, n);
  return j;
}

ScannedSlave slave_from(const json& j) {
  ScannedSlave n;
  get(j, "position", n.position);
  get(j, "vendor_id", n.vendor_id);
  get(j, "product_code", n.product_code);
  get(j, "revision", n.revision);
  get(j, "serial", n.serial);
  get(j, "name", n.name);
  get(j, "order", n.order);
  get(j, "coe", n.coe);
  get(j, "dc", n.dc);
  get(j, "esi", n.esi);
  get(j, "problems", n.problems);
  get_opt(j, "supported_modes", n.supported_modes);
  get_factors(j, n);
  return n;
}

// --- Step 8, compensation; step 9, backup (helper C) ---
json points_json(const std::vector<CompPoint>& v) {
  json a = json::array();
  for (const CompPoint& p : v) a.push_back({p.target, p.run, p.direction, p.deviation_um});
  return a;
}
std::vector<CompPoint> points_from(const json& a, const std::string& origin, const char* key) {
  std::vector<CompPoint> v;
  for (const json& p : a) {
    if (!p.is_array() || p.size() != 4)
      throw std::runtime_error(origin + ": axes[].compensation." + key + ": expected [target, run, direction, deviation_um]");
    v.push_back({p[0].get<double>(), p[1].get<int>(), p[2].get<int>(), p[3].get<double>()});
  }
  return v;
}
json figures_json(const CompFigures& f) {
  return {{"A", f.A}, {"A_up", f.A_up}, {"A_down", f.A_down}, {"E", f.E}, {"E_up", f.E_up}, {"E_down", f.E_down},
          {"R", f.R}, {"B", f.B}, {"B_mean", f.B_mean}, {"M", f.M}};
}
CompFigures figures_from(const json& j) {
  CompFigures f;
  get(j, "A", f.A);
  get(j, "A_up", f.A_up);
  get(j, "A_down", f.A_down);
  get(j, "E", f.E);
  get(j, "E_up", f.E_up);
  get(j, "E_down", f.E_down);
  get(j, "R", f.R);
  get(j, "B", f.B);
  get(j, "B_mean", f.B_mean);
  get(j, "M", f.M);
  return f;
}
json compensation_json(const AxisCompensation& c) {
  json j = {{"x_min", c.x_min}, {"x_max", c.x_max}, {"targets", c.targets}, {"runs", c.runs},
            {"overshoot_mm", c.overshoot_mm}, {"dwell_s", c.dwell_s}, {"feed_mm_min", c.feed_mm_min},
            {"seed", c.seed}, {"program", c.program}, {"source", c.source}, {"points", points_json(c.points)},
            {"check_points", points_json(c.check_points)}, {"fitted", c.fitted}, {"fit_dir", c.fit_dir},
            {"install", c.install}, {"scaling_counts_per_mm", c.scaling_counts_per_mm},
            {"scaling_reverse", c.scaling_reverse}};
  if (c.measured) j["measured"] = figures_json(*c.measured);
  if (c.checked) j["checked"] = figures_json(*c.checked);
  if (c.fitted) {
    j["before"] = figures_json(c.before);
    j["predicted"] = figures_json(c.predicted);
    j["table"] = {{"nominal", c.nominal}, {"forward", c.forward}, {"reverse", c.reverse}};
  }
  return j;
}
AxisCompensation compensation_from(const json& j, const std::string& origin) {
  AxisCompensation c;
  get(j, "x_min", c.x_min);
  get(j, "x_max", c.x_max);
  get(j, "targets", c.targets);
  get(j, "runs", c.runs);
  get(j, "overshoot_mm", c.overshoot_mm);
  get(j, "dwell_s", c.dwell_s);
  get(j, "feed_mm_min", c.feed_mm_min);
  get(j, "seed", c.seed);
  get(j, "program", c.program);
  get(j, "source", c.source);
  get(j, "fitted", c.fitted);
  get(j, "fit_dir", c.fit_dir);
  get(j, "install", c.install);
  get(j, "scaling_counts_per_mm", c.scaling_counts_per_mm);
  get(j, "scaling_reverse", c.scaling_reverse);
  if (j.contains("points")) c.points = points_from(j["points"], origin, "points");
  if (j.contains("check_points")) c.check_points = points_from(j["check_points"], origin, "check_points");
  if (j.contains("measured")) c.measured = figures_from(j["measured"]);
  if (j.contains("checked")) c.checked = figures_from(j["checked"]);
  if (j.contains("before")) c.before = figures_from(j["before"]);
  if (j.contains("predicted")) c.predicted = figures_from(j["predicted"]);
  if (j.contains("table")) {
    const json& t = j["table"];
    get(t, "nominal", c.nominal);
    get(t, "forward", c.forward);
    get(t, "reverse", c.reverse);
    if (c.forward.size() != c.nominal.size() || c.reverse.size() != c.nominal.size())
      throw std::runtime_error(origin + ": axes[].compensation.table: nominal, forward and reverse differ in length");
  }
  return c;
}
json backup_json(const DriveBackup& b) { return {{"dir", b.dir}, {"time", b.time}, {"files", b.files}}; }
DriveBackup backup_from(const json& j) {
  DriveBackup b;
  get(j, "dir", b.dir);
  get(j, "time", b.time);
  get(j, "files", b.files);
  return b;
}
// --- end of helper C's block ---
// --- Steps 5 and 6 (helper A) ---
json switch_json(const SwitchFinding& f) {
  return {{"seen", f.seen}, {"position", f.position}, {"position_high", f.position_high}, {"has_high", f.has_high},
          {"active_high", f.active_high}, {"pin", f.pin}};
}
SwitchFinding switch_from(const json& j) {
  SwitchFinding f;
  get(j, "seen", f.seen);
  get(j, "position", f.position);
  get(j, "position_high", f.position_high);
  get(j, "has_high", f.has_high);
  get(j, "active_high", f.active_high);
  get(j, "pin", f.pin);
  return f;
}
void put_steps56(json& j, const Axis& a) {
  if (a.switches) {
    const AxisSwitches& w = *a.switches;
    j["switches"] = {{"search_mm", w.search_mm}, {"velocity", w.velocity}, {"start", w.start},
                     {"neg_limit", switch_json(w.neg_limit)}, {"pos_limit", switch_json(w.pos_limit)},
                     {"home", switch_json(w.home)}, {"problems", w.problems}};
  }
  if (a.homing) {
    const AxisHoming& h = *a.homing;
    j["homing"] = {{"method", h.method}, {"references", h.references}, {"spread", h.spread},
                   {"search_velocity", h.search_velocity}, {"latch_velocity", h.latch_velocity},
                   {"home_offset", h.home_offset}, {"home", h.home}, {"measured", h.measured}};
  }
}
void get_steps56(const json& j, Axis& a) {
  if (j.contains("switches")) {
    const json& w = j["switches"];
    AxisSwitches s;
    get(w, "search_mm", s.search_mm);
    get(w, "velocity", s.velocity);
    get(w, "start", s.start);
    if (w.contains("neg_limit")) s.neg_limit = switch_from(w["neg_limit"]);
    if (w.contains("pos_limit")) s.pos_limit = switch_from(w["pos_limit"]);
    if (w.contains("home")) s.home = switch_from(w["home"]);
    get(w, "problems", s.problems);
    a.switches = s;
  }
  if (j.contains("homing")) {
    const json& w = j["homing"];
    AxisHoming h;
    get(w, "method", h.method);
    get(w, "references", h.references);
    get(w, "spread", h.spread);
    get(w, "search_velocity", h.search_velocity);
    get(w, "latch_velocity", h.latch_velocity);
    get(w, "home_offset", h.home_offset);
    get(w, "home", h.home);
    get(w, "measured", h.measured);
    a.homing = h;
  }
}
// --- end of steps 5 and 6 ---
// --- step 7, tuning (helper B) ---
json tuning_json(const AxisTuning& t) {
  json tests = json::array();
  for (const TuningTest& x : t.tests)
    tests.push_back({{"series", x.series}, {"velocity", x.velocity}, {"acceleration", x.acceleration},
                     {"jerk", x.jerk}, {"reached_velocity", x.reached_velocity},
                     {"reached_acceleration", x.reached_acceleration}, {"max_ferror", x.max_ferror},
                     {"max_torque", x.max_torque}, {"ferror_per_velocity", x.ferror_per_velocity},
                     {"standstill_ferror", x.standstill_ferror}, {"limit_cycles", x.limit_cycles},
                     {"saturated", x.saturated}, {"fault", x.fault}, {"finding", x.finding}, {"csv", x.csv}});
  return {{"tests", tests}, {"margin_pct", t.margin_pct}, {"max_velocity", t.max_velocity},
          {"max_acceleration", t.max_acceleration}, {"max_jerk", t.max_jerk}, {"ferror", t.ferror},
          {"min_ferror", t.min_ferror}, {"velocity_limit", t.velocity_limit},
          {"acceleration_limit", t.acceleration_limit}};
}

AxisTuning tuning_from(const json& j) {
  AxisTuning t;
  if (j.contains("tests"))
    for (const json& x : j["tests"]) {
      TuningTest r;
      get(x, "series", r.series);
      get(x, "velocity", r.velocity);
      get(x, "acceleration", r.acceleration);
      get(x, "jerk", r.jerk);
      get(x, "reached_velocity", r.reached_velocity);
      get(x, "reached_acceleration", r.reached_acceleration);
      get(x, "max_ferror", r.max_ferror);
      get(x, "max_torque", r.max_torque);
      get(x, "ferror_per_velocity", r.ferror_per_velocity);
      get(x, "standstill_ferror", r.standstill_ferror);
      get(x, "limit_cycles", r.limit_cycles);
      get(x, "saturated", r.saturated);
      get(x, "fault", r.fault);
      get(x, "finding", r.finding);
      get(x, "csv", r.csv);
      t.tests.push_back(r);
    }
  get(j, "margin_pct", t.margin_pct);
  get(j, "max_velocity", t.max_velocity);
  get(j, "max_acceleration", t.max_acceleration);
  get(j, "max_jerk", t.max_jerk);
  get(j, "ferror", t.ferror);
  get(j, "min_ferror", t.min_ferror);
  get(j, "velocity_limit", t.velocity_limit);
  get(j, "acceleration_limit", t.acceleration_limit);
  return t;
}
json step_json(const StepResponse& s) {
  return {{"amplitude_mm_s", s.amplitude_mm_s}, {"edges", s.edges},     {"rise_time_s", s.rise_time_s},
          {"overshoot_pct", s.overshoot_pct},   {"settling_time_s", s.settling_time_s}, {"csv", s.csv}};
}
json chirp_json(const ChirpResponse& c) {
  json points = json::array();
  for (const FrequencyPoint& p : c.points)
    points.push_back({{"frequency_hz", p.frequency_hz}, {"gain_db", p.gain_db}, {"phase_deg", p.phase_deg}});
  return {{"amplitude_mm_s", c.amplitude_mm_s}, {"points", points},  {"bandwidth_hz", c.bandwidth_hz},
          {"bandwidth_above", c.bandwidth_above}, {"csv", c.csv}};
}
json response_json(const AxisResponse& r) {
  json j = {{"skipped", r.skipped},
            {"gains", {{"velocity_gain", r.gains.velocity_gain}, {"velocity_integral", r.gains.velocity_integral}}}};
  put_opt(j["gains"], "position_gain", r.gains.position_gain);
  if (r.step) j["step"] = step_json(*r.step);
  if (r.chirp) j["chirp"] = chirp_json(*r.chirp);
  if (r.position_step) j["position_step"] = step_json(*r.position_step);
  if (r.position_chirp) j["position_chirp"] = chirp_json(*r.position_chirp);
  return j;
}

StepResponse step_from(const json& w) {
  StepResponse s;
  get(w, "amplitude_mm_s", s.amplitude_mm_s);
  get(w, "edges", s.edges);
  get(w, "rise_time_s", s.rise_time_s);
  get(w, "overshoot_pct", s.overshoot_pct);
  get(w, "settling_time_s", s.settling_time_s);
  get(w, "csv", s.csv);
  return s;
}
ChirpResponse chirp_from(const json& w) {
  ChirpResponse c;
  get(w, "amplitude_mm_s", c.amplitude_mm_s);
  if (w.contains("points"))
    for (const json& x : w["points"]) {
      FrequencyPoint p;
      get(x, "frequency_hz", p.frequency_hz);
      get(x, "gain_db", p.gain_db);
      get(x, "phase_deg", p.phase_deg);
      c.points.push_back(p);
    }
  get(w, "bandwidth_hz", c.bandwidth_hz);
  get(w, "bandwidth_above", c.bandwidth_above);
  get(w, "csv", c.csv);
  return c;
}
AxisResponse response_from(const json& j) {
  AxisResponse r;
  get(j, "skipped", r.skipped);
  if (j.contains("gains")) {
    get(j["gains"], "velocity_gain", r.gains.velocity_gain);
    get(j["gains"], "velocity_integral", r.gains.velocity_integral);
    get_opt(j["gains"], "position_gain", r.gains.position_gain);
  }
  if (j.contains("step")) r.step = step_from(j["step"]);
  if (j.contains("chirp")) r.chirp = chirp_from(j["chirp"]);
  if (j.contains("position_step")) r.position_step = step_from(j["position_step"]);
  if (j.contains("position_chirp")) r.position_chirp = chirp_from(j["position_chirp"]);
  return r;
}
// --- end of step 7 ---

json direction_json(const DirectionTest& d) {
  return {{"commanded_mm", d.commanded_mm}, {"feedback_mm", d.feedback_mm}, {"dial_mm", d.dial_mm},
          {"has_dial", d.has_dial}, {"reversed", d.reversed}, {"correction", d.correction}, {"verdict", d.verdict}};
}
DirectionTest direction_from(const json& d) {
  DirectionTest t;
  get(d, "commanded_mm", t.commanded_mm);
  get(d, "feedback_mm", t.feedback_mm);
  get(d, "dial_mm", t.dial_mm);
  get(d, "has_dial", t.has_dial);
  get(d, "reversed", t.reversed);
  get(d, "correction", t.correction);
  get(d, "verdict", t.verdict);
  return t;
}

json axis_json(const Axis& a) {
  json j = {{"letter", std::string(1, a.letter)}, {"joint", a.joint}, {"node", a.node}, {"slave", a.slave},
            {"min_limit", a.min_limit}, {"max_limit", a.max_limit},
            {"max_velocity", a.max_velocity}, {"max_acceleration", a.max_acceleration}, {"enabled", a.enabled},
            {"limits_source", a.limits_source}};
  const AxisScaling& s = a.scaling;
  j["scaling"] = {{"encoder_counts", s.encoder_counts}, {"gear_motor_revs", s.gear_motor_revs},
                  {"gear_load_revs", s.gear_load_revs}, {"screw_lead", s.screw_lead},
                  {"correction", s.correction}, {"reverse", s.reverse}, {"dial_checked", s.dial_checked},
                  {"source", s.source},
                  {"counts_per_mm", s.counts_per_mm()}};
  if (a.direction) j["direction_test"] = direction_json(*a.direction);
  if (a.gantry) {
    const GantryDrive& g = *a.gantry;
    json gj = {{"node", g.node}, {"slave", g.slave}, {"joint", g.joint}, {"reverse", g.reverse},
               {"correction", g.correction}, {"dial_checked", g.dial_checked}, {"squaring", g.squaring}};
    if (g.direction) gj["direction_test"] = direction_json(*g.direction);
    Axis steps;  // its switches and homing as an axis' (put_steps56)
    steps.switches = g.switches;
    steps.homing = g.homing;
    put_steps56(gj, steps);
    j["gantry"] = gj;
  }
  if (a.compensation) j["compensation"] = compensation_json(*a.compensation);
  put_steps56(j, a);
  if (a.tuning) j["tuning"] = tuning_json(*a.tuning);
  if (a.response) j["response"] = response_json(*a.response);
  return j;
}

Axis axis_from(const json& j, const std::string& origin) {
  Axis a;
  const std::string letter = j.value("letter", std::string("X"));
  if (letter.size() != 1) throw std::runtime_error(origin + ": axes[].letter \"" + letter + "\": expected one letter");
  a.letter = letter[0];
  get(j, "joint", a.joint);
  get(j, "node", a.node);
  if (j.contains("slave")) get(j, "slave", a.slave);
  if (j.contains("gantry_with") && !j["gantry_with"].get<std::string>().empty())  // the key before gantry pairs were written
    throw std::runtime_error(origin + ": axes[].gantry_with \"" + j["gantry_with"].get<std::string>() +
                             "\": a gantry's second drive is assigned with --gantry-node (or --gantry-slave) now: "
                             "assign axis " + letter + " again");
  if (j.contains("gantry")) {
    const json& g = j["gantry"];
    GantryDrive d;
    get(g, "node", d.node);
    get(g, "slave", d.slave);
    get(g, "joint", d.joint);
    get(g, "reverse", d.reverse);
    get(g, "correction", d.correction);
    get(g, "dial_checked", d.dial_checked);
    get(g, "squaring", d.squaring);
    if (g.contains("direction_test")) d.direction = direction_from(g["direction_test"]);
    Axis steps;
    get_steps56(g, steps);
    d.switches = steps.switches;
    d.homing = steps.homing;
    a.gantry = d;
  }
  get(j, "min_limit", a.min_limit);
  get(j, "max_limit", a.max_limit);
  if (j.contains("limits_source")) {
    get(j, "limits_source", a.limits_source);
    if (!a.limits_source.empty() && a.limits_source != "entered" && a.limits_source != "switches")
      throw std::runtime_error(origin + ": axes[].limits_source \"" + a.limits_source +
                               "\": expected \"\", \"entered\" or \"switches\"");
  } else if (a.min_limit != Axis{}.min_limit || a.max_limit != Axis{}.max_limit) {
    a.limits_source = "entered";  // a file from before the key: limits other than the defaults were given
  }
  get(j, "max_velocity", a.max_velocity);
  get(j, "max_acceleration", a.max_acceleration);
  get(j, "enabled", a.enabled);
  if (j.contains("scaling")) {
    const json& s = j["scaling"];
    get(s, "encoder_counts", a.scaling.encoder_counts);
    get(s, "gear_motor_revs", a.scaling.gear_motor_revs);
    get(s, "gear_load_revs", a.scaling.gear_load_revs);
    get(s, "screw_lead", a.scaling.screw_lead);
    get(s, "correction", a.scaling.correction);
    get(s, "reverse", a.scaling.reverse);
    get(s, "dial_checked", a.scaling.dial_checked);
    get(s, "source", a.scaling.source);
  }
  if (j.contains("direction_test")) a.direction = direction_from(j["direction_test"]);
  if (j.contains("compensation")) a.compensation = compensation_from(j["compensation"], origin);
  get_steps56(j, a);
  if (j.contains("tuning")) a.tuning = tuning_from(j["tuning"]);
  if (j.contains("response")) a.response = response_from(j["response"]);
  return a;
}

}  // namespace

std::string to_json_text(const State& s) {
  json j;
  j["version"] = State::kVersion;
  j["machine"] = s.machine;
  j["interface"] = s.interface;
  j["bitrate"] = s.bitrate;
  j["eds_dir"] = s.eds_dir;
  j["nodes"] = json::array();
  for (const auto& n : s.nodes) j["nodes"].push_back(node_json(n));
  j["ethercat_interface"] = s.ethercat_interface;
  j["esi_dir"] = s.esi_dir;
  j["slaves"] = json::array();
  for (const auto& n : s.slaves) j["slaves"].push_back(slave_json(n));
  j["axes"] = json::array();
  for (const auto& a : s.axes) j["axes"].push_back(axis_json(a));
  j["ini_includes"] = s.ini_includes;
  j["hal_before_bus"] = s.hal_before_bus;
  j["hal_after_bus"] = s.hal_after_bus;
  j["log"] = s.log;
  if (s.backup) j["backup"] = backup_json(*s.backup);
  j["config_ini"] = s.config_ini;
  if (s.check)
    j["check"] = {{"program", s.check->program}, {"ini", s.check->ini}, {"passed", s.check->passed},
                  {"message", s.check->message}, {"duration_s", s.check->duration_s}, {"time", s.check->time}};
  return j.dump(2) + "\n";
}

State from_json_text(const std::string& text, const std::string& origin) {
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw std::runtime_error(origin + ": not a commissioning state (JSON): " + e.what());
  }
  try {
    const int version = j.value("version", 0);
    if (version != State::kVersion)
      throw std::runtime_error(origin + ": version " + std::to_string(version) + ", this program reads version " +
                               std::to_string(State::kVersion));
    State s;
    get(j, "machine", s.machine);
    get(j, "interface", s.interface);
    get(j, "bitrate", s.bitrate);
    get(j, "eds_dir", s.eds_dir);
    if (j.contains("nodes"))
      for (const json& n : j["nodes"]) s.nodes.push_back(node_from(n));
    get(j, "ethercat_interface", s.ethercat_interface);
    get(j, "esi_dir", s.esi_dir);
    if (j.contains("slaves"))
      for (const json& n : j["slaves"]) s.slaves.push_back(slave_from(n));
    if (j.contains("axes"))
      for (const json& a : j["axes"]) s.axes.push_back(axis_from(a, origin));
    get(j, "ini_includes", s.ini_includes);
    get(j, "hal_before_bus", s.hal_before_bus);
    get(j, "hal_after_bus", s.hal_after_bus);
    get(j, "log", s.log);
    if (j.contains("backup")) s.backup = backup_from(j["backup"]);
    get(j, "config_ini", s.config_ini);
    if (j.contains("check")) {
      const json& c = j["check"];
      CheckRun r;
      get(c, "program", r.program);
      get(c, "ini", r.ini);
      get(c, "passed", r.passed);
      get(c, "message", r.message);
      get(c, "duration_s", r.duration_s);
      get(c, "time", r.time);
      s.check = r;
    }
    return s;
  } catch (const json::exception& e) {
    throw std::runtime_error(origin + ": " + e.what());
  }
}

State load_state(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) {
    if (!std::filesystem::exists(file)) return State{};
    throw std::runtime_error(file.string() + ": cannot read");
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return from_json_text(ss.str(), file.string());
}

void save_state(const State& s, const std::filesystem::path& file) { write_file_atomically(file, to_json_text(s)); }

}  // namespace cnc::commission
