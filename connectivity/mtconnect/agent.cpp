#include "connectivity/mtconnect/agent.hpp"

#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>

namespace cnc::mtconnect {

namespace {

constexpr const char* kUnavailable = "UNAVAILABLE";

std::string number(double v, const char* fmt = "%.4f") {
  if (!std::isfinite(v)) return kUnavailable;
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  if (std::string(buf) == "-0.0000") return "0.0000";
  return buf;
}

const char* category_name(Category c) {
  switch (c) {
    case Category::Sample: return "SAMPLE";
    case Category::Event: return "EVENT";
    case Category::Condition: return "CONDITION";
  }
  return "EVENT";
}

// MTConnect's EXECUTION from the task's state.
std::string execution_of(const ipc::Status& s) {
  if (s.task.state != ipc::TaskState::On) return "STOPPED";
  if (s.task.paused || s.task.interp_state == ipc::InterpState::Paused) return "INTERRUPTED";
  if (s.task.interp_state == ipc::InterpState::Idle) return "READY";
  return "ACTIVE";
}

std::string mode_of(const ipc::Status& s) {
  switch (s.task.mode) {
    case ipc::TaskMode::Auto: return "AUTOMATIC";
    case ipc::TaskMode::Mdi: return "MANUAL_DATA_INPUT";
    case ipc::TaskMode::Manual: return "MANUAL";
  }
  return kUnavailable;
}

}  // namespace

std::string xml_escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default:
        // Control characters are not allowed in XML 1.0.
        if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') out += ' ';
        else out += c;
    }
  }
  return out;
}

std::string iso_time(int64_t ns) {
  const time_t secs = static_cast<time_t>(ns / 1'000'000'000);
  tm utc{};
  gmtime_r(&secs, &utc);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%06dZ", utc.tm_year + 1900, utc.tm_mon + 1,
                utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, static_cast<int>((ns / 1000) % 1'000'000));
  return buf;
}

Agent::Agent(AgentOptions options) : options_(std::move(options)) {
  instance_id_ = static_cast<uint64_t>(std::time(nullptr));
  for (int a = 0; a < kNumAxes; ++a) position_[a] = load_[a] = -1;
  avail_ = add_item({"avail", Category::Event, "AVAILABILITY", "Availability", "", "", "", -1});
  const int ctrl = add_component("Controller", "ctrl", "controller", -1);
  estop_ = add_item({"estop", Category::Event, "EMERGENCY_STOP", "EmergencyStop", "", "", "", ctrl});
  mode_ = add_item({"mode", Category::Event, "CONTROLLER_MODE", "ControllerMode", "", "", "", ctrl});
  system_ = add_item({"system", Category::Condition, "SYSTEM", "", "", "", "", ctrl});
  const int path = add_component("Path", "path1", "path", ctrl);
  execution_ = add_item({"execution", Category::Event, "EXECUTION", "Execution", "", "", "", path});
  program_ = add_item({"program", Category::Event, "PROGRAM", "Program", "", "", "", path});
  line_ = add_item({"line", Category::Event, "LINE", "Line", "", "", "", path});
  tool_ = add_item({"tool", Category::Event, "TOOL_NUMBER", "ToolNumber", "", "", "", path});
  feed_ovr_ = add_item({"feed_ovr", Category::Event, "PATH_FEEDRATE_OVERRIDE", "PathFeedrateOverride", "PROGRAMMED",
                        "", "", path});
  rapid_ovr_ = add_item({"rapid_ovr", Category::Event, "PATH_FEEDRATE_OVERRIDE", "PathFeedrateOverride", "RAPID", "",
                         "", path});
  message_ = add_item({"message", Category::Event, "MESSAGE", "Message", "", "", "", path});
  feedrate_ = add_item({"path_feedrate", Category::Sample, "PATH_FEEDRATE", "PathFeedrate", "ACTUAL",
                        "MILLIMETER/SECOND", "", path});
  logic_ = add_item({"logic", Category::Condition, "LOGIC_PROGRAM", "", "", "", "", path});
  const int axes = add_component("Axes", "axes", "axes", -1);
  for (int a = 0; a < kNumAxes; ++a) {
    if (!(options_.axis_mask & (1u << a))) continue;
    const bool rotary = a >= 3 && a <= 5;
    const std::string letter(1, kAxisLetters[a]);
    const std::string lower(1, static_cast<char>(kAxisLetters[a] - 'A' + 'a'));
    const int c = add_component(rotary ? "Rotary" : "Linear", lower + "_axis", letter, axes);
    position_[a] = add_item({lower + "_pos", Category::Sample, rotary ? "ANGLE" : "POSITION",
                             rotary ? "Angle" : "Position", "ACTUAL", rotary ? "DEGREE" : "MILLIMETER",
                             "MACHINE", c});
    load_[a] = add_item({lower + "_load", Category::Sample, "LOAD", "Load", "", "PERCENT", "", c});
  }
  const int spindle = add_component("Rotary", "spindle", "S", axes);
  spindle_speed_ = add_item({"s_speed", Category::Sample, "ROTARY_VELOCITY", "RotaryVelocity", "ACTUAL",
                             "REVOLUTION/MINUTE", "", spindle});
  spindle_cmd_ = add_item({"s_speed_cmd", Category::Sample, "ROTARY_VELOCITY", "RotaryVelocity", "COMMANDED",
                           "REVOLUTION/MINUTE", "", spindle});
  spindle_load_ = add_item({"s_load", Category::Sample, "LOAD", "Load", "", "PERCENT", "", spindle});
  spindle_ovr_ = add_item({"s_ovr", Category::Event, "ROTARY_VELOCITY_OVERRIDE", "RotaryVelocityOverride", "", "",
                           "", spindle});
  // Everything starts unavailable (sequence 1..n), as an agent without its
  // adapter.
  update(nullptr, 0);
}

