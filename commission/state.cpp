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

json node_json(const ScannedNode& n) {
  json j = {{"node_id", n.node_id}, {"device_type", n.device_type}, {"vendor_id", n.vendor_id},
            {"product_code", n.product_code}, {"revision", n.revision}, {"serial", n.serial},
            {"name", n.name}, {"firmware", n.firmware}, {"eds", n.eds}, {"cia402", n.cia402},
            {"fault", n.fault}, {"problems", n.problems}};
  put_opt(j, "supported_modes", n.supported_modes);
  put_opt(j, "statusword", n.statusword);
  put_opt(j, "error_code", n.error_code);
  put_opt(j, "encoder_increments", n.encoder_increments);
  put_opt(j, "encoder_motor_revs", n.encoder_motor_revs);
  put_opt(j, "gear_motor_revs", n.gear_motor_revs);
  put_opt(j, "gear_shaft_revs", n.gear_shaft_revs);
  put_opt(j, "feed", n.feed);
  put_opt(j, "feed_shaft_revs", n.feed_shaft_revs);
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
  get_opt(j, "encoder_increments", n.encoder_increments);
  get_opt(j, "encoder_motor_revs", n.encoder_motor_revs);
  get_opt(j, "gear_motor_revs", n.gear_motor_revs);
  get_opt(j, "gear_shaft_revs", n.gear_shaft_revs);
  get_opt(j, "feed", n.feed);
  get_opt(j, "feed_shaft_revs", n.feed_shaft_revs);
  return n;
}

json slave_json(const ScannedSlave& n) {
  return {{"position", n.position}, {"vendor_id", n.vendor_id}, {"product_code", n.product_code},
          {"revision", n.revision}, {"serial", n.serial}, {"name", n.name}, {"order", n.order},
          {"coe", n.coe}, {"dc", n.dc}, {"esi", n.esi}, {"problems", n.problems}};
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
  return n;
}

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
// --- end of step 7 ---

json axis_json(const Axis& a) {
  json j = {{"letter", std::string(1, a.letter)}, {"joint", a.joint}, {"node", a.node},
            {"gantry_with", a.gantry_with}, {"min_limit", a.min_limit}, {"max_limit", a.max_limit},
            {"max_velocity", a.max_velocity}, {"max_acceleration", a.max_acceleration}, {"enabled", a.enabled}};
  const AxisScaling& s = a.scaling;
  j["scaling"] = {{"encoder_counts", s.encoder_counts}, {"gear_motor_revs", s.gear_motor_revs},
                  {"gear_load_revs", s.gear_load_revs}, {"screw_lead", s.screw_lead},
                  {"correction", s.correction}, {"reverse", s.reverse}, {"source", s.source},
                  {"counts_per_mm", s.counts_per_mm()}};
  if (a.direction) {
    const DirectionTest& d = *a.direction;
    j["direction_test"] = {{"commanded_mm", d.commanded_mm}, {"feedback_mm", d.feedback_mm},
                           {"dial_mm", d.dial_mm}, {"has_dial", d.has_dial}, {"reversed", d.reversed},
                           {"correction", d.correction}, {"verdict", d.verdict}};
  }
  if (a.tuning) j["tuning"] = tuning_json(*a.tuning);
  return j;
}

Axis axis_from(const json& j, const std::string& origin) {
  Axis a;
  const std::string letter = j.value("letter", std::string("X"));
  if (letter.size() != 1) throw std::runtime_error(origin + ": axes[].letter \"" + letter + "\": expected one letter");
  a.letter = letter[0];
  get(j, "joint", a.joint);
  get(j, "node", a.node);
  get(j, "gantry_with", a.gantry_with);
  get(j, "min_limit", a.min_limit);
  get(j, "max_limit", a.max_limit);
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
    get(s, "source", a.scaling.source);
  }
  if (j.contains("direction_test")) {
    const json& d = j["direction_test"];
    DirectionTest t;
    get(d, "commanded_mm", t.commanded_mm);
    get(d, "feedback_mm", t.feedback_mm);
    get(d, "dial_mm", t.dial_mm);
    get(d, "has_dial", t.has_dial);
    get(d, "reversed", t.reversed);
    get(d, "correction", t.correction);
    get(d, "verdict", t.verdict);
    a.direction = t;
  }
  if (j.contains("tuning")) a.tuning = tuning_from(j["tuning"]);
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
