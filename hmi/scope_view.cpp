#include "hmi/scope_view.hpp"

#include <stdexcept>

#include "core/util/strings.hpp"

namespace cnc::hmi::scope {

const char* to_string(Edge e) {
  switch (e) {
    case Edge::Rising: return "rising";
    case Edge::Falling: return "falling";
    case Edge::Level: return "level";
    case Edge::None: return "none";
  }
  return "?";
}

const char* to_string(Mode m) {
  switch (m) {
    case Mode::Single: return "single";
    case Mode::Normal: return "normal";
    case Mode::Auto: return "auto";
  }
  return "?";
}

std::vector<std::string> split_pins(std::string_view text) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : text) {
    if (c == ',' || c == ' ' || c == '\t' || c == '\n') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

namespace {
void check_name(const std::string& n, const char* what) {
  if (n.empty()) throw std::invalid_argument(std::string(what) + ": empty name");
  for (char c : n) {
    if (c == ',' || c == '=' || c == ' ' || c == '\t' || c == '"' || c == '#' || c == '\n') {
      throw std::invalid_argument(std::string(what) + " \"" + n + "\": a pin name has no '" + std::string(1, c) + "'");
    }
  }
}
std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}
}  // namespace

std::string setup_line(const Settings& s) {
  if (s.pins.empty()) throw std::invalid_argument("pins: give at least one pin");
  std::vector<std::string> all = s.pins;
  for (const auto& p : s.pins) check_name(p, "pins");
  if (!s.trigger.empty()) {
    check_name(s.trigger, "trigger");
    bool in = false;
    for (const auto& p : s.pins) in = in || p == s.trigger;
    if (!in) all.push_back(s.trigger);
  }
  if (all.size() > 16) {
    throw std::invalid_argument("pins: " + std::to_string(all.size()) + " channels (with the trigger); the scope records at most 16");
  }
  if (s.pre_percent < 0 || s.pre_percent > 100) throw std::invalid_argument("pre-trigger: 0 to 100 %");
  if (s.samples == 1 || s.samples < 0) throw std::invalid_argument("samples: at least 2 (0: the buffer's size)");
  std::string line = "scope setup ";
  for (std::size_t i = 0; i < s.pins.size(); ++i) line += (i ? "," : "") + s.pins[i];
  if (!s.trigger.empty()) {
    line += " trigger=" + s.trigger + " edge=" + to_string(s.edge) + " level=" + number(s.level);
  }
  line += " pre=" + std::to_string(s.pre_percent);
  if (s.samples > 0) line += " samples=" + std::to_string(s.samples);
  line += std::string(" mode=") + to_string(s.mode);
  return line;
}

State parse_state(std::string_view text) {
  State st;
  const auto words = split_pins(trim(text));
  if (words.empty()) throw std::invalid_argument("scope state: empty answer");
  st.name = words[0];
  if (st.name != "idle" && st.name != "filling" && st.name != "waiting" && st.name != "triggered" && st.name != "done") {
    throw std::invalid_argument("scope state: \"" + std::string(trim(text)) + "\" is not a state");
  }
  for (std::size_t i = 1; i < words.size(); ++i) {
    const auto eq = words[i].find('=');
    if (words[i] == "forced") {
      st.forced = true;
      continue;
    }
    if (eq == std::string::npos) continue;
    const auto v = parse_int(words[i].substr(eq + 1));
    if (!v) continue;
    const std::string k = words[i].substr(0, eq);
    if (k == "samples") st.samples = static_cast<int>(*v);
    else if (k == "pre") st.pre = static_cast<int>(*v);
    else if (k == "channels") st.channels = static_cast<int>(*v);
  }
  return st;
}

Capture parse_csv(std::string text) {
  Capture c;
  const auto lines = split(text, '\n', true);
  if (lines.empty() || lines[0].rfind("time_s", 0) != 0) {
    throw std::invalid_argument("scope csv: line 1: expected the header time_s,PIN,...");
  }
  const auto head = split(lines[0], ',', false);
  c.names.assign(head.begin() + 1, head.end());
  c.columns.resize(c.names.size());
  for (std::size_t i = 1; i < lines.size(); ++i) {
    if (trim(lines[i]).empty()) continue;
    const auto cells = split(lines[i], ',', false);
    if (cells.size() != head.size()) {
      throw std::invalid_argument("scope csv: line " + std::to_string(i + 1) + ": " + std::to_string(cells.size()) +
                                  " values, expected " + std::to_string(head.size()));
    }
    for (std::size_t k = 0; k < cells.size(); ++k) {
      const auto v = parse_double(trim(cells[k]));
      if (!v) throw std::invalid_argument("scope csv: line " + std::to_string(i + 1) + ": \"" + cells[k] + "\" is not a number");
      if (k == 0) c.time.push_back(*v);
      else c.columns[k - 1].push_back(*v);
    }
  }
  c.csv = std::move(text);
  return c;
}

}  // namespace cnc::hmi::scope
