#include "commission/wizard/step_runner.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <nlohmann/json.hpp>

#include "cia402/profile.hpp"
#include "core/ipc/status.hpp"
#include "core/util/strings.hpp"

namespace cnc::commission::wizard {

namespace {

std::string trim_copy(std::string_view s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string_view::npos) return {};
  const auto b = s.find_last_not_of(" \t\r\n");
  return std::string(s.substr(a, b - a + 1));
}

char check_letter(char letter) {
  const char l = static_cast<char>(letter >= 'a' && letter <= 'z' ? letter - 'a' + 'A' : letter);
  if (std::string_view("XYZABCUVW").find(l) == std::string_view::npos)
    throw std::invalid_argument(std::string("axis \"") + letter + "\": expected one of X Y Z A B C U V W");
  return l;
}

double check_number(double v, const char* field) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string(field) + ": expected a number");
  return v;
}

double check_positive(double v, const char* field) {
  if (!(check_number(v, field) > 0)) throw std::invalid_argument(std::string(field) + ": must be greater than 0");
  return v;
}

void require(const std::string& v, const char* field) {
  if (trim_copy(v).empty()) throw std::invalid_argument(std::string(field) + ": required");
}

// `--bring-up DIR` of the motion steps: a controller of the step's own.
void add_bring_up(Argv& a, const std::string& dir) {
  if (!trim_copy(dir).empty()) a.insert(a.end(), {"--bring-up", trim_copy(dir)});
}

}  // namespace

const char* step_title(int step) noexcept {
  static const char* const kTitles[kSteps] = {"Bus",     "Axes",   "Scaling",      "Direction", "Limits",
                                              "Homing",  "Tuning", "Compensation", "Write"};
  return step >= 0 && step < kSteps ? kTitles[step] : "?";
}

