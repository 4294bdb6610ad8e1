#include "comp/measurement.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::comp {

bool Measurement::has_temperature() const noexcept {
  for (const MeasurementPoint& p : points) {
    if (std::isfinite(p.temperature_c)) return true;
  }
  return false;
}

bool Measurement::has_time() const noexcept {
  for (const MeasurementPoint& p : points) {
    if (std::isfinite(p.time_s)) return true;
  }
  return false;
}

namespace {

enum Column { kTarget, kRun, kDirection, kDeviation, kTemperature, kTime, kColumns };
constexpr const char* kNames[kColumns] = {"target", "run", "direction", "deviation_um", "temperature_c", "time_s"};

int parse_direction(std::string_view s) {
  const std::string d = to_lower(trim(s));
  if (d == "+" || d == "up" || d == "1" || d == "+1") return 1;
  if (d == "-" || d == "down" || d == "-1") return -1;
  return 0;
}

std::string short_number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

}  // namespace

Measurement parse_measurement(std::string_view text, const std::string& file_name, const MeasurementLimits& limits) {
  Measurement m;
  std::vector<int> point_lines;  // line of each point, for the duplicate check
  int column[kColumns];
  for (int& c : column) c = -1;
  std::size_t ncols = 0;
  bool have_header = false;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) eol = text.size();
    std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::string_view body = trim(line);
    if (body.empty()) continue;
    if (body.front() == '#') {
      std::string_view c = trim(body.substr(1));
      if (starts_with_icase(c, "axis:")) m.axis = std::string(trim(c.substr(5)));
      else m.notes.emplace_back(c);
      continue;
    }
    const std::vector<std::string> cells = split(body, ',');
    if (!have_header) {
      for (std::size_t k = 0; k < cells.size(); ++k) {
        const std::string name = to_lower(trim(cells[k]));
        int found = -1;
        for (int c = 0; c < kColumns; ++c) {
          if (name == kNames[c]) found = c;
        }
        if (found < 0) {
          throw ConfigError(file_name, line_no,
                            "unknown column '" + name +
                                "' (expected target, run, direction, deviation_um and optionally temperature_c, time_s)");
        }
        if (column[found] >= 0) throw ConfigError(file_name, line_no, "column '" + name + "' appears twice");
        column[found] = static_cast<int>(k);
      }
      for (int c = kTarget; c <= kDeviation; ++c) {
        if (column[c] < 0) {
          throw ConfigError(file_name, line_no,
                            std::string("the header has no '") + kNames[c] +
                                "' column (the first line that is not a comment names the columns: "
                                "target,run,direction,deviation_um[,temperature_c][,time_s])");
        }
      }
      ncols = cells.size();
      have_header = true;
      continue;
    }
    if (cells.size() != ncols) {
      throw ConfigError(file_name, line_no,
                        "expected " + std::to_string(ncols) + " values, found " + std::to_string(cells.size()));
    }
    MeasurementPoint p;
    const auto number = [&](int c) {
      const auto v = parse_double(trim(cells[static_cast<std::size_t>(column[c])]));
      if (!v) {
        throw ConfigError(file_name, line_no,
                          std::string(kNames[c]) + ": '" + std::string(trim(cells[static_cast<std::size_t>(column[c])])) +
                              "' is not a number");
      }
      return *v;
    };
    p.target = number(kTarget);
    const auto run = parse_int(trim(cells[static_cast<std::size_t>(column[kRun])]));
    if (!run || *run < 1 || *run > 100000) {
      throw ConfigError(file_name, line_no, "run: expected a whole number from 1, found '" +
                                                std::string(trim(cells[static_cast<std::size_t>(column[kRun])])) + "'");
    }
    p.run = static_cast<int>(*run);
    p.direction = parse_direction(cells[static_cast<std::size_t>(column[kDirection])]);
    if (p.direction == 0) {
      throw ConfigError(file_name, line_no,
                        "direction: expected + or - (or up/down), found '" +
                            std::string(trim(cells[static_cast<std::size_t>(column[kDirection])])) + "'");
    }
    if (!(std::fabs(p.target) <= limits.max_abs_target)) {
      throw ConfigError(file_name, line_no,
                        "target: " + format_double(p.target) + " is not a position on a machine axis (more than " +
                            format_double(limits.max_abs_target) + " machine units from 0)");
    }
    p.deviation_um = number(kDeviation);
    if (!(std::fabs(p.deviation_um) <= limits.max_abs_deviation_um)) {
      throw ConfigError(
          file_name, line_no,
          "deviation_um: " + format_double(p.deviation_um) + " um (" + short_number(p.deviation_um / 1000) +
              " mm) is larger than " + format_double(limits.max_abs_deviation_um) +
              " um: deviations are in micrometres (position reached minus target); are these nanometres? A "
              "compensation from them would move the axis by millimetres. If the axis really is this far off, "
              "raise the limit (cnc-comp --max-deviation UM)");
    }
    if (column[kTemperature] >= 0) {
      p.temperature_c = number(kTemperature);
      if (!(p.temperature_c >= limits.min_temperature_c && p.temperature_c <= limits.max_temperature_c)) {
        throw ConfigError(file_name, line_no,
                          "temperature_c: " + format_double(p.temperature_c) + " is outside " +
                              format_double(limits.min_temperature_c) + ".." + format_double(limits.max_temperature_c) +
                              " degrees Celsius (kelvin or Fahrenheit?)");
      }
    }
    if (column[kTime] >= 0) {
      p.time_s = number(kTime);
      if (!(std::fabs(p.time_s) <= limits.max_abs_time_s)) {
        throw ConfigError(file_name, line_no,
                          "time_s: " + format_double(p.time_s) + " s is not a time in a measurement (more than " +
                              format_double(limits.max_abs_time_s) + " s)");
      }
    }
    m.points.push_back(p);
    point_lines.push_back(line_no);
  }
  if (!have_header) throw ConfigError(file_name, 0, "no header line (target,run,direction,deviation_um...)");
  if (m.points.empty()) throw ConfigError(file_name, 0, "no measured points");
  // Each run of a target and direction once: sorted by direction, run and
  // target, a repeat is next to its first occurrence (targets within 1e-6
  // are one target, as the ISO evaluation groups them).
  std::vector<std::size_t> order(m.points.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const MeasurementPoint &p = m.points[a], &q = m.points[b];
    if (p.direction != q.direction) return p.direction < q.direction;
    if (p.run != q.run) return p.run < q.run;
    if (p.target != q.target) return p.target < q.target;
    return point_lines[a] < point_lines[b];
  });
  std::size_t first = 0, again = m.points.size();  // the first repeat in file order
  for (std::size_t k = 1; k < order.size(); ++k) {
    const MeasurementPoint &p = m.points[order[k - 1]], &q = m.points[order[k]];
    if (p.direction != q.direction || p.run != q.run || std::fabs(q.target - p.target) > 1e-6) continue;
    if (order[k] < again) {
      first = order[k - 1];
      again = order[k];
    }
  }
  if (again < m.points.size()) {
    const MeasurementPoint& q = m.points[again];
    throw ConfigError(file_name, point_lines[again],
                      "run " + std::to_string(q.run) + " of target " + format_double(m.points[first].target) +
                          " moving " + (q.direction > 0 ? "+" : "-") + " appears again (first at line " +
                          std::to_string(point_lines[first]) +
                          "): each run of a target and direction is one line; a repeated line would count as an "
                          "extra run");
  }
  return m;
}

