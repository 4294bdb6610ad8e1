// The task controller: its configuration, construction and the link to
// motion; its commands, program running and status are in
// task_commands.cpp, task_program.cpp and task_status.cpp
// (task_internal.hpp: what they share).
#include "core/task/task_internal.hpp"

#include <algorithm>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "core/ini/ini_file.hpp"
#include "core/interp/line_reader.hpp"
#include "core/motion/params.hpp"
#include "core/util/strings.hpp"
#include "core/util/time.hpp"

namespace cnc::task {

using ipc::CommandState;
using ipc::CommandType;
using motion::Cmd;

TaskConfig TaskConfig::from_ini(const ini::IniFile& ini) {
  TaskConfig c;
  for (int i = 0; i < 64; ++i) {
    const auto v = ini.find("MDI_COMMAND_LIST", "MDI_COMMAND_MACRO" + std::to_string(i));
    if (!v) break;
    c.mdi_macros.push_back(*v);
  }
  c.on_abort_command = ini.get_string("RS274NGC", "ON_ABORT_COMMAND", "");
  // Read (and checked) at start-up: a bad value stops the start with the
  // file, line and key, never a running controller.
  for (int s = 0; s < ipc::kMaxSpindles; ++s) {
    c.spindle_increment[static_cast<std::size_t>(s)] =
        ini.get_double("SPINDLE_" + std::to_string(s), "INCREMENT", 100, {0, 1e6});
  }
  return c;
}

using namespace detail;


TaskController::TaskController(const ini::IniFile& ini, hal::Hal& hal, motion::MotionComponent& motion,
                               io::IoController& io, MessageQueue& messages)
    : ini_(ini), hal_(hal), motion_(motion), io_(io), messages_(messages), cfg_(TaskConfig::from_ini(ini)) {
  ms_ = motion_.status();
  canon_cfg_ = canon_config(ini, motion_.config(), ms_.traj.axis_mask);
  view_.tools = &io_.table();
  view_.tool_in_spindle = io_.tool_in_spindle();
  view_.position = ms_.traj.position;
  view_limits(view_);
  canon_ = std::make_unique<TaskCanon>(canon_cfg_, items_, view_);
  canon_->on_print = [this](std::string_view t) { post(MessageKind::Text, std::string(t)); };
  interp_config_ = interp::Config::from_ini(ini);
  interp_config_.axis_mask = ms_.traj.axis_mask;
  interp_config_.spindles = std::max(1, motion_.config().spindles);  // motion owns [TRAJ]SPINDLES
  interp_config_.task = true;  // #<_task> is 1 and M99 in the main program starts it again, as in LinuxCNC's task
  python_ = interp::python_settings(ini);
  interp_ = make_interpreter(*canon_);
  try {
    interp_->init();
  } catch (const interp::InterpError& e) {
    const bool params = !interp_config_.parameter_file.empty() && e.file() == interp_config_.parameter_file.string();
    throw ConfigError(e.file().empty() ? ini.path().string() : e.file(), e.line(),
                      std::string(params                                ? "[RS274NGC]PARAMETER_FILE: "
                                  : e.message().starts_with("[PYTHON]") ? ""
                                                                        : "[RS274NGC]RS274NGC_STARTUP_CODE: ") +
                          e.message());
  }
  items_.clear();
  canon_->set_end_position(ms_.traj.position);
}

std::unique_ptr<interp::Interpreter> TaskController::make_interpreter(interp::Canon& canon) const {
  interp::Config cfg = interp_config_;
  cfg.script = interp::make_python_host(python_);
  return std::make_unique<interp::Interpreter>(canon, std::move(cfg));
}

TaskController::~TaskController() {
  if (interp_) {
    if (const std::string unsaved = save_parameters(); !unsaved.empty()) std::fprintf(stderr, "cncd: %s\n", unsaved.c_str());
  }
  if (user_m_pid_ > 0) {
    ::kill(user_m_pid_, SIGTERM);
    ::waitpid(user_m_pid_, nullptr, 0);
  }
}

void TaskController::post(MessageKind kind, const std::string& text) { messages_.post(kind, "task", text); }

void TaskController::view_limits(MachineView& view) const { task::view_limits(ms_, view); }

void TaskController::report_spindle_limits() {
  for (int s = 0; s < ms_.traj.spindles && s < ipc::kMaxSpindles; ++s) {
    const ipc::SpindleStatus& sp = ms_.spindles[s];
    bool& said = spindle_limited_[static_cast<std::size_t>(s)];
    if (!sp.speed_limited || !sp.enabled) {
      said = false;
      continue;
    }
    if (said) continue;
    said = true;
    const double asked = sp.speed * sp.override_scale;
    const bool reverse = asked < 0;
    const double out = std::fabs(sp.speed_out), want = std::fabs(asked);
    const std::string key = "[SPINDLE_" + std::to_string(s) + "]" +
                            (want > out ? (reverse ? "MAX_REVERSE_VELOCITY" : "MAX_FORWARD_VELOCITY")
                                        : (reverse ? "MIN_REVERSE_VELOCITY" : "MIN_FORWARD_VELOCITY"));
    post(MessageKind::Text, "spindle " + std::to_string(s) + ": " + figure(want) + " rpm (" +
                                figure(std::fabs(sp.speed)) + " rpm x " + figure(sp.override_scale * 100) +
                                " %) is " + (want > out ? "above " : "below ") + key + " " +
                                figure(want > out ? (reverse ? sp.max_reverse : sp.max_forward)
                                                         : (reverse ? sp.min_reverse : sp.min_forward)) +
                                " rpm: the spindle is commanded " + figure(out) + " rpm" +
                                (reverse ? " in reverse" : ""));
  }
}

void TaskController::report_jog_limit(const motion::MotionCommand& m) {
  const double asked = std::fabs(m.value[0]) * ms_.traj.feed_scale;
  double limit = 0;
  std::string what;
  if (m.axis_mode) {
    if (m.joint < 0 || m.joint >= kNumAxes) return;
    limit = ms_.axes[m.joint].velocity_limit;
    what = std::string("axis ") + kAxisLetters[m.joint];
  } else {
    if (m.joint < 0 || m.joint >= std::min(ms_.traj.joints, kMaxJoints)) return;
    limit = ms_.joints[m.joint].velocity_limit;
    what = "joint " + std::to_string(m.joint);
  }
  if (limit <= 0 || asked <= limit * (1 + 1e-9)) return;
  post(MessageKind::Text, "jog of " + what + " at " + figure(asked) + " units/s: limited to " +
                              figure(limit) + " units/s, the limit in force");
}

uint64_t TaskController::send(motion::MotionCommand c) {
  const uint64_t serial = motion_.submit(c);
  if (serial != 0) last_submitted_ = serial;
  return serial;
}

const motion::MotionResult* TaskController::motion_result(uint64_t serial) const {
  const auto it = results_.find(serial);
  return it == results_.end() ? nullptr : &it->second;
}

bool TaskController::motion_idle() const {
  return last_answered_ >= last_submitted_ && ms_.last_serial >= last_submitted_ && ms_.tp_done && ms_.traj.inpos;
}

bool TaskController::machine_homed() const { return ms_.all_homed; }

void TaskController::answer_after(const ipc::Command& cmd, uint64_t serial, std::function<bool()> also_wait) {
  waiters_.push_back(Waiter{cmd, [this, cmd, serial, also_wait]() {
                              if (serial == 0) {
                                reporter_->report(cmd, CommandState::Rejected, "the motion command queue is full");
                                return true;
                              }
                              if (!motion_answered(serial)) {
                                // Motion stands still: no answer is coming
                                // (its queue drops what it held when it runs again).
                                if (!motion_.servo_stalled()) return false;
                                reporter_->report(cmd, CommandState::Rejected,
                                                  "motion is not running: " + motion_.stall_reason());
                                return true;
                              }
                              const motion::MotionResult* r = motion_result(serial);
                              if (r && !r->accepted) {
                                reporter_->report(cmd, CommandState::Rejected, r->reason.view());
                                return true;
                              }
                              if (also_wait && !also_wait()) return false;
                              reporter_->report(cmd, CommandState::Done);
                              return true;
                            }});
}

void TaskController::ensure_motion_mode(ipc::MotionMode m) {
  if (ms_.traj.mode == m) return;
  motion::MotionCommand c;
  c.type = m == ipc::MotionMode::Free ? Cmd::Free : m == ipc::MotionMode::Teleop ? Cmd::Teleop : Cmd::Coord;
  send(c);
}

}  // namespace cnc::task