std::string number_arg(double v) {
  char buf[64];
  for (int precision = 6; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

// ------------------------------------------------------------ command lines

Argv CommandBuilder::base() const { return {"--state", state_.string()}; }

Argv CommandBuilder::axis(char letter, const char* step) const {
  Argv a = base();
  a.insert(a.end(), {"axis", std::string(1, check_letter(letter)), step});
  return a;
}

Argv CommandBuilder::scan(bool ethercat, const std::string& interface, const std::string& description_dir,
                          const std::string& expect) const {
  require(interface, ethercat ? "EtherCAT interface" : "CAN interface");
  Argv a = base();
  a.insert(a.end(), {ethercat ? "scan-ethercat" : "scan", "--interface", trim_copy(interface)});
  if (!trim_copy(description_dir).empty())
    a.insert(a.end(), {ethercat ? "--esi-dir" : "--eds-dir", trim_copy(description_dir)});
  if (!ethercat && !trim_copy(expect).empty()) {
    for (const auto& w : split(trim_copy(expect), ',')) {
      int id = 0;
      const std::string t = trim_copy(w);
      const auto r = std::from_chars(t.data(), t.data() + t.size(), id);
      if (r.ec != std::errc() || r.ptr != t.data() + t.size() || id < 1 || id > 127)
        throw std::invalid_argument("expected nodes \"" + expect + "\": node-IDs 1-127 separated by commas");
    }
    a.insert(a.end(), {"--expect", trim_copy(expect)});
  }
  return a;
}

Argv CommandBuilder::lss(const std::string& interface, int first) const {
  require(interface, "CAN interface");
  if (first < 1 || first > 127) throw std::invalid_argument("first node-ID " + std::to_string(first) + ": expected 1-127");
  Argv a = base();
  a.insert(a.end(), {"lss", "--interface", trim_copy(interface), "--first", std::to_string(first)});
  return a;
}

Argv CommandBuilder::assign(char letter, int node, int joint, int gantry_node, bool gantry_reverse) const {
  if (node < 1 || node > 127) throw std::invalid_argument("node-ID " + std::to_string(node) + ": expected 1-127");
  if (joint < 0 || joint > 15) throw std::invalid_argument("joint " + std::to_string(joint) + ": expected 0-15");
  if (gantry_node < 0 || gantry_node > 127)
    throw std::invalid_argument("gantry node-ID " + std::to_string(gantry_node) + ": expected 1-127 (0: no gantry)");
  if (gantry_node == node)
    throw std::invalid_argument("gantry node-ID " + std::to_string(gantry_node) + ": the second drive needs a node of its own");
  Argv a = axis(letter, "assign");
  a.insert(a.end(), {"--node", std::to_string(node), "--joint", std::to_string(joint)});
  if (gantry_node > 0) a.insert(a.end(), {"--gantry-node", std::to_string(gantry_node)});
  if (gantry_node > 0 && gantry_reverse) a.push_back("--gantry-reverse");
  return a;
}

Argv CommandBuilder::identify(char letter, const std::filesystem::path& scratch_state) const {
  if (scratch_state.empty() || scratch_state == state_)
    throw std::invalid_argument("identify: needs a scratch copy of the state, not the state itself");
  Argv a = CommandBuilder(scratch_state).direction_test(letter, kIdentifyDistance, kIdentifyVelocity);
  return a;
}

Argv CommandBuilder::scaling(char letter, double lead, double counts, double gear_motor, double gear_load) const {
  Argv a = axis(letter, "scaling");
  a.insert(a.end(), {"--lead", number_arg(check_positive(lead, "screw lead"))});
  if (check_number(counts, "counts per revolution") > 0) a.insert(a.end(), {"--counts", number_arg(counts)});
  const bool gm = check_number(gear_motor, "gear (motor)") > 0, gl = check_number(gear_load, "gear (load)") > 0;
  if (gm != gl) throw std::invalid_argument("gear: give both motor and load revolutions, or neither (from the drive)");
  if (gm) a.insert(a.end(), {"--gear", number_arg(gear_motor) + ":" + number_arg(gear_load)});
  return a;
}

Argv CommandBuilder::direction_test(char letter, double distance, double velocity,
                                    const std::string& bring_up_dir) const {
  if (check_number(distance, "distance") == 0 || std::fabs(distance) > kMaxTestTravel)
    throw std::invalid_argument("distance " + number_arg(distance) + " mm: expected 0 < |distance| <= " +
                                number_arg(kMaxTestTravel));
  if (check_positive(velocity, "velocity") > kMaxTestVelocity)
    throw std::invalid_argument("velocity " + number_arg(velocity) + " mm/s: at most " + number_arg(kMaxTestVelocity));
  Argv a = axis(letter, "direction-test");
  a.insert(a.end(), {"--distance", number_arg(distance), "--velocity", number_arg(velocity)});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::dial(char letter, double mm) const {
  Argv a = axis(letter, "dial");
  a.push_back(number_arg(check_number(mm, "dial reading")));
  return a;
}

Argv CommandBuilder::limits(char letter, double min, double max, double velocity, double acceleration) const {
  if (!(check_number(min, "minimum") < check_number(max, "maximum")))
    throw std::invalid_argument("limits: the minimum must be below the maximum");
  Argv a = axis(letter, "limits");
  a.insert(a.end(), {"--min", number_arg(min), "--max", number_arg(max), "--velocity",
                     number_arg(check_positive(velocity, "velocity")), "--acceleration",
                     number_arg(check_positive(acceleration, "acceleration"))});
  return a;
}

Argv CommandBuilder::switches(char letter, double search_mm, double velocity, const std::string& bring_up_dir) const {
  Argv a = axis(letter, "switches");
  if (check_number(search_mm, "search distance") > 0) a.insert(a.end(), {"--search", number_arg(search_mm)});
  if (check_number(velocity, "velocity") > 0) a.insert(a.end(), {"--velocity", number_arg(velocity)});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::soft_limits(char letter, double margin_mm) const {
  Argv a = axis(letter, "soft-limits");
  if (check_number(margin_mm, "margin") < 0) throw std::invalid_argument("margin: must not be negative");
  a.insert(a.end(), {"--margin", number_arg(margin_mm)});
  return a;
}

Argv CommandBuilder::homing_methods() const {
  Argv a = base();
  a.push_back("homing-methods");
  return a;
}

Argv CommandBuilder::homing(char letter, const std::string& method, int repeat, const std::string& bring_up_dir) const {
  const std::string m = trim_copy(method);
  bool valid = m == "controller";
  if (m.rfind("drive:", 0) == 0) {
    int n = 0;
    const char* b = m.data() + 6;
    const auto r = std::from_chars(b, m.data() + m.size(), n);
    valid = r.ec == std::errc() && r.ptr == m.data() + m.size() && r.ptr != b;
  }
  if (!valid) throw std::invalid_argument("homing method \"" + method + "\": expected controller or drive:N");
  if (repeat < 1 || repeat > 20) throw std::invalid_argument("repeat " + std::to_string(repeat) + ": expected 1-20");
  Argv a = axis(letter, "homing");
  a.insert(a.end(), {"--method", m, "--repeat", std::to_string(repeat)});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::tune(char letter, double max_velocity, double max_acceleration, double margin_pct,
                          const std::string& record_dir, int steps, const std::string& bring_up_dir) const {
  Argv a = axis(letter, "tune");
  if (check_number(max_velocity, "maximum velocity") > 0) a.insert(a.end(), {"--max-velocity", number_arg(max_velocity)});
  if (check_number(max_acceleration, "maximum acceleration") > 0)
    a.insert(a.end(), {"--max-acceleration", number_arg(max_acceleration)});
  if (check_number(margin_pct, "margin") < 0 || margin_pct >= 100)
    throw std::invalid_argument("margin " + number_arg(margin_pct) + " %: expected 0-99");
  a.insert(a.end(), {"--margin", number_arg(margin_pct)});
  if (!trim_copy(record_dir).empty()) a.insert(a.end(), {"--record", trim_copy(record_dir)});
  if (steps != 0) {
    if (steps < 2 || steps > 20) throw std::invalid_argument("tests per series " + std::to_string(steps) + ": expected 2-20");
    a.insert(a.end(), {"--steps", std::to_string(steps)});
  }
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::accept_tuning(const Axis& ax) const {
  if (!ax.tuning || !(ax.tuning->max_velocity > 0) || !(ax.tuning->max_acceleration > 0))
    throw std::invalid_argument(std::string("axis ") + ax.letter + ": no tuning recommendation to accept (Tune first)");
  return limits(ax.letter, ax.min_limit, ax.max_limit, ax.tuning->max_velocity, ax.tuning->max_acceleration);
}

Argv CommandBuilder::response(char letter, long velocity_gain, const std::string& record_dir,
                              const std::string& bring_up_dir) const {
  require(bring_up_dir, "configuration folder");
  Argv a = axis(letter, "response");
  if (velocity_gain < 0 || velocity_gain > 4'000'000'000L)
    throw std::invalid_argument("velocity gain " + std::to_string(velocity_gain) + ": expected 0 (keep) to 4000000000");
  if (velocity_gain > 0) a.insert(a.end(), {"--velocity-gain", std::to_string(velocity_gain)});
  if (!trim_copy(record_dir).empty()) a.insert(a.end(), {"--record", trim_copy(record_dir)});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::comp_program(char letter, const std::string& out_ngc, const CompCycle& c) const {
  require(out_ngc, "program file");
  Argv a = axis(letter, "comp-program");
  a.insert(a.end(), {"--out", trim_copy(out_ngc)});
  const bool lo = check_number(c.min, "cycle start") != 0, hi = check_number(c.max, "cycle end") != 0;
  if (lo || hi) {
    if (!(c.min < c.max)) throw std::invalid_argument("cycle: the start must be below the end (or both 0: the soft limits)");
    a.insert(a.end(), {"--min", number_arg(c.min), "--max", number_arg(c.max)});
  }
  if (c.targets < 0 || c.runs < 0) throw std::invalid_argument("cycle: targets and runs must not be negative");
  if (c.targets > 0) a.insert(a.end(), {"--targets", std::to_string(c.targets)});
  if (c.runs > 0) a.insert(a.end(), {"--runs", std::to_string(c.runs)});
  if (check_number(c.dwell_s, "dwell") < 0 || check_number(c.feed_mm_min, "feed") < 0)
    throw std::invalid_argument("cycle: dwell and feed must not be negative");
  if (c.dwell_s > 0) a.insert(a.end(), {"--dwell", number_arg(c.dwell_s)});
  if (c.feed_mm_min > 0) a.insert(a.end(), {"--feed", number_arg(c.feed_mm_min)});
  return a;
}

Argv CommandBuilder::comp_run(char letter, const std::string& laser_csv, const std::string& laser_pin,
                              const std::string& bring_up_dir) const {
  Argv a = axis(letter, "comp-run");
  const std::string csv = trim_copy(laser_csv), pin = trim_copy(laser_pin);
  if (!csv.empty() && !pin.empty())
    throw std::invalid_argument("laser: a HAL pin or a CSV file, not both");
  if (!pin.empty()) a.insert(a.end(), {"--laser-pin", pin});
  if (!csv.empty()) a.insert(a.end(), {"--laser", csv});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::comp_run_camera(char letter, const std::string& camera, double pitch_mm, double um_per_px,
                                     const std::string& bring_up_dir) const {
  require(camera, "camera (/dev/videoN, or exec:COMMAND)");
  if (pitch_mm < 0 || um_per_px < 0) throw std::invalid_argument("camera: the scale's pitch and the pixel scale must be > 0");
  Argv a = axis(letter, "comp-run");
  a.insert(a.end(), {"--camera", trim_copy(camera)});
  if (pitch_mm > 0) a.insert(a.end(), {"--pitch", number_arg(pitch_mm)});
  if (um_per_px > 0) a.insert(a.end(), {"--um-per-px", number_arg(um_per_px)});
  add_bring_up(a, bring_up_dir);
  return a;
}

Argv CommandBuilder::comp_measurements(char letter, const std::string& csv, const std::string& values) const {
  const std::string c = trim_copy(csv);
  std::string v;
  for (char ch : values)  // entered one per line or separated by commas or blanks
    v += (ch == '\n' || ch == ' ' || ch == '\t' || ch == ';') ? ',' : ch;
  std::string joined;
  for (const auto& w : split(v, ',')) {
    const std::string t = trim_copy(w);
    if (t.empty()) continue;
    double d = 0;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), d);
    if (r.ec != std::errc() || r.ptr != t.data() + t.size())
      throw std::invalid_argument("measurement \"" + t + "\": expected a number (deviation in um)");
    joined += (joined.empty() ? "" : ",") + t;
  }
  if (c.empty() == joined.empty())
    throw std::invalid_argument("measurements: give either a CSV file or the values, not both or neither");
  Argv a = axis(letter, "comp-measurements");
  if (!c.empty()) a.insert(a.end(), {"--csv", c});
  else a.insert(a.end(), {"--values", joined});
  return a;
}

Argv CommandBuilder::comp_fit(char letter, bool install) const {
  Argv a = axis(letter, "comp-fit");
  if (install) a.push_back("--install");
  return a;
}

Argv CommandBuilder::write(const std::string& dir, const std::string& name, bool yes) const {
  require(dir, "configuration folder");
  Argv a = base();
  a.insert(a.end(), {"write", "--dir", trim_copy(dir)});
  if (!trim_copy(name).empty()) a.insert(a.end(), {"--name", trim_copy(name)});
  if (yes) a.push_back("--yes");
  return a;
}

Argv CommandBuilder::backup(const std::string& dir) const {
  require(dir, "backup folder");
  Argv a = base();
  a.insert(a.end(), {"backup", "--dir", trim_copy(dir)});
  return a;
}

Argv CommandBuilder::check(const std::string& program, double timeout_s) const {
  Argv a = base();
  a.push_back("check");
  if (!trim_copy(program).empty()) a.insert(a.end(), {"--program", trim_copy(program)});
  if (check_number(timeout_s, "time limit") < 0) throw std::invalid_argument("time limit: must not be negative");
  if (timeout_s > 0) a.insert(a.end(), {"--timeout", number_arg(timeout_s)});
  return a;
}

Argv CommandBuilder::bring_up(const std::string& dir) const {
  require(dir, "bring-up folder");
  Argv a = base();
  a.insert(a.end(), {"bring-up", "--dir", trim_copy(dir)});
  return a;
}

Argv CommandBuilder::shutdown() const {
  Argv a = base();
  a.push_back("shutdown");
  return a;
}

// ------------------------------------------------------------ output

std::optional<Progress> parse_progress(std::string_view line) {
  const std::string l = trim_copy(line);
  constexpr std::string_view kTag = "progress:";
  if (l.rfind(kTag, 0) != 0) return std::nullopt;
  std::string_view rest(l);
  rest.remove_prefix(kTag.size());
  while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
  Progress p;
  auto r = std::from_chars(rest.data(), rest.data() + rest.size(), p.index);
  if (r.ec != std::errc() || r.ptr == rest.data() + rest.size() || *r.ptr != '/') return std::nullopt;
  const char* c = r.ptr + 1;
  r = std::from_chars(c, rest.data() + rest.size(), p.count);
  if (r.ec != std::errc() || p.count <= 0 || p.index < 0 || p.index > p.count) return std::nullopt;
  p.text = trim_copy(std::string_view(r.ptr, static_cast<std::size_t>(rest.data() + rest.size() - r.ptr)));
  return p;
}

void OutputCollector::take_line(std::string line) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (auto p = parse_progress(line)) {
    progress_ = *p;
    fresh_.push_back(*p);
  } else {
    lines_.push_back(std::move(line));
  }
}

std::vector<Progress> OutputCollector::add_stdout(std::string_view chunk) {
  fresh_.clear();
  out_partial_.append(chunk);
  std::size_t start = 0, nl;
  while ((nl = out_partial_.find('\n', start)) != std::string::npos) {
    take_line(out_partial_.substr(start, nl - start));
    start = nl + 1;
  }
  out_partial_.erase(0, start);
  return std::move(fresh_);
}

void OutputCollector::add_stderr(std::string_view chunk) { err_.append(chunk); }

StepResult OutputCollector::finish(bool exited_normally, int exit_code, bool abort_requested) {
  if (!out_partial_.empty()) take_line(std::exchange(out_partial_, {}));
  StepResult r;
  r.lines = lines_;
  r.error = trim_copy(err_);
  r.last_progress = progress_;
  r.exit_code = exited_normally ? exit_code : -1;
  if (abort_requested && (!exited_normally || exit_code != 0)) r.outcome = StepResult::Outcome::Aborted;
  else if (!exited_normally) r.outcome = StepResult::Outcome::Crashed;
  else if (exit_code == 0) r.outcome = StepResult::Outcome::Done;
  else if (exit_code == 2) r.outcome = StepResult::Outcome::Usage;
  else if (exit_code == 1) r.outcome = StepResult::Outcome::Problem;
  else r.outcome = StepResult::Outcome::Crashed;
  return r;
}

const char* to_string(StepResult::Outcome o) noexcept {
  switch (o) {
    case StepResult::Outcome::Done: return "done";
    case StepResult::Outcome::Problem: return "problem";
    case StepResult::Outcome::Usage: return "refused";
    case StepResult::Outcome::Aborted: return "aborted";
    case StepResult::Outcome::Crashed: return "failed";
  }
  return "?";
}

std::string StepResult::summary() const {
  auto last_lines = [this](std::size_t n) {
    std::string s;
    for (std::size_t i = lines.size() > n ? lines.size() - n : 0; i < lines.size(); ++i) s += lines[i] + "\n";
    return trim_copy(s);
  };
  std::string why = error.empty() ? last_lines(3) : error;
  switch (outcome) {
    case Outcome::Done: return "done";
    case Outcome::Problem: return "problem (nothing saved): " + why;
    case Outcome::Usage:
      return "refused (status 2): " + why +
             "\n(the command line was not accepted: a subcommand this build of cnc-commission lacks, or an option)";
    case Outcome::Aborted: return "aborted; the machine is switched off" + (why.empty() ? "" : ": " + why);
    case Outcome::Crashed:
      return (exit_code < 0 ? std::string("ended by a signal or did not start") : "status " + std::to_string(exit_code)) +
             (why.empty() ? "" : ": " + why);
  }
  return why;
}

// ------------------------------------------------------------ hold-to-run

HoldToRun::Action HoldToRun::press() noexcept {
  if (running() || held_) return Action::None;
  held_ = true;
  starting_ = true;
  interrupted_ = false;
  return Action::Start;
}

HoldToRun::Action HoldToRun::release() noexcept {
  if (!held_) return Action::None;
  held_ = false;
  if (!running() || interrupted_) return Action::None;
  interrupted_ = true;
  return Action::Interrupt;
}

void HoldToRun::started() noexcept {
  starting_ = false;
  running_ = true;
}

void HoldToRun::finished() noexcept {
  starting_ = running_ = false;
}

// ------------------------------------------------------------ done steps

std::array<bool, kSteps> steps_done(const State& s, const std::string& state_json_text) {
  std::array<bool, kSteps> d{};
  d[0] = !s.nodes.empty() || !s.slaves.empty();
  d[1] = !s.axes.empty();
  bool any = false, scaled = true, tested = true;
  for (const auto& a : s.axes) {
    if (!a.enabled) continue;
    any = true;
    scaled = scaled && a.scaling.counts_per_mm() > 0;
    tested = tested && a.direction && a.direction->has_dial;
  }
  d[2] = any && scaled;
  d[3] = any && tested;
  // Steps 5-8: their results by key in each enabled axis' JSON object.
  nlohmann::json j;
  if (!state_json_text.empty()) j = nlohmann::json::parse(state_json_text, nullptr, false);
  const char* kKeys[4] = {"switches", "homing", "tuning", "compensation"};
  for (int k = 0; k < 4; ++k) {
    bool all = any && j.is_object() && j.contains("axes") && j["axes"].is_array();
    if (all) {
      for (const auto& a : j["axes"]) {
        if (a.is_object() && a.value("enabled", true) && (!a.contains(kKeys[k]) || a[kKeys[k]].is_null())) all = false;
      }
    }
    d[static_cast<std::size_t>(4 + k)] = all;
  }
  for (const auto& l : s.log)
    if (l.rfind("configuration written to ", 0) == 0) d[8] = true;
  return d;
}

std::array<bool, kSteps> steps_done(const std::filesystem::path& state_file) {
  const State s = load_state(state_file);
  std::string text;
  if (std::ifstream in{state_file}) {
    std::stringstream ss;
    ss << in.rdbuf();
    text = ss.str();
  }
  return steps_done(s, text);
}

// ------------------------------------------------------------ tune CSV

TuneTrace parse_tune_csv(const std::string& text, const std::string& origin) {
  TuneTrace t;
  std::vector<double>* cols[6] = {&t.time_s, &t.command_mm, &t.feedback_mm, &t.ferror_mm, &t.velocity_mm_s, &t.torque_pct};
  const char* names[6] = {"time_s", "command_mm", "feedback_mm", "ferror_mm", "velocity_mm_s", "torque_pct"};
  std::istringstream in(text);
  std::string line;
  int lineno = 0;
  std::vector<int> where(6, -1);
  std::size_t width = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++lineno;
    const std::string l = trim_copy(line);
    if (l.empty() || l[0] == '#') continue;
    const auto cells = split(l, ',');
    if (!header) {
      for (std::size_t c = 0; c < cells.size(); ++c)
        for (int k = 0; k < 6; ++k)
          if (trim_copy(cells[c]) == names[k]) where[static_cast<std::size_t>(k)] = static_cast<int>(c);
      for (int k = 0; k < 6; ++k)
        if (where[static_cast<std::size_t>(k)] < 0)
          throw std::invalid_argument(origin + ":" + std::to_string(lineno) + ": no column " + names[k] + " in the header");
      width = cells.size();
      header = true;
      continue;
    }
    if (cells.size() != width)
      throw std::invalid_argument(origin + ":" + std::to_string(lineno) + ": " + std::to_string(cells.size()) +
                                  " columns, the header has " + std::to_string(width));
    for (int k = 0; k < 6; ++k) {
      const std::string cell = trim_copy(cells[static_cast<std::size_t>(where[static_cast<std::size_t>(k)])]);
      double v = 0;
      const auto r = std::from_chars(cell.data(), cell.data() + cell.size(), v);
      if (r.ec != std::errc() || r.ptr != cell.data() + cell.size() || !std::isfinite(v))
        throw std::invalid_argument(origin + ":" + std::to_string(lineno) + ": " + names[k] + " \"" + cell +
                                    "\" is not a number");
      cols[k]->push_back(v);
    }
  }
  if (!header) throw std::invalid_argument(origin + ": empty (no header line)");
  return t;
}

TuneTrace load_tune_csv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::invalid_argument(file.string() + ": cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_tune_csv(ss.str(), file.string());
}

// ------------------------------------------------------------ homing methods

std::vector<HomingMethod> parse_homing_methods(const std::vector<std::string>& lines) {
  std::vector<HomingMethod> out;
  for (const auto& raw : lines) {
    const std::string l = trim_copy(raw);
    if (l.empty()) continue;
    const auto end = l.find_first_of(" \t:");
    std::string word = l.substr(0, end);
    std::string method;
    if (word == "controller") {
      method = word;
    } else if (word == "drive" && end != std::string::npos && l[end] == ':') {
      const auto e2 = l.find_first_of(" \t", end + 1);
      const std::string n = l.substr(end + 1, e2 == std::string::npos ? std::string::npos : e2 - end - 1);
      int v = 0;
      const auto r = std::from_chars(n.data(), n.data() + n.size(), v);
      if (r.ec == std::errc() && r.ptr == n.data() + n.size() && !n.empty()) method = "drive:" + n;
    } else {
      int v = 0;
      const auto r = std::from_chars(word.data(), word.data() + word.size(), v);
      if (r.ec == std::errc() && r.ptr == word.data() + word.size() && !word.empty()) method = "drive:" + word;
    }
    if (!method.empty()) out.push_back({method, l});
  }
  return out;
}

// ------------------------------------------------------------ status strip

StatusStrip status_strip(const ipc::Status& s) {
  StatusStrip r;
  r.estop_ok = s.io.estop_chain_ok && !s.motion.estop_latched;
  if (!s.io.estop_chain_ok) r.estop = "E-STOP: chain open";
  else if (s.motion.estop_latched) r.estop = std::string("E-STOP latched (") + ipc::to_string(s.motion.estop_cause) + ")";
  else r.estop = std::string("E-stop chain closed, machine ") + ipc::to_string(s.task.state);
  for (const auto& d : s.drives) {
    if (!d.present) continue;
    std::string t = (d.joint >= 0 ? "J" + std::to_string(d.joint) : std::string("spindle")) + " " +
                    cia402::to_string(static_cast<cia402::State>(d.state <= 8 ? d.state : 8));
    if (!d.fault_text.empty()) t += ": " + std::string(d.fault_text.c_str());
    r.drives.push_back(std::move(t));
  }
  const int n = s.motion.joints < kMaxJoints ? s.motion.joints : kMaxJoints;
  for (int j = 0; j < n; ++j) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "J%d %.3f", j, s.joints[j].pos_fb);
    r.joints.push_back(buf);
  }
  return r;
}

}  // namespace cnc::commission::wizard