int Agent::add_component(std::string element, std::string id, std::string name, int parent) {
  components_.push_back({std::move(element), std::move(id), std::move(name), parent});
  return static_cast<int>(components_.size()) - 1;
}

int Agent::add_item(DataItem item) {
  items_.push_back(std::move(item));
  latest_.push_back({});
  return static_cast<int>(items_.size()) - 1;
}

void Agent::set(int item, const std::string& value, int64_t now_ns) {
  if (item < 0) return;
  Observation& last = latest_[static_cast<std::size_t>(item)];
  if (last.sequence != 0 && last.value == value) return;
  Observation o;
  o.sequence = next_seq_++;
  o.time_ns = now_ns;
  o.item = item;
  o.value = value;
  last = o;
  buffer_.push_back(o);
  while (buffer_.size() > options_.buffer_size) buffer_.pop_front();
}

void Agent::set_condition(int item, const std::string& level, const std::string& text, const std::string& code,
                          int64_t now_ns) {
  Observation& last = latest_[static_cast<std::size_t>(item)];
  if (last.sequence != 0 && last.level == level && last.value == text && last.native_code == code) return;
  Observation o;
  o.sequence = next_seq_++;
  o.time_ns = now_ns;
  o.item = item;
  o.level = level;
  o.value = text;
  o.native_code = code;
  last = o;
  buffer_.push_back(o);
  while (buffer_.size() > options_.buffer_size) buffer_.pop_front();
}

void Agent::update(const ipc::Status* s, int64_t now_ns) {
  if (now_ns == 0) now_ns = 1;
  if (!s) {
    for (int i = 0; i < static_cast<int>(items_.size()); ++i) {
      if (items_[static_cast<std::size_t>(i)].category == Category::Condition) {
        set_condition(i, "Unavailable", "", "", now_ns);
      } else {
        set(i, kUnavailable, now_ns);
      }
    }
    last_task_state_ = 0;
    return;
  }
  set(avail_, "AVAILABLE", now_ns);
  const int state = static_cast<int>(s->task.state);
  set(estop_, s->task.state == ipc::TaskState::Estop ? "TRIGGERED" : "ARMED", now_ns);
  set(mode_, mode_of(*s), now_ns);
  // Faults stand until the operator resets the E-stop or turns the machine
  // on; a program start clears the program's (LOGIC_PROGRAM) condition.
  const bool cleared = last_task_state_ == 0 || (state != last_task_state_ && (s->task.state == ipc::TaskState::EstopReset ||
                                                                              s->task.state == ipc::TaskState::On));
  if (cleared) {
    set_condition(system_, "Normal", "", "", now_ns);
    set_condition(logic_, "Normal", "", "", now_ns);
  }
  const std::string exec = execution_of(*s);
  if (exec == "ACTIVE" && latest_[static_cast<std::size_t>(execution_)].value == "READY") {
    set_condition(logic_, "Normal", "", "", now_ns);
  }
  last_task_state_ = state;
  set(execution_, exec, now_ns);
  set(program_, s->task.file.empty() ? std::string(kUnavailable) : std::string(s->task.file.c_str()), now_ns);
  set(line_, std::to_string(s->task.current_line), now_ns);
  set(tool_, std::to_string(s->io.tool_in_spindle), now_ns);
  set(feed_ovr_, number(s->motion.feed_scale * 100, "%.0f"), now_ns);
  set(rapid_ovr_, number(s->motion.rapid_scale * 100, "%.0f"), now_ns);
  // Machine units are mm (linear_units: machine units per mm).
  const double per_mm = s->motion.linear_units > 0 ? s->motion.linear_units : 1;
  set(feedrate_, number(s->motion.current_vel / per_mm), now_ns);
  for (int a = 0; a < kNumAxes; ++a) {
    if (position_[a] < 0) continue;
    const bool rotary = a >= 3 && a <= 5;
    set(position_[a], number(rotary ? s->motion.actual_position[a] : s->motion.actual_position[a] / per_mm), now_ns);
    // Load: the torque of the drive of the joint that moves this axis.
    std::string load = kUnavailable;
    for (const ipc::DriveStatus& d : s->drives) {
      if (!d.present || d.joint < 0 || d.joint >= kMaxJoints) continue;
      if (s->joints[d.joint].axis == a) load = number(std::fabs(d.torque_percent), "%.1f");
    }
    set(load_[a], load, now_ns);
  }
  const ipc::SpindleStatus& sp = s->spindles[0];
  set(spindle_speed_, number(sp.speed_feedback, "%.1f"), now_ns);
  set(spindle_cmd_, number(sp.speed_out, "%.1f"), now_ns);
  const ipc::DriveStatus& sd = s->drives[kMaxJoints];  // the spindle's drive
  set(spindle_load_, sd.present ? number(std::fabs(sd.torque_percent), "%.1f") : std::string(kUnavailable), now_ns);
  set(spindle_ovr_, number(sp.override_scale * 100, "%.0f"), now_ns);
}

