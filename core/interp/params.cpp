// Numbered and named parameters: LinuxCNC's numbering (5061 probe, 5161
// G28, 5181 G30, 5211 G92, 5220-5390 coordinate systems, 5399 M66, 5400
// tool, 5420 position), predefined read-only names, and the parameter file.
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

#include "core/interp/impl.hpp"

namespace cnc::interp {

namespace {
bool is_readonly(int index) { return (index >= 5399 && index <= 5413) || (index >= 5420 && index <= 5428); }

bool required_persistent(int index) {
  if (index >= 5161 && index <= 5169) return true;
  if (index >= 5181 && index <= 5189) return true;
  if (index >= 5210 && index <= 5220) return true;
  if (index >= 5221 && index <= 5390) {
    const int k = (index - 5221) % 20;
    return k <= 9;
  }
  return false;
}
}  // namespace

void Interpreter::State::init_parameters() {
  params.assign(kMaxParameters, 0.0);
  persistent.assign(kMaxParameters, false);
  for (int i = 1; i < kMaxParameters; ++i) persistent[static_cast<std::size_t>(i)] = required_persistent(i);
  params[5220] = 1.0;
  globals.clear();
  // The value of the last subroutine return: 0 until a subroutine returns.
  globals["_value"] = 0.0;
  globals["_value_returned"] = 0.0;
}

void Interpreter::State::load_parameter_file() {
  if (config.parameter_file.empty()) return;
  const std::string file = config.parameter_file.string();
  std::error_code ec;
  const auto dir = config.parameter_file.has_parent_path() ? config.parameter_file.parent_path()
                                                            : std::filesystem::path(".");
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InterpError("the folder of the parameter file does not exist (" + dir.string() +
                          "): the parameters could never be saved",
                      file, 0, "");
  }
  // Temporary files of a save that a kill interrupted.
  cnc::remove_stale_temporaries(config.parameter_file);
  if (!std::filesystem::exists(config.parameter_file, ec)) return;  // starts from zeros; created on save
  // A regular file only (a FIFO would block, /dev/zero never end), read
  // line by line with the interpreter's line length limit.
  std::unique_ptr<LineReader> reader;
  try {
    reader = std::make_unique<LineReader>(file);
  } catch (const InterpError& e) {
    throw InterpError("Unable to open parameter file: " + e.message(), file, 0, "");
  }
  std::string_view line;
  int last = 0;
  while (reader->next(line)) {
    const int line_no = reader->line_number();
    const std::string_view t = cnc::trim(line);
    if (t.empty() || t[0] == '#' || t[0] == ';') continue;
    const auto words = cnc::split_blanks(t);
    const auto index = cnc::parse_int(words[0]);
    const auto value = words.size() >= 2 ? cnc::parse_double(words[1]) : std::nullopt;
    if (!index || !value || words.size() > 2) {
      throw InterpError("Bad line in parameter file, expected '<number> <value>'", file, line_no, std::string(line));
    }
    if (*index < 1 || *index >= kMaxParameters) {
      throw InterpError("Parameter number out of range", file, line_no, std::string(line));
    }
    if (*index <= last) throw InterpError("Parameter file out of order", file, line_no, std::string(line));
    last = static_cast<int>(*index);
    params[static_cast<std::size_t>(*index)] = *value;
    persistent[static_cast<std::size_t>(*index)] = true;
  }
  saved_parameters_ = parameter_text();
}

std::string Interpreter::State::parameter_text() const {
  std::string out;
  char buf[64];
  for (int i = 1; i < kMaxParameters; ++i) {
    if (!persistent[static_cast<std::size_t>(i)]) continue;
    std::snprintf(buf, sizeof buf, "%d\t%.6f\n", i, params[static_cast<std::size_t>(i)]);
    out += buf;
  }
  return out;
}

void Interpreter::State::save_parameter_file() const {
  if (config.parameter_file.empty()) return;
  std::string out = parameter_text();
  if (out == saved_parameters_) return;  // nothing changed: no write, no fsync
  cnc::write_file_atomically(config.parameter_file, out);
  saved_parameters_ = std::move(out);
}

double Interpreter::State::get_param(int index) const {
  if (index >= 5400 && index <= 5413) {
    const ToolData& t = tools.spindle();
    if (index == 5400) return t.is_empty() ? 0.0 : t.number;
    // As LinuxCNC: tool table values, in machine units.
    if (index <= 5409) return t.offset[index - 5401];
    if (index == 5410) return t.diameter;
    if (index == 5411) return t.front_angle;
    if (index == 5412) return t.back_angle;
    return t.orientation;
  }
  if (index >= 5420 && index <= 5428) return pos[index - 5420];
  return params[static_cast<std::size_t>(index)];
}

