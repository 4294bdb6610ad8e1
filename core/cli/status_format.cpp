#include "core/cli/status_format.hpp"

#include <cinttypes>
#include <cstdarg>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/util/time.hpp"

namespace cnc::cli {
namespace {

std::string fmt(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* f, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}

std::string axes_line(const char* label, const Pose& p, uint32_t mask) {
  std::string out = fmt("  %-10s", label);
  for (int a = 0; a < kNumAxes; ++a) {
    if (mask & (1U << a)) out += fmt(" %c%11.4f", kAxisLetters[a], p[a]);
  }
  return out + "\n";
}

nlohmann::json pose_json(const Pose& p) { return nlohmann::json(p.v); }

// A limit for a person: "none" when unlimited (1e99).
std::string limit(double v) { return v < 1e98 ? fmt("%g", v) : std::string("none"); }
std::string lower_limit(double v) { return v > -1e98 ? fmt("%g", v) : std::string("none"); }

}  // namespace

std::string format_status(const ipc::Status& s, const ipc::Liveness* live) {
  std::ostringstream o;
  if (live && live->task_stalled) {
    o << fmt("WARNING: the task cycle has not run for %.1f s: this status is stale. E-stop still works "
             "(cnc estop and the E-stop chain act in the servo thread).\n",
             static_cast<double>(live->status_age_ns) * 1e-9);
  }
  if (live && live->servo_stalled) {
    o << fmt("WARNING: motion has not run in the servo thread for %.1f s: E-stop requests are not acted on by "
             "motion; only the drives' own watchdogs stop them.\n",
             static_cast<double>(live->servo_age_ns) * 1e-9);
  }
  const double uptime = static_cast<double>(s.health.time_ns - s.health.started_ns) * 1e-9;
  o << fmt("Controller pid %d, up %.1f s, machine \"%s\"\n", s.health.pid, uptime, s.health.machine.c_str());
  o << fmt("  config     %s\n", s.health.ini_file.c_str());
  o << fmt("  realtime   memory %s, %s\n", s.health.realtime_memory_locked ? "locked" : "not locked",
           s.health.realtime_fifo ? "SCHED_FIFO" : "normal scheduling");
  if (!s.health.realtime_note.empty()) o << "             " << s.health.realtime_note.c_str() << "\n";
  if (s.task.available) {
    o << fmt("Task: state %s, mode %s, interpreter %s, exec %s%s\n", to_string(s.task.state), to_string(s.task.mode),
             to_string(s.task.interp_state), to_string(s.task.exec_state), s.task.paused ? ", PAUSED" : "");
    if (!s.task.file.empty()) {
      o << fmt("  program    %s  line %d (read %d of %d)\n", s.task.file.c_str(), s.task.current_line, s.task.read_line,
               s.task.total_lines);
    }
  } else {
    o << "Task: no task controller loaded\n";
  }
  if (s.motion.joints > 0) {
    if (s.motion.servo_stalled) {
      o << "Motion: NOT RUNNING (motion-controller stopped in the servo thread; nothing is commanded to move; the "
           "values below are its last)\n";
    } else {
      o << fmt("Motion: mode %s, %s, %s, queue %d, line %d, velocity %.3f\n", to_string(s.motion.mode),
               s.motion.enabled ? "enabled" : "disabled", s.motion.inpos ? "in position" : "moving", s.motion.queue,
               s.motion.motion_line, s.motion.current_vel);
    }
    if (s.motion.spindle_wait >= 0) {
      o << fmt("  waiting for spindle %d at speed (%.1f s; spindle.%d.at-speed is FALSE)\n", s.motion.spindle_wait,
               s.motion.spindle_wait_s, s.motion.spindle_wait);
    }
    if (s.motion.estop_latched) {
      o << fmt("  E-stop     latched in the servo thread: %s\n",
               s.motion.estop_cause == ipc::EstopCause::Request
                   ? fmt("requested by process %d", s.motion.estop_pid).c_str()
                   : "the E-stop chain is open");
    }
    if (s.motion.max_velocity < 1e90) {
      o << fmt("  overrides  feed %.0f%%, rapid %.0f%%, max velocity %.3f\n", s.motion.feed_scale * 100,
               s.motion.rapid_scale * 100, s.motion.max_velocity);
    } else {
      o << fmt("  overrides  feed %.0f%%, rapid %.0f%%, max velocity not limited\n", s.motion.feed_scale * 100,
               s.motion.rapid_scale * 100);
    }
    o << fmt("  tool       %d in the spindle%s%s%s\n", s.io.tool_in_spindle, s.io.flood ? ", flood on" : "",
             s.io.mist ? ", mist on" : "", s.spindles[0].enabled ? ", spindle on" : "");
    o << axes_line("commanded", s.motion.position, s.motion.axis_mask);
    if (s.motion.carte_fb_valid) o << axes_line("actual", s.motion.actual_position, s.motion.axis_mask);
    else o << "  actual     unknown (forward kinematics not usable until homed)\n";
    o << axes_line("to go", s.motion.dtg, s.motion.axis_mask);
    o << "  joint  homed  enabled  fault   pos-cmd       pos-fb       f-error   limits\n";
    for (int j = 0; j < s.motion.joints && j < kMaxJoints; ++j) {
      const ipc::JointStatus& js = s.joints[j];
      std::string lim;
      if (js.min_hard_limit) lim += "MIN-HARD ";
      if (js.max_hard_limit) lim += "MAX-HARD ";
      if (js.min_soft_limit) lim += "min-soft ";
      if (js.max_soft_limit) lim += "max-soft ";
      o << fmt("  %5d  %-5s  %-7s  %-5s %11.4f  %11.4f  %10.5f   %s\n", j,
               js.homed ? "yes" : js.homing ? "..." : "no", js.enabled ? "yes" : "no", js.fault ? "YES" : "no",
               js.pos_cmd, js.pos_fb, js.ferror_current, lim.c_str());
    }
    // The limits in force: the INI's, as changed at run time (cnc set).
    o << fmt("  limits in force (units, /s, /s^2, /s^3)\n    path       velocity %s  acceleration %s  jerk %s\n",
             limit(s.motion.max_linear_velocity).c_str(), limit(s.motion.max_linear_acceleration).c_str(),
             limit(s.motion.max_linear_jerk).c_str());
    for (int a = 0; a < kNumAxes; ++a) {
      if (!(s.motion.axis_mask & (1U << a))) continue;
      const ipc::AxisStatus& ax = s.axes[a];
      o << fmt("    axis %c     %s..%s  velocity %s  acceleration %s  jerk %s  (moves use %g, %g)\n", kAxisLetters[a],
               lower_limit(ax.min_position_limit).c_str(),
               limit(ax.max_position_limit).c_str(), limit(ax.max_velocity).c_str(), limit(ax.max_acceleration).c_str(),
               limit(ax.max_jerk).c_str(), ax.velocity_limit, ax.acceleration_limit);
    }
    for (int j = 0; j < s.motion.joints && j < kMaxJoints; ++j) {
      const ipc::JointStatus& js = s.joints[j];
      o << fmt("    joint %-4d %s..%s  velocity %s  acceleration %s  jerk %s  f-error %g..%g  (jogs use %g)\n", j,
               lower_limit(js.min_position_limit).c_str(),
               limit(js.max_position_limit).c_str(), limit(js.max_velocity).c_str(), limit(js.max_acceleration).c_str(),
               limit(js.max_jerk).c_str(), js.min_ferror, js.ferror, js.velocity_limit);
    }
    for (int i = 0; i < s.motion.spindles && i < ipc::kMaxSpindles; ++i) {
      const ipc::SpindleStatus& sp = s.spindles[i];
      o << fmt("    spindle %d  forward %g..%s rpm, reverse %s; commanded %g rpm x %.0f%%, out %g rpm%s\n", i,
               sp.min_forward, limit(sp.max_forward).c_str(),
               sp.max_reverse <= 0 ? "not allowed" : fmt("%g..%s rpm", sp.min_reverse, limit(sp.max_reverse).c_str()).c_str(),
               sp.speed, sp.override_scale * 100, sp.speed_out, sp.speed_limited ? " (held at a limit)" : "");
    }
  }
  bool any_drive = false;
  for (const ipc::DriveStatus& d : s.drives) any_drive = any_drive || d.present;
  if (any_drive) {
    o << "Drives:\n";
    for (const ipc::DriveStatus& d : s.drives) {
      if (!d.present) continue;
      o << fmt("  %-20s joint %2d  status 0x%04x  mode %d  f-error %9.5f  torque %5.1f%%  %s\n", d.name.c_str(),
               d.joint, d.statusword, d.mode, d.following_error, d.torque_percent, d.fault_text.c_str());
    }
  }
  o << "Threads:\n";
  for (const ipc::ThreadStatus& t : s.threads) {
    if (t.name.empty()) continue;
    o << fmt("  %-14s period %" PRId64 " ns, %" PRIu64 " cycles, %" PRIu64 " overruns, %s\n", t.name.c_str(),
             t.period_ns, t.cycles, t.overruns, t.fifo ? "SCHED_FIFO" : "normal scheduling");
    o << fmt("                 wake-up latency p50 %.1f us, p99.9 %.1f us, max %.1f us; period %.1f..%.1f us; "
             "exec %.1f us (max %.1f)\n",
             static_cast<double>(t.latency_p50_ns) / 1e3, static_cast<double>(t.latency_p999_ns) / 1e3,
             static_cast<double>(t.latency_max_ns) / 1e3, static_cast<double>(t.period_min_ns) / 1e3,
             static_cast<double>(t.period_max_ns) / 1e3, static_cast<double>(t.exec_last_ns) / 1e3,
             static_cast<double>(t.exec_max_ns) / 1e3);
    if (t.sim_exec_max_ns > 0) {
      o << fmt("                 of which product functions %.1f us (max %.1f), simulators %.1f us (max %.1f)\n",
               static_cast<double>(t.product_exec_last_ns) / 1e3, static_cast<double>(t.product_exec_max_ns) / 1e3,
               static_cast<double>(t.sim_exec_last_ns) / 1e3, static_cast<double>(t.sim_exec_max_ns) / 1e3);
    }
    if (t.overruns > 0) {
      o << fmt("                 overruns: streak %u now, longest %u; %" PRIu64 " periods missed, longest gap %" PRId64
               "; %" PRIu64 " blamed on late wake-ups",
               t.overrun_streak, t.longest_streak, t.missed_cycles, t.longest_gap, t.late_wakes);
      if (!t.overrun_function.empty()) {
        o << fmt(", %u on %s (max %.1f us)", t.overrun_function_count, t.overrun_function.c_str(),
                 static_cast<double>(t.overrun_function_max_ns) / 1e3);
      }
      o << "\n";
    }
  }
  for (const ipc::SimulatorStatus& sim : s.simulators) {
    if (sim.name.empty()) continue;
    o << fmt("  %-14s simulator on its own thread: %" PRIu64 " periods, %" PRIu64 " late (%" PRIu64
             " caught up in the HAL thread), woken %" PRIu64 " times; exec %.1f us (max %.1f)\n",
             sim.name.c_str(), sim.steps, sim.late_steps, sim.helped_steps, sim.wakes,
             static_cast<double>(sim.exec_last_ns) / 1e3,
             static_cast<double>(sim.exec_max_ns) / 1e3);
  }
  o << format_alarms(s.alarms);
  o << fmt("Last command: serial %u %s, %s\n", s.echo.serial, to_string(s.echo.type), to_string(s.echo.state));
  return o.str();
}

std::string format_alarms(const ipc::AlarmStatus& a, bool all) {
  if (!a.available) return "";
  std::ostringstream o;
  o << fmt("Alarms: %u active%s\n", a.active, a.dropped ? fmt(", %u older ones dropped", a.dropped).c_str() : "");
  for (const ipc::AlarmEntry& e : a.list) {
    if (e.id == 0 || (e.acknowledged && !all)) continue;
    const std::time_t t = static_cast<std::time_t>(e.last_ns / 1'000'000'000);
    std::tm tm{};
    ::localtime_r(&t, &tm);
    char when[32];
    std::strftime(when, sizeof when, "%H:%M:%S", &tm);
    o << fmt("  #%u %s%s%s: %s\n", e.id, when, e.acknowledged ? " (acknowledged)" : "",
             e.count > 1 ? fmt(" x%u", e.count).c_str() : "", e.text.c_str());
  }
  return o.str();
}

std::string status_json(const ipc::Status& s, int indent, const ipc::Liveness* live) {
  using nlohmann::json;
  json j;
  j["health"] = {{"heartbeat", s.health.heartbeat},
                 {"time_ns", s.health.time_ns},
                 {"started_ns", s.health.started_ns},
                 {"pid", s.health.pid},
                 {"realtime_memory_locked", s.health.realtime_memory_locked},
                 {"realtime_fifo", s.health.realtime_fifo},
                 {"realtime_note", s.health.realtime_note.c_str()},
                 {"ini_file", s.health.ini_file.c_str()},
                 {"machine", s.health.machine.c_str()},
                 {"messages_dropped", s.health.messages_dropped},
                 {"task_cycle_ns", s.health.task_cycle_ns},
                 {"shutting_down", s.health.shutting_down}};
  j["echo"] = {{"serial", s.echo.serial}, {"state", to_string(s.echo.state)}, {"type", to_string(s.echo.type)}};
  j["task"] = {{"available", s.task.available},
               {"state", to_string(s.task.state)},
               {"mode", to_string(s.task.mode)},
               {"interp_state", to_string(s.task.interp_state)},
               {"exec_state", to_string(s.task.exec_state)},
               {"paused", s.task.paused},
               {"block_delete", s.task.block_delete},
               {"optional_stop", s.task.optional_stop},
               {"file", s.task.file.c_str()},
               {"command", s.task.command.c_str()},
               {"current_line", s.task.current_line},
               {"read_line", s.task.read_line},
               {"total_lines", s.task.total_lines},
               {"g5x_index", s.task.g5x_index},
               {"g5x_offset", pose_json(s.task.g5x_offset)},
               {"g92_offset", pose_json(s.task.g92_offset)},
               {"rotation_xy", s.task.rotation_xy},
               {"tool_offset", pose_json(s.task.tool_offset)},
               {"program_units", s.task.program_units},
               {"gcodes", s.task.active_gcodes},
               {"mcodes", s.task.active_mcodes},
               {"settings", s.task.active_settings},
               {"program_elapsed_s", static_cast<double>(s.task.program_elapsed_ns) * 1e-9},
               {"blocks_executed", s.task.blocks_executed}};
  j["motion"] = {{"mode", to_string(s.motion.mode)},
                 {"enabled", s.motion.enabled},
                 {"inpos", s.motion.inpos},
                 {"paused", s.motion.paused},
                 {"queue", s.motion.queue},
                 {"queue_full", s.motion.queue_full},
                 {"spindle_wait", s.motion.spindle_wait},
                 {"spindle_wait_s", s.motion.spindle_wait_s},
                 {"motion_line", s.motion.motion_line},
                 {"axis_mask", s.motion.axis_mask},
                 {"joints", s.motion.joints},
                 {"position", pose_json(s.motion.position)},
                 {"actual_position", pose_json(s.motion.actual_position)},
                 {"actual_position_valid", s.motion.carte_fb_valid},
                 {"dtg", pose_json(s.motion.dtg)},
                 {"current_vel", s.motion.current_vel},
                 {"feed_scale", s.motion.feed_scale},
                 {"rapid_scale", s.motion.rapid_scale},
                 {"max_velocity", s.motion.max_velocity},
                 {"max_linear_velocity", s.motion.max_linear_velocity},
                 {"max_linear_acceleration", s.motion.max_linear_acceleration},
                 {"max_linear_jerk", s.motion.max_linear_jerk},
                 {"probe_tripped", s.motion.probe_tripped},
                 {"probed_position", pose_json(s.motion.probed_position)},
                 {"watchdog_enabled", s.motion.watchdog_enabled},
                 {"servo_cycles", s.motion.servo_cycles},
                 {"estop_latched", s.motion.estop_latched},
                 {"estop_cause", to_string(s.motion.estop_cause)},
                 {"estop_pid", s.motion.estop_pid},
                 {"servo_stalled", s.motion.servo_stalled}};
  {
    json alarms = json::array();
    for (const ipc::AlarmEntry& e : s.alarms.list) {
      if (e.id == 0) continue;
      alarms.push_back({{"id", e.id},
                        {"count", e.count},
                        {"first_ns", e.first_ns},
                        {"last_ns", e.last_ns},
                        {"acknowledged", e.acknowledged},
                        {"source", e.source.c_str()},
                        {"cause", e.cause.c_str()},
                        {"text", e.text.c_str()}});
    }
    j["alarms"] = {{"available", s.alarms.available},
                   {"active", s.alarms.active},
                   {"dropped", s.alarms.dropped},
                   {"list", alarms}};
  }
  if (live) {
    j["liveness"] = {{"status_age_s", static_cast<double>(live->status_age_ns) * 1e-9},
                     {"task_stalled", live->task_stalled},
                     {"servo_age_s", live->servo_age_ns < 0 ? -1.0 : static_cast<double>(live->servo_age_ns) * 1e-9},
                     {"servo_stalled", live->servo_stalled}};
  }
  json joints = json::array();
  for (int i = 0; i < s.motion.joints && i < kMaxJoints; ++i) {
    const ipc::JointStatus& js = s.joints[i];
    joints.push_back({{"homed", js.homed},
                      {"homing", js.homing},
                      {"enabled", js.enabled},
                      {"fault", js.fault},
                      {"inpos", js.inpos},
                      {"pos_cmd", js.pos_cmd},
                      {"pos_fb", js.pos_fb},
                      {"motor_pos_cmd", js.motor_pos_cmd},
                      {"motor_pos_fb", js.motor_pos_fb},
                      {"velocity", js.velocity},
                      {"ferror_current", js.ferror_current},
                      {"ferror_highmark", js.ferror_highmark},
                      {"min_hard_limit", js.min_hard_limit},
                      {"max_hard_limit", js.max_hard_limit},
                      {"min_soft_limit", js.min_soft_limit},
                      {"max_soft_limit", js.max_soft_limit},
                      {"axis", js.axis},
                      {"min_position_limit", js.min_position_limit},
                      {"max_position_limit", js.max_position_limit},
                      {"max_velocity", js.max_velocity},
                      {"max_acceleration", js.max_acceleration},
                      {"max_jerk", js.max_jerk},
                      {"velocity_limit", js.velocity_limit},
                      {"ferror", js.ferror},
                      {"min_ferror", js.min_ferror}});
  }
  j["joints"] = joints;
  json axes = json::array();
  for (int a = 0; a < kNumAxes; ++a) {
    if (!(s.motion.axis_mask & (1U << a))) continue;
    const ipc::AxisStatus& ax = s.axes[a];
    axes.push_back({{"axis", std::string(1, kAxisLetters[a])},
                    {"min_position_limit", ax.min_position_limit},
                    {"max_position_limit", ax.max_position_limit},
                    {"max_velocity", ax.max_velocity},
                    {"max_acceleration", ax.max_acceleration},
                    {"max_jerk", ax.max_jerk},
                    {"velocity_limit", ax.velocity_limit},
                    {"acceleration_limit", ax.acceleration_limit},
                    {"velocity", ax.velocity}});
  }
  j["axes"] = axes;
  j["io"] = {{"tool_in_spindle", s.io.tool_in_spindle},
             {"pocket_prepped", s.io.pocket_prepped},
             {"flood", s.io.flood},
             {"mist", s.io.mist},
             {"lube", s.io.lube},
             {"estop_chain_ok", s.io.estop_chain_ok}};
  json spindles = json::array();
  for (int i = 0; i < s.motion.spindles && i < ipc::kMaxSpindles; ++i) {
    const ipc::SpindleStatus& sp = s.spindles[i];
    spindles.push_back({{"speed", sp.speed}, {"direction", sp.direction}, {"enabled", sp.enabled},
                        {"override", sp.override_scale}, {"at_speed", sp.at_speed}, {"brake", sp.brake},
                        {"amp_fault", sp.amp_fault}, {"speed_out", sp.speed_out}, {"speed_limited", sp.speed_limited},
                        {"max_forward", sp.max_forward}, {"min_forward", sp.min_forward},
                        {"max_reverse", sp.max_reverse}, {"min_reverse", sp.min_reverse}});
  }
  j["spindles"] = spindles;
  json threads = json::array();
  for (const ipc::ThreadStatus& t : s.threads) {
    if (t.name.empty()) continue;
    threads.push_back({{"name", t.name.c_str()},
                       {"fifo", t.fifo},
                       {"period_ns", t.period_ns},
                       {"cycles", t.cycles},
                       {"overruns", t.overruns},
                       {"missed_cycles", t.missed_cycles},
                       {"overrun_streak", t.overrun_streak},
                       {"longest_streak", t.longest_streak},
                       {"longest_gap", t.longest_gap},
                       {"late_wakes", t.late_wakes},
                       {"overrun_function", t.overrun_function.c_str()},
                       {"overrun_function_count", t.overrun_function_count},
                       {"overrun_function_max_ns", t.overrun_function_max_ns},
                       {"latency_min_ns", t.latency_min_ns},
                       {"latency_p50_ns", t.latency_p50_ns},
                       {"latency_p99_ns", t.latency_p99_ns},
                       {"latency_p999_ns", t.latency_p999_ns},
                       {"latency_max_ns", t.latency_max_ns},
                       {"period_min_ns", t.period_min_ns},
                       {"period_max_ns", t.period_max_ns},
                       {"exec_last_ns", t.exec_last_ns},
                       {"exec_max_ns", t.exec_max_ns},
                       {"product_exec_last_ns", t.product_exec_last_ns},
                       {"product_exec_max_ns", t.product_exec_max_ns},
                       {"sim_exec_last_ns", t.sim_exec_last_ns},
                       {"sim_exec_max_ns", t.sim_exec_max_ns}});
  }
  j["threads"] = threads;
  json simulators = json::array();
  for (const ipc::SimulatorStatus& sim : s.simulators) {
    if (sim.name.empty()) continue;
    simulators.push_back({{"name", sim.name.c_str()},
                          {"steps", sim.steps},
                          {"late_steps", sim.late_steps},
                          {"helped_steps", sim.helped_steps},
                          {"wakes", sim.wakes},
                          {"exec_last_ns", sim.exec_last_ns},
                          {"exec_max_ns", sim.exec_max_ns}});
  }
  j["simulators"] = simulators;
  return j.dump(indent);
}

}  // namespace cnc::cli
