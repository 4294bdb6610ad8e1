#include "hmi/readouts.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace cnc::hmi {

namespace {
std::string pct(double scale) {
  char b[32];
  std::snprintf(b, sizeof b, "%.0f%%", scale * 100.0);
  return b;
}
}  // namespace

std::string feed_readout(const ipc::Status& s, bool machine_inch, const NumberFormat& f) {
  const std::string mu = machine_inch ? "in/min" : "mm/min";
  const std::string pu = s.task.program_units == 1 ? "in/min" : "mm/min";
  const double now = s.motion.enabled ? std::fabs(s.motion.current_vel) * 60.0 : 0.0;
  std::string out;
  if (s.task.state != ipc::TaskState::On) {
    out = "F – (machine off)";
  } else {
    const double feed = s.task.active_settings[1];
    out = "F " + f.fixed(feed, 0) + " " + pu + " × " + pct(s.motion.feed_scale) + " = " +
          f.fixed(feed * s.motion.feed_scale, 0) + " " + pu;
  }
  return out + " · now " + f.fixed(now, 0) + " " + mu;
}

std::string spindle_readout(const ipc::Status& s, const NumberFormat& f) {
  const ipc::SpindleStatus& sp = s.spindles[0];
  const bool on = s.task.state == ipc::TaskState::On;
  std::string out;
  if (!on) {
    out = "S – (machine off)";
  } else {
    const double cmd = s.task.active_settings[2];
    out = "S " + f.fixed(cmd, 0) + " rpm";
    if (sp.enabled) {
      const char* dir = sp.direction > 0 ? " FWD" : sp.direction < 0 ? " REV" : "";
      out += " × " + pct(sp.override_scale) + " = " + f.fixed(std::fabs(sp.speed_out), 0) + " rpm" + dir;
      if (sp.speed_limited) out += " (at its limit)";
    } else {
      out += " · spindle stopped";
    }
  }
  out += " · actual " + f.fixed(std::fabs(sp.speed_feedback), 0) + " rpm";
  if (on && sp.enabled && !sp.at_speed) out += " · NOT AT SPEED";
  return out;
}

std::string mdi_running_readout(const ipc::Status& s) {
  const bool mdi_running = s.task.mode == ipc::TaskMode::Mdi && s.task.interp_state != ipc::InterpState::Idle;
  if (!mdi_running || s.task.command.empty()) return "";
  return "running: " + std::string(s.task.command.view());
}

ProgramProgress program_progress(const ipc::Status& s) {
  ProgramProgress p;
  if (s.task.file.empty() || s.task.total_lines <= 0) return p;
  const bool running = s.task.interp_state != ipc::InterpState::Idle && s.task.mode == ipc::TaskMode::Auto;
  p.elapsed_s = static_cast<double>(s.task.program_elapsed_ns) * 1e-9;
  if (!running) {
    p.percent = s.task.program_elapsed_ns > 0 && s.task.current_line == 0 ? 100 : 0;
    return p;
  }
  const double done = std::clamp(static_cast<double>(s.task.current_line) / s.task.total_lines, 0.0, 1.0);
  p.percent = static_cast<int>(std::floor(done * 100.0));
  // Extrapolated only with enough behind it: 2 % of the lines and 2 s.
  if (done >= 0.02 && p.elapsed_s >= 2.0) p.remaining_s = p.elapsed_s * (1.0 - done) / done;
  return p;
}