void Interpreter::State::set_param(int index, double value, bool check_readonly) {
  if (check_readonly && is_readonly(index)) fail("Parameter is readonly");
  params[static_cast<std::size_t>(index)] = value;
}

bool Interpreter::State::predefined(const std::string& name, double& v) const {
  if (name.size() < 2 || name[0] != '_') return false;
  const std::string_view n(name);
  auto b = [&](bool x) {
    v = x ? 1.0 : 0.0;
    return true;
  };
  if (n.size() == 2) {
    const int axis = axis_index(n[1]);
    if (axis >= 0) {
      v = pos[axis];
      return true;
    }
  }
  if (n.starts_with("_abs_") && n.size() == 6) {
    const int axis = axis_index(n[5]);
    if (axis >= 0) {
      v = program_to_machine(pos)[axis];  // through G92, rotation, origin and tool
      return true;
    }
  }
  if (n == "_metric") return b(units != Units::Inch);
  if (n == "_imperial") return b(units == Units::Inch);
  if (n == "_absolute") return b(absolute);
  if (n == "_incremental") return b(!absolute);
  if (n == "_inverse_time") return b(feed_mode == FeedMode::InverseTime);
  if (n == "_units_per_minute") return b(feed_mode == FeedMode::UnitsPerMinute);
  if (n == "_units_per_rev") return b(feed_mode == FeedMode::UnitsPerRev);
  if (n == "_coord_system") {
    static constexpr int codes[] = {540, 550, 560, 570, 580, 590, 591, 592, 593};
    v = codes[origin - 1];
    return true;
  }
  if (n == "_tool_offset") return b(tool_offset_g != 490);
  if (n == "_retract_r_plane") return b(!retract_old_z);
  if (n == "_retract_old_z") return b(retract_old_z);
  if (n == "_spindle_rpm_mode") return b(!css);
  if (n == "_spindle_css_mode") return b(css);
  if (n == "_ijk_absolute_mode") return b(ijk_absolute);
  if (n == "_lathe_diameter_mode") return b(diameter_mode);
  if (n == "_lathe_radius_mode") return b(!diameter_mode);
  if (n == "_spindle_on") return b(spindle != Direction::Stopped);
  if (n == "_spindle_cw") return b(spindle == Direction::Clockwise);
  if (n == "_mist") return b(mist);
  if (n == "_flood") return b(flood);
  if (n == "_speed_override") return b(speed_override);
  if (n == "_feed_override") return b(feed_override);
  if (n == "_adaptive_feed") return b(adaptive);
  if (n == "_feed_hold") return b(feed_hold);
  if (n == "_feed") {
    v = feed;
    return true;
  }
  if (n == "_rpm") {
    v = speed;
    return true;
  }
  if (n == "_current_tool") {
    v = tools.spindle().is_empty() ? 0 : tools.spindle().number;
    return true;
  }
  if (n == "_current_pocket") {
    v = tools.spindle().is_empty() ? 0 : tools.spindle().pocket;
    return true;
  }
  if (n == "_selected_tool") {
    v = selected_tool;
    return true;
  }
  if (n == "_selected_pocket") {
    v = selected_index;
    return true;
  }
  if (n == "_motion_mode") {
    v = motion_mode == kMotionNone ? -1 : motion_mode < 0 ? 800 : motion_mode;
    return true;
  }
  if (n == "_plane") {
    static constexpr int codes[] = {170, 190, 180, 171, 191, 181};
    v = codes[static_cast<int>(plane)];
    return true;
  }
  if (n == "_ccomp") {
    v = cutter_side;
    return true;
  }
  if (n == "_call_level") {
    v = static_cast<double>(frames.size() - 1);
    return true;
  }
  if (n == "_remap_level") {
    v = remap_level();
    return true;
  }
  if (n == "_line") {
    v = current_line;
    return true;
  }
  if (n == "_task") {
    v = config.task ? 1 : 0;
    return true;
  }
  if (n == "_vmajor") {
    v = 2.9;  // LinuxCNC 2.9 dialect
    return true;
  }
  if (n == "_metric_machine") {
    // LinuxCNC: -1 without an INI file or its [TRAJ]LINEAR_UNITS, 0 for
    // "inch", else 1
    v = -1;
    if (config.ini != nullptr) {
      if (const auto u = config.ini->find("TRAJ", "LINEAR_UNITS")) v = *u == "inch" ? 0 : 1;
    }
    return true;
  }
  if (n == "_vminor") {
    v = 0.0;
    return true;
  }
  if (n.starts_with("_ini[")) {
    const std::size_t close = n.find(']');
    if (close == std::string_view::npos || config.ini == nullptr) return false;
    const std::string section(n.substr(5, close - 5));
    const std::string key(n.substr(close + 1));
    std::optional<std::string> text = config.ini->find(cnc::to_upper(section), cnc::to_upper(key));
    if (!text) text = config.ini->find(section, key);
    if (!text) return false;
    const auto d = cnc::parse_double(*text);
    if (!d) return false;
    v = *d;
    ini_names_read.insert(name);
    return true;
  }
  if (config.script) {
    try {
      if (config.script->script_parameter(name, v)) return true;
    } catch (const std::runtime_error& e) {
      fail("#<" + name + ">: " + e.what());
    }
  }
  return false;
}