Measurement load_measurement(const std::filesystem::path& path, const MeasurementLimits& limits) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const std::exception& e) {
    throw ConfigError(path.string(), 0, std::string("cannot read the measurement: ") + e.what());
  }
  return parse_measurement(text, path.string(), limits);
}

std::string format_measurement(const Measurement& m) {
  std::string out;
  if (!m.axis.empty()) out += "# axis: " + m.axis + "\n";
  for (const std::string& n : m.notes) out += "# " + n + "\n";
  const bool temp = m.has_temperature(), time = m.has_time();
  out += "target,run,direction,deviation_um";
  if (temp) out += ",temperature_c";
  if (time) out += ",time_s";
  out += "\n";
  char buf[160];
  for (const MeasurementPoint& p : m.points) {
    int n = std::snprintf(buf, sizeof buf, "%.6f,%d,%c,%.4f", p.target, p.run, p.direction > 0 ? '+' : '-',
                          p.deviation_um);
    if (temp) n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), ",%.3f", p.temperature_c);
    if (time) std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), ",%.3f", p.time_s);
    out += buf;
    out += "\n";
  }
  return out;
}

void number_runs(Measurement& m, double tolerance) {
  std::vector<std::pair<double, int>> seen;  // (target, direction) -> count, linear: a few hundred targets
  std::vector<int> count;
  for (MeasurementPoint& p : m.points) {
    std::size_t k = 0;
    for (; k < seen.size(); ++k) {
      if (seen[k].second == p.direction && std::fabs(seen[k].first - p.target) <= tolerance) break;
    }
    if (k == seen.size()) {
      seen.emplace_back(p.target, p.direction);
      count.push_back(0);
    }
    p.run = ++count[k];
  }
}

}  // namespace cnc::comp
