#include "connectivity/mqtt/bridge.hpp"

#include <nlohmann/json.hpp>

#include <stdexcept>

#include "core/ipc/operator_commands.hpp"

namespace cnc::mqtt {

using nlohmann::json;

namespace {

json axes_json(const Pose& p, uint32_t mask) {
  json j = json::object();
  for (int a = 0; a < kNumAxes; ++a) {
    if (mask & (1u << a)) j[std::string(1, kAxisLetters[a])] = p[a];
  }
  return j;
}

// Same length, every byte compared: the time does not tell how much of a
// guessed token was right.
bool same_secret(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

}  // namespace

std::string state_json(const ipc::Status& s) {
  json j;
  j["task_state"] = to_string(s.task.state);
  j["task_mode"] = to_string(s.task.mode);
  j["interp_state"] = to_string(s.task.interp_state);
  j["exec_state"] = to_string(s.task.exec_state);
  j["estop"] = s.task.state == ipc::TaskState::Estop;
  j["enabled"] = s.motion.enabled;
  j["paused"] = s.task.paused;
  j["file"] = s.task.file.c_str();
  j["tool_in_spindle"] = s.io.tool_in_spindle;
  j["feed_override"] = s.motion.feed_scale;
  j["rapid_override"] = s.motion.rapid_scale;
  j["spindle_override"] = s.spindles[0].override_scale;
  j["spindle_speed"] = s.spindles[0].speed_out;
  j["spindle_enabled"] = s.spindles[0].enabled;
  j["flood"] = s.io.flood;
  j["mist"] = s.io.mist;
  json homed = json::array();
  for (int i = 0; i < s.motion.joints && i < kMaxJoints; ++i) homed.push_back(s.joints[i].homed);
  j["homed"] = homed;
  return j.dump();
}

std::string position_json(const ipc::Status& s, uint32_t mask) {
  json j;
  j["position"] = axes_json(s.motion.position, mask);
  j["actual_position"] = axes_json(s.motion.actual_position, mask);
  j["velocity"] = s.motion.current_vel;
  j["line"] = s.task.current_line;
  return j.dump();
}

std::string message_json(const Message& m) {
  json j;
  j["kind"] = cnc::to_string(m.kind);
  j["source"] = m.source.c_str();
  j["text"] = m.text.c_str();
  j["time"] = static_cast<double>(m.time_ns) * 1e-9;
  return j.dump();
}

std::vector<std::string> program_events(const ipc::Status* before, const ipc::Status& now) {
  std::vector<std::string> out;
  auto event = [&](const char* name) {
    json j;
    j["event"] = name;
    j["file"] = now.task.file.c_str();
    j["line"] = now.task.current_line;
    j["elapsed"] = static_cast<double>(now.task.program_elapsed_ns) * 1e-9;
    j["errors"] = now.task.errors_since_start;
    out.push_back(j.dump());
  };
  if (!before) return out;
  if (std::string_view(before->task.file.c_str()) != std::string_view(now.task.file.c_str()) && !now.task.file.empty()) {
    event("opened");
  }
  // A program runs in auto mode: MDI lines are not program events.
  const bool was_running = before->task.interp_state != ipc::InterpState::Idle && before->task.mode == ipc::TaskMode::Auto;
  const bool running = now.task.interp_state != ipc::InterpState::Idle && now.task.mode == ipc::TaskMode::Auto;
  if (!was_running && running) event("started");
  if (was_running && running && !before->task.paused && now.task.paused) event("paused");
  if (was_running && running && before->task.paused && !now.task.paused) event("resumed");
  if (was_running && !running) event("finished");
  return out;
}

const std::vector<std::string>& command_names() {
  static const std::vector<std::string> names = {
      "estop", "estop-reset", "on", "off", "mode", "home", "unhome", "mdi", "open", "run", "pause", "resume",
      "step", "abort", "feed-override", "rapid-override", "spindle-override", "spindle", "flood", "mist"};
  return names;
}

CommandRequest parse_command(const std::string& payload, const std::string& token,
                             const std::set<std::string>& allowed) {
  namespace c = ipc::commands;
  json j;
  try {
    j = json::parse(payload);
  } catch (const std::exception& e) {
    throw std::invalid_argument(std::string("not JSON: ") + e.what());
  }
  if (!j.is_object()) throw std::invalid_argument("expected a JSON object");
  CommandRequest r;
  if (j.contains("id")) r.id = j["id"].is_string() ? j["id"].get<std::string>() : j["id"].dump();
  if (token.empty() || !j.contains("token") || !j["token"].is_string() || !same_secret(j["token"].get<std::string>(), token)) {
    throw std::invalid_argument("not authorised (wrong or missing token)");
  }
  if (!j.contains("command") || !j["command"].is_string()) throw std::invalid_argument("no \"command\"");
  r.name = j["command"].get<std::string>();
  if (!allowed.count(r.name)) throw std::invalid_argument("command \"" + r.name + "\" is not in the whitelist");
  const json args = j.value("args", json::array());
  if (!args.is_array()) throw std::invalid_argument("\"args\" must be an array");
  auto num = [&](std::size_t i) -> double {
    if (i >= args.size() || !args[i].is_number()) {
      throw std::invalid_argument(r.name + ": argument " + std::to_string(i + 1) + " must be a number");
    }
    return args[i].get<double>();
  };
  auto str = [&](std::size_t i) -> std::string {
    if (i >= args.size() || !args[i].is_string()) {
      throw std::invalid_argument(r.name + ": argument " + std::to_string(i + 1) + " must be a string");
    }
    return args[i].get<std::string>();
  };
  const std::string& n = r.name;
  if (n == "estop") {
    r.command = c::set_state(ipc::TaskState::Estop);
    r.estop = true;
  } else if (n == "estop-reset") r.command = c::set_state(ipc::TaskState::EstopReset);
  else if (n == "on") r.command = c::set_state(ipc::TaskState::On);
  else if (n == "off") r.command = c::set_state(ipc::TaskState::Off);
  else if (n == "mode") {
    const std::string m = str(0);
    if (m == "manual") r.command = c::set_mode(ipc::TaskMode::Manual);
    else if (m == "auto") r.command = c::set_mode(ipc::TaskMode::Auto);
    else if (m == "mdi") r.command = c::set_mode(ipc::TaskMode::Mdi);
    else throw std::invalid_argument("mode: expected manual, auto or mdi");
  } else if (n == "home" || n == "unhome") {
    const int joint = args.empty() ? -1 : static_cast<int>(num(0));
    if (joint < -1 || joint >= kMaxJoints) throw std::invalid_argument(n + ": joint out of range");
    r.command = n == "home" ? c::home(joint) : c::unhome(joint);
  } else if (n == "mdi") r.command = c::mdi(str(0));
  else if (n == "open") {
    const std::string path = str(0);
    if (path.empty() || path[0] != '/') throw std::invalid_argument("open: the path must be absolute");
    r.command = c::open(path);
  } else if (n == "run") r.command = c::run(args.empty() ? 0 : static_cast<int>(num(0)));
  else if (n == "pause") r.command = c::pause();
  else if (n == "resume") r.command = c::resume();
  else if (n == "step") r.command = c::step();
  else if (n == "abort") r.command = c::abort();
  else if (n == "feed-override") r.command = c::feed_override(num(0) / 100);
  else if (n == "rapid-override") r.command = c::rapid_override(num(0) / 100);
  else if (n == "spindle-override") r.command = c::spindle_override(num(0) / 100);
  else if (n == "spindle") {
    const double rpm = num(0);
    r.command = rpm == 0 ? c::spindle_off() : c::spindle_on(rpm);
  } else if (n == "flood") r.command = c::flood(num(0) != 0);
  else if (n == "mist") r.command = c::mist(num(0) != 0);
  else throw std::invalid_argument("unknown command \"" + n + "\"");
  return r;
}

}  // namespace cnc::mqtt