bool Interpreter::State::find_named(const std::string& name, double& value) const {
  if (!name.empty() && name[0] == '_') {
    if (predefined(name, value)) return true;
    const auto it = globals.find(name);
    if (it == globals.end()) return false;
    value = it->second;
    return true;
  }
  const auto& locals = frames.back().locals;
  const auto it = locals.find(name);
  if (it == locals.end()) return false;
  value = it->second;
  return true;
}

double Interpreter::State::get_named(const std::string& name) const {
  double v = 0;
  if (!find_named(name, v)) fail("Named parameter #<" + name + "> not defined");
  return v;
}

void Interpreter::State::set_named(const std::string& name, double value) {
  if (!name.empty() && name[0] == '_') {
    double dummy = 0;
    if (name != "_value" && name != "_value_returned" && predefined(name, dummy)) {
      fail("Cannot assign to read-only parameter #<" + name + ">");
    }
    globals[name] = value;
    return;
  }
  frames.back().locals[name] = value;
}

std::string Interpreter::State::substitute_params(std::string_view text) {
  // (DEBUG,...), (PRINT,...), (LOG,...) and (ABORT,...) text as LinuxCNC
  // expands it: #n and #<name> become their values, unknown ones
  // "######"; a format given before them holds for the rest of the text:
  // %d (no decimals), %f (4 decimals), %.Nf (N decimals), else "%f" (6).
  std::string out;
  std::string format = "%f";
  std::size_t i = 0;
  char buf[64];
  while (i < text.size()) {
    const char c = text[i];
    if (c == '%') {
      ++i;
      if (i < text.size() && text[i] == 'd') {
        format = "%.0f";
        ++i;
      } else if (i < text.size() && text[i] == 'f') {
        format = "%.4f";
        ++i;
      } else if (i < text.size() && text[i] == '.') {
        ++i;
        if (i + 1 < text.size() && std::isdigit(static_cast<unsigned char>(text[i])) && text[i + 1] == 'f') {
          format = std::string("%.") + text[i] + "f";
          i += 2;
        } else {
          out.push_back('.');
        }
      } else {
        out.push_back('%');
      }
      continue;
    }
    if (c != '#') {
      out.push_back(c);
      ++i;
      continue;
    }
    ++i;
    if (i >= text.size()) fail("Named parameter not terminated");
    bool found = false;
    double v = 0;
    if (std::isdigit(static_cast<unsigned char>(text[i]))) {
      long index = 0;
      while (i < text.size() && std::isdigit(static_cast<unsigned char>(text[i]))) {
        if (index < 1000000) index = index * 10 + (text[i] - '0');
        ++i;
      }
      if (index >= 1 && index < kMaxParameters) {
        v = get_param(static_cast<int>(index));
        found = true;
      } else if (index == 0) {
        found = true;  // LinuxCNC reads its unused #0: always 0
      }
    } else if (text[i] == '<') {
      ++i;
      std::string name;
      while (i < text.size() && text[i] != '>' && text[i] != ')') {
        if (text[i] != ' ' && text[i] != '\t') name.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(text[i]))));
        ++i;
      }
      if (i >= text.size() || text[i] != '>') fail("Named parameter not terminated");
      ++i;
      found = find_named(name, v);
    } else {
      out.push_back('#');
      continue;
    }
    if (found) {
      if (std::fabs(v) < 0.0001) v = 0.0;  // LinuxCNC shows near-zero (and -0) as 0
      const int n = std::snprintf(buf, sizeof buf, format.c_str(), v);
      out += (n < 0 || n >= 30) ? std::string("######") : std::string(buf);
    } else {
      out += "######";
    }
  }
  return out;
}

}  // namespace cnc::interp