void Agent::message(const Message& m, int64_t now_ns) {
  const std::string source = m.source.c_str();
  const std::string text = m.text.c_str();
  if (m.kind == MessageKind::Error) {
    set_condition(source == "interp" ? logic_ : system_, "Fault", text, source, now_ns);
  } else {
    set(message_, text, now_ns);
  }
}

std::string Agent::header(const char* kind, int64_t now_ns) const {
  std::string h = "<Header creationTime=\"" + iso_time(now_ns) + "\" sender=\"" + xml_escape(options_.sender) +
                  "\" instanceId=\"" + std::to_string(instance_id_) + "\" version=\"" + kVersion + "\"";
  // The asset document's header has no bufferSize (MTConnectAssets_1.3).
  if (std::string(kind) != "Assets") h += " bufferSize=\"" + std::to_string(options_.buffer_size) + "\"";
  if (std::string(kind) == "Streams") {
    const uint64_t first = first_sequence();
    h += " nextSequence=\"" + std::to_string(next_seq_) + "\" firstSequence=\"" + std::to_string(first) +
         "\" lastSequence=\"" + std::to_string(next_seq_ - 1) + "\"";
  } else if (std::string(kind) == "Devices") {
    h += " assetBufferSize=\"1024\" assetCount=\"0\"";
  } else if (std::string(kind) == "Assets") {
    h += " assetBufferSize=\"1024\" assetCount=\"0\"";
  }
  return h + "/>";
}

namespace {
std::string open_doc(const char* kind) {
  const std::string ns = std::string("urn:mtconnect.org:MTConnect") + kind + ":1.3";
  return std::string("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<MTConnect") + kind + " xmlns=\"" + ns +
         "\" xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xsi:schemaLocation=\"" + ns +
         " http://schemas.mtconnect.org/schemas/MTConnect" + kind + "_1.3.xsd\">\n";
}
}  // namespace

std::string Agent::probe(int64_t now_ns) const {
  std::string x = open_doc("Devices") + header("Devices", now_ns) + "\n<Devices>\n<Device id=\"dev\" name=\"" +
                  xml_escape(options_.device_name) + "\" uuid=\"" + xml_escape(options_.uuid) + "\">\n" +
                  "<Description manufacturer=\"cnc\">CNC controller (LinuxCNC architecture)</Description>\n";
  auto data_items = [&](int component) {
    std::string d;
    for (const DataItem& it : items_) {
      if (it.component != component) continue;
      d += "<DataItem id=\"" + it.id + "\" category=\"" + category_name(it.category) + "\" type=\"" + it.type + "\"";
      if (!it.sub_type.empty()) d += " subType=\"" + it.sub_type + "\"";
      if (!it.units.empty()) d += " units=\"" + it.units + "\" nativeUnits=\"" + it.units + "\"";
      if (!it.coordinate_system.empty()) d += " coordinateSystem=\"" + it.coordinate_system + "\"";
      d += "/>\n";
    }
    return d.empty() ? d : "<DataItems>\n" + d + "</DataItems>\n";
  };
  std::function<std::string(int)> children = [&](int parent) {
    std::string c;
    for (int i = 0; i < static_cast<int>(components_.size()); ++i) {
      const Component& k = components_[static_cast<std::size_t>(i)];
      if (k.parent != parent) continue;
      c += "<" + k.element + " id=\"" + k.id + "\" name=\"" + xml_escape(k.name) + "\">\n" + data_items(i) +
           children(i) + "</" + k.element + ">\n";
    }
    return c.empty() ? c : "<Components>\n" + c + "</Components>\n";
  };
  x += data_items(-1) + children(-1) + "</Device>\n</Devices>\n</MTConnectDevices>\n";
  return x;
}