std::string format_duration(double seconds) {
  const long t = seconds > 0 ? std::lround(seconds) : 0;
  char b[32];
  std::snprintf(b, sizeof b, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  return b;
}

std::string progress_readout(const ipc::Status& s, double estimate_s) {
  if (s.task.file.empty()) return "no program open";
  const ProgramProgress p = program_progress(s);
  std::string out = "line " + std::to_string(s.task.current_line) + " of " + std::to_string(s.task.total_lines);
  if (p.percent >= 0) out += " · " + std::to_string(p.percent) + "%";
  const bool running = s.task.interp_state != ipc::InterpState::Idle && s.task.mode == ipc::TaskMode::Auto;
  if (running || s.task.program_elapsed_ns > 0) out += " · " + format_duration(p.elapsed_s);
  if (estimate_s >= 0 && running) {
    out += " · about " + format_duration(std::max(0.0, estimate_s - p.elapsed_s)) + " left (planner)";
  } else if (estimate_s >= 0) {
    out += " · planned " + format_duration(estimate_s) + " of motion";
  } else if (p.remaining_s >= 0) {
    out += " · about " + format_duration(p.remaining_s) + " left (from lines)";
  }
  // Errors of a program that ran (not MDI's, not before any program).
  if (s.task.program_started_ns != 0 && s.task.errors_since_start > 0) {
    out += " · errors: " + std::to_string(s.task.errors_since_start);
  }
  return out;
}

std::optional<double> parse_estimate_output(std::string_view output) {
  const std::size_t at = output.find(" s of motion");
  if (at == std::string_view::npos) return std::nullopt;
  std::size_t start = at;
  while (start > 0 && (std::isdigit(static_cast<unsigned char>(output[start - 1])) != 0 || output[start - 1] == '.')) {
    --start;
  }
  if (start == at) return std::nullopt;
  const std::string number(output.substr(start, at - start));
  char* end = nullptr;
  const double v = std::strtod(number.c_str(), &end);
  if (end == number.c_str() || *end != '\0' || !(v >= 0)) return std::nullopt;
  return v;
}

std::vector<std::string> statusword_bits(uint16_t sw) {
  static const char* const kNames[16] = {
      "ready to switch on",   "switched on",      "operation enabled", "fault",
      "voltage enabled",      nullptr,            "switch on disabled", "warning",
      "manufacturer bit 8",   "remote",           "target reached",    "internal limit active",
      "set-point followed",   "following error",  "manufacturer bit 14", "manufacturer bit 15"};
  std::vector<std::string> out;
  for (int b = 0; b < 16; ++b) {
    const bool set = (sw >> b) & 1U;
    if (b == 5) {
      // Quick stop is active low: bit 5 clear means a quick stop is active
      // (in the states where the bit is meaningful).
      if (!set && (sw & 0x0003U) == 0x0003U) out.emplace_back("QUICK STOP active");
      continue;
    }
    if (set) out.emplace_back(kNames[b]);
  }
  return out;
}

std::string statusword_readout(uint16_t sw) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X", sw);
  std::string out = b;
  const auto bits = statusword_bits(sw);
  for (std::size_t i = 0; i < bits.size(); ++i) out += (i ? ", " : ": ") + bits[i];
  return out;
}

std::string statusword_short(uint16_t sw) {
  static const char* const kShort[16] = {"RTSO", "SO", "OE", "F", "VE", nullptr, "SOD", "W",
                                         "MS8", "RM", "TR", "ILA", "SPF", "FE", "MS14", "MS15"};
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X", sw);
  std::string out = b;
  for (int i = 0; i < 16; ++i) {
    const bool set = (sw >> i) & 1U;
    if (i == 5) {
      if (!set && (sw & 0x0003U) == 0x0003U) out += " QS!";
      continue;
    }
    if (set) out += std::string(" ") + kShort[i];
  }
  return out;
}

std::string drive_velocity_unit(bool spindle, bool angular, bool machine_inch) {
  if (spindle) return "rpm";
  if (angular) return "°/s";
  return machine_inch ? "in/s" : "mm/s";
}

std::string drive_position_unit(bool angular, bool machine_inch) {
  if (angular) return "°";
  return machine_inch ? "in" : "mm";
}

double drive_velocity_value(const ipc::DriveStatus& d) { return d.joint < 0 ? d.velocity * 60.0 : d.velocity; }

}  // namespace cnc::hmi