std::string Agent::observation_xml(const Observation& o) const {
  const DataItem& it = items_[static_cast<std::size_t>(o.item)];
  const std::string common = " dataItemId=\"" + it.id + "\" timestamp=\"" + iso_time(o.time_ns) + "\" sequence=\"" +
                             std::to_string(o.sequence) + "\"";
  if (it.category == Category::Condition) {
    std::string x = "<" + o.level + common + " type=\"" + it.type + "\"";
    if (!o.native_code.empty()) x += " nativeCode=\"" + xml_escape(o.native_code) + "\"";
    return o.value.empty() ? x + "/>\n" : x + ">" + xml_escape(o.value) + "</" + o.level + ">\n";
  }
  std::string x = "<" + it.element + common;
  if (!it.sub_type.empty()) x += " subType=\"" + it.sub_type + "\"";
  return x + ">" + xml_escape(o.value) + "</" + it.element + ">\n";
}

std::string Agent::streams(const std::vector<const Observation*>& obs, int64_t now_ns) const {
  std::string x = open_doc("Streams") + header("Streams", now_ns) + "\n<Streams>\n<DeviceStream name=\"" +
                  xml_escape(options_.device_name) + "\" uuid=\"" + xml_escape(options_.uuid) + "\">\n";
  // One ComponentStream per component (the device is -1), its samples,
  // events and conditions in sequence order.
  for (int c = -1; c < static_cast<int>(components_.size()); ++c) {
    std::string samples, events, conditions;
    for (const Observation* o : obs) {
      const DataItem& it = items_[static_cast<std::size_t>(o->item)];
      if (it.component != c) continue;
      (it.category == Category::Sample ? samples : it.category == Category::Event ? events : conditions) +=
          observation_xml(*o);
    }
    if (samples.empty() && events.empty() && conditions.empty()) continue;
    const std::string element = c < 0 ? "Device" : components_[static_cast<std::size_t>(c)].element;
    const std::string id = c < 0 ? "dev" : components_[static_cast<std::size_t>(c)].id;
    const std::string name = c < 0 ? options_.device_name : components_[static_cast<std::size_t>(c)].name;
    x += "<ComponentStream component=\"" + element + "\" name=\"" + xml_escape(name) + "\" componentId=\"" + id +
         "\">\n";
    if (!samples.empty()) x += "<Samples>\n" + samples + "</Samples>\n";
    if (!events.empty()) x += "<Events>\n" + events + "</Events>\n";
    if (!conditions.empty()) x += "<Condition>\n" + conditions + "</Condition>\n";
    x += "</ComponentStream>\n";
  }
  return x + "</DeviceStream>\n</Streams>\n</MTConnectStreams>\n";
}

std::string Agent::current(int64_t now_ns) const {
  std::vector<const Observation*> obs;
  for (const Observation& o : latest_) obs.push_back(&o);
  return streams(obs, now_ns);
}

std::string Agent::sample(uint64_t from, uint64_t count, int64_t now_ns, int& http_status) const {
  const uint64_t first = first_sequence();
  if (from == 0) from = first;
  if (from < first || from > next_seq_) {
    http_status = 400;
    return error("OUT_OF_RANGE",
                 "'from' must be between " + std::to_string(first) + " and " + std::to_string(next_seq_), now_ns);
  }
  if (count == 0 || count > options_.buffer_size) {
    http_status = 400;
    return error("OUT_OF_RANGE", "'count' must be between 1 and " + std::to_string(options_.buffer_size), now_ns);
  }
  http_status = 200;
  std::vector<const Observation*> obs;
  for (const Observation& o : buffer_) {
    if (o.sequence < from) continue;
    if (obs.size() >= count) break;
    obs.push_back(&o);
  }
  std::string x = streams(obs, now_ns);
  // nextSequence of a sample: the one after the last returned.
  if (!obs.empty() && obs.back()->sequence + 1 != next_seq_) {
    const std::string want = "nextSequence=\"" + std::to_string(next_seq_) + "\"";
    const auto at = x.find(want);
    if (at != std::string::npos) {
      x.replace(at, want.size(), "nextSequence=\"" + std::to_string(obs.back()->sequence + 1) + "\"");
    }
  }
  return x;
}

std::string Agent::assets(int64_t now_ns) const {
  return open_doc("Assets") + header("Assets", now_ns) + "\n<Assets/>\n</MTConnectAssets>\n";
}

std::string Agent::error(const std::string& code, const std::string& text, int64_t now_ns) const {
  return open_doc("Error") + header("Error", now_ns) + "\n<Errors>\n<Error errorCode=\"" + code + "\">" +
         xml_escape(text) + "</Error>\n</Errors>\n</MTConnectError>\n";
}

}  // namespace cnc::mtconnect
