#include "core/task/task_controller.hpp"

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

namespace {

CanonConfig canon_config(const ini::IniFile& ini, const motion::MotionConfig& m, uint32_t axis_mask) {
  CanonConfig c;
  c.machine_units_per_mm = m.linear_units_per_mm;
  c.axis_mask = axis_mask;
  if (const auto pos = ini.find("EMCIO", "TOOL_CHANGE_POSITION")) {
    const auto words = split_blanks(*pos);
    c.has_tool_change_position = true;
    for (std::size_t i = 0; i < words.size() && i < static_cast<std::size_t>(kNumAxes); ++i) {
      const auto v = parse_double(words[i]);
      if (!v) ini.fail(ini.find_entry("EMCIO", "TOOL_CHANGE_POSITION"), "expected numbers X Y Z [A B C ...]");
      c.tool_change_position[static_cast<int>(i)] = *v;
    }
  }
  c.tool_change_quill_up = ini.get_bool("EMCIO", "TOOL_CHANGE_QUILL_UP", false);
  return c;
}

// A figure for a message: six significant digits ("55000", not "55000.00000000001").
std::string figure(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// "process 1234 (cnc)": who asked, for the message channel.
std::string describe_process(int32_t pid) {
  if (pid <= 0) return "an unknown process";
  std::ifstream in("/proc/" + std::to_string(pid) + "/comm");
  std::string name;
  std::getline(in, name);
  return "process " + std::to_string(pid) + " (" + (name.empty() ? std::string("no longer running") : name) + ")";
}

// Lines of a program the interpreter has just opened (for the status);
// a regular file only, like everything the interpreter reads.
int count_lines(const std::string& path) {
  int fd = -1;
  try {
    fd = interp::open_regular_file(path);
  } catch (const interp::InterpError&) {
    return 0;  // replaced since the interpreter opened it: the count is not known
  }
  int n = 0;
  char buf[65536];
  for (;;) {
    const ssize_t got = ::read(fd, buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    for (ssize_t i = 0; i < got; ++i) n += buf[i] == '\n' ? 1 : 0;
  }
  ::close(fd);
  return n;
}

// Reading and executing per task cycle, in the program, MDI, run from line
// and its preview.
constexpr int64_t kReadBudgetNs = 2'000'000;

// An interpreter error as the message channel shows it: file:line: text,
// without the file for an MDI line.
std::string describe(const interp::InterpError& e) {
  if (e.file().empty() || e.file() == "<mdi>") return e.message();
  return e.file() + ":" + std::to_string(e.line()) + ": " + e.message();
}

}  // namespace

// Run from line in progress: what the lines before the target left behind.
struct TaskController::Reconstruction {
  int line = 0;
  bool done = false;
  std::string error;  // empty: done and running
  std::deque<Item> kept;
  Item spindle, flood, mist, tool_change, tool_offset;
  bool have_spindle = false, have_flood = false, have_mist = false, have_tool = false, have_offset = false;
};

// Run-from-line preview: a scratch interpreter stepped within the budget.
struct TaskController::PreviewJob {
  int line = 0;
  std::deque<Item> items;
  MachineView view;
  std::unique_ptr<TaskCanon> canon;
  std::unique_ptr<interp::Interpreter> interp;
};

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
  interp_config_.task = true;  // #<_task> is 1 and M99 in the main program starts it again, as in LinuxCNC's task
  interp_ = std::make_unique<interp::Interpreter>(*canon_, interp_config_);
  try {
    interp_->init();
  } catch (const interp::InterpError& e) {
    const bool params = !interp_config_.parameter_file.empty() && e.file() == interp_config_.parameter_file.string();
    throw ConfigError(e.file().empty() ? ini.path().string() : e.file(), e.line(),
                      std::string(params ? "[RS274NGC]PARAMETER_FILE: " : "[RS274NGC]RS274NGC_STARTUP_CODE: ") +
                          e.message());
  }
  items_.clear();
  canon_->set_end_position(ms_.traj.position);
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

void TaskController::view_limits(MachineView& view) const {
  view.max_linear_velocity = ms_.traj.max_linear_velocity;
  view.max_linear_acceleration = ms_.traj.max_linear_acceleration;
  // The fastest an axis may go bounds rapids when [TRAJ] gives no maximum.
  double rapid = ms_.traj.max_linear_velocity;
  if (!(rapid < 1e98)) {
    rapid = 0;
    for (int a = 0; a < kNumAxes; ++a) {
      if (ms_.traj.axis_mask & (1u << a)) rapid = std::max(rapid, ms_.axes[a].velocity_limit);
    }
  }
  view.rapid_velocity = rapid > 0 ? rapid : 1;
  if (!(view.max_linear_velocity < 1e98)) view.max_linear_velocity = view.rapid_velocity;
}

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

// ------------------------------------------------------------ commands

bool TaskController::handle_command(const ipc::Command& cmd, ipc::CommandReporter& reporter) {
  reporter_ = &reporter;
  const std::size_t waiters_before = waiters_.size();
  std::string why;
  const bool idle = interp_state_ == ipc::InterpState::Idle && mdi_queue_.empty() && !running_mdi_;
  const auto need_on = [&]() -> std::string {
    if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
    return {};
  };
  const auto motion_cmd = [&](Cmd type, double v0 = 0, double v1 = 0, int joint = 0) {
    motion::MotionCommand c;
    c.type = type;
    c.value[0] = v0;
    c.value[1] = v1;
    c.joint = static_cast<int16_t>(joint);
    answer_after(cmd, send(c));
  };
  switch (cmd.type) {
    case CommandType::TaskSetState: why = set_state(cmd); break;
    case CommandType::AuxEstopOn: {
      ipc::Command c = cmd;
      c.i[0] = static_cast<int>(ipc::TaskState::Estop);
      why = set_state(c);
      break;
    }
    case CommandType::AuxEstopReset: {
      ipc::Command c = cmd;
      c.i[0] = static_cast<int>(ipc::TaskState::EstopReset);
      why = set_state(c);
      break;
    }
    case CommandType::TaskSetMode: why = set_mode(cmd); break;
    case CommandType::TaskAbort: abort_all("aborted by the operator", true); break;
    case CommandType::TaskPlanOpen:
      if (!idle) why = "a program or MDI is running: abort it first";
      else why = program_open(std::string(cmd.text.view()));
      break;
    case CommandType::TaskPlanClose:
      if (!idle) why = "a program or MDI is running: abort it first";
      else {
        interp_->close();
        file_.clear();
        total_lines_ = 0;
      }
      break;
    case CommandType::TaskPlanRun: why = program_run(cmd); break;
    case CommandType::TaskPlanRunPreview:
      if (!idle) why = "a program or MDI is running";
      else why = run_from_line_preview(cmd);
      break;
    case CommandType::TaskPlanPause:
      if (interp_state_ == ipc::InterpState::Idle && !running_mdi_) why = "nothing is running to pause";
      else pause(true);
      break;
    case CommandType::TaskPlanResume:
      if (!paused_) why = "nothing is paused";
      else resume();
      break;
    case CommandType::TaskPlanStep:
      if (paused_) {
        stepping_ = true;
        resume();
      } else if (interp_state_ == ipc::InterpState::Idle) {
        ipc::Command run = cmd;
        run.i[0] = 0;
        stepping_ = true;
        why = program_run(run);
        if (!why.empty()) stepping_ = false;
      } else {
        why = "stepping works from a paused or stopped program";
      }
      break;
    case CommandType::TaskPlanExecute: why = mdi(cmd); break;
    case CommandType::TaskPlanInit:
      if (!idle) why = "a program or MDI is running: abort it first";
      else {
        interp_->reset();
        items_.clear();
      }
      break;
    case CommandType::TaskPlanSynch:
      if (!idle) why = "a program or MDI is running";
      else interp_->synch();
      break;
    case CommandType::TaskPlanSetOptionalStop: optional_stop_ = cmd.i[0] != 0; break;
    case CommandType::TaskPlanSetBlockDelete:
      block_delete_ = cmd.i[0] != 0;  // takes effect when a program starts
      if (!idle) why = "block delete changes take effect when the program is next started";
      break;
    case CommandType::TrajSetScale: motion_cmd(Cmd::Scale, cmd.d[0]); break;
    case CommandType::TrajSetRapidScale: motion_cmd(Cmd::RapidScale, cmd.d[0]); break;
    case CommandType::TrajSetMaxVelocity: motion_cmd(Cmd::MaxVelocity, cmd.d[0]); break;
    case CommandType::TrajSetFeedHoldEnable: motion_cmd(Cmd::FeedHoldEnable, cmd.i[0]); break;
    case CommandType::TrajSetFeedOverrideEnable: motion_cmd(Cmd::FeedOverrideEnable, cmd.i[0]); break;
    case CommandType::TrajSetAdaptiveFeedEnable: motion_cmd(Cmd::AdaptiveFeedEnable, cmd.i[0]); break;
    case CommandType::TrajClearProbeTripped: motion_cmd(Cmd::ClearProbeFlag); break;
    case CommandType::TrajSetTeleopEnable:
      if (!(why = need_on()).empty()) break;
      if (!idle) { why = "a program or MDI is running"; break; }
      motion_cmd(cmd.i[0] ? Cmd::Teleop : Cmd::Free);
      break;
    case CommandType::MotionSetDigitalOutput: motion_cmd(Cmd::SetDigitalOut, cmd.i[1], 0, cmd.i[0]); break;
    case CommandType::MotionSetAnalogOutput: motion_cmd(Cmd::SetAnalogOut, cmd.d[0], 0, cmd.i[0]); break;
    case CommandType::JogCont:
    case CommandType::JogIncr:
    case CommandType::JogAbs:
    case CommandType::JogStop: why = jog(cmd); break;
    case CommandType::JointHome: why = home(cmd); break;
    case CommandType::JointUnhome:
      if (!idle) { why = "a program or MDI is running"; break; }
      motion_cmd(Cmd::Unhome, 0, 0, cmd.i[0]);
      break;
    case CommandType::JointOverrideLimits: motion_cmd(Cmd::OverrideLimits, 1); break;
    case CommandType::JointActivate: motion_cmd(Cmd::ActivateJoint, 0, 0, cmd.i[0]); break;
    case CommandType::JointDeactivate: motion_cmd(Cmd::DeactivateJoint, 0, 0, cmd.i[0]); break;
    case CommandType::JointLoadComp:
      why = "compensation tables are read from [JOINT_n]COMP_FILE at start-up; loading them at run time is not available yet";
      break;
    case CommandType::SetParameter: why = set_parameter(cmd); break;
    case CommandType::MotionEnable:
    case CommandType::MotionDisable:
      why = "motion is enabled and disabled by the machine state: use 'on' and 'off'";
      break;
    case CommandType::SpindleOn:
    case CommandType::SpindleOff:
    case CommandType::SpindleIncrease:
    case CommandType::SpindleDecrease:
    case CommandType::SpindleConstant: {
      if (!(why = need_on()).empty()) break;
      if (interp_state_ != ipc::InterpState::Idle && cmd.type != CommandType::SpindleOff) {
        why = "the program controls the spindle while it runs";
        break;
      }
      const int s = cmd.i[0];
      if (s < 0 || s >= ipc::kMaxSpindles) { why = "no spindle " + std::to_string(s); break; }
      const ipc::SpindleStatus& sp = ms_.spindles[s];
      const double increment = cfg_.spindle_increment[static_cast<std::size_t>(s)];
      double rpm = sp.enabled ? sp.speed : 0;
      if (cmd.type == CommandType::SpindleOn) rpm = cmd.d[0];
      if (cmd.type == CommandType::SpindleOff) rpm = 0;
      if (cmd.type == CommandType::SpindleIncrease) rpm += rpm >= 0 ? increment : -increment;
      if (cmd.type == CommandType::SpindleDecrease) rpm -= rpm >= 0 ? increment : -increment;
      motion_cmd(Cmd::SetSpindle, rpm, rpm != 0 ? 1 : 0, s);
      break;
    }
    case CommandType::SpindleBrakeRelease: motion_cmd(Cmd::SpindleBrake, 0, 0, cmd.i[0]); break;
    case CommandType::SpindleBrakeEngage: motion_cmd(Cmd::SpindleBrake, 1, 0, cmd.i[0]); break;
    case CommandType::SpindleOrient: motion_cmd(Cmd::SpindleOrient, cmd.d[0], cmd.i[1], cmd.i[0]); break;
    case CommandType::SpindleOverride: motion_cmd(Cmd::SpindleOverride, cmd.d[0], 0, cmd.i[0]); break;
    case CommandType::CoolantMistOn:
    case CommandType::CoolantMistOff:
    case CommandType::CoolantFloodOn:
    case CommandType::CoolantFloodOff:
    case CommandType::LubeOn:
    case CommandType::LubeOff: {
      const bool on = cmd.type == CommandType::CoolantMistOn || cmd.type == CommandType::CoolantFloodOn ||
                      cmd.type == CommandType::LubeOn;
      if (on && !(why = need_on()).empty()) break;
      if (cmd.type == CommandType::CoolantMistOn || cmd.type == CommandType::CoolantMistOff) io_.set_mist(on);
      else if (cmd.type == CommandType::LubeOn || cmd.type == CommandType::LubeOff) io_.set_lube(on);
      else io_.set_flood(on);
      break;
    }
    case CommandType::ToolLoadTable:
    case CommandType::ToolSetOffset:
    case CommandType::ToolSetNumber:
    case CommandType::ToolDelete:
      if (!idle) why = "a program or MDI is running: the tool table changes when it has ended";
      else why = tool_command(cmd);
      break;
    case CommandType::SetWorkOffset: {
      if (!idle) { why = "a program or MDI is running"; break; }
      const int idx = cmd.i[0];
      std::string line;
      char buf[64];
      if (idx >= 1 && idx <= 9) {
        line = "G10 L2 P" + std::to_string(idx);
        for (int a = 0; a < kNumAxes; ++a) {
          if (!(ms_.traj.axis_mask & (1U << a))) continue;
          std::snprintf(buf, sizeof buf, " %c%.10g", kAxisLetters[a], cmd.d[a]);
          line += buf;
        }
        std::snprintf(buf, sizeof buf, " R%.10g", cmd.d[9]);
        line += buf;
      } else if (idx == 0) {
        for (int a = 0; a < kNumAxes; ++a) {
          std::snprintf(buf, sizeof buf, "#%d=%.10g ", 5211 + a, cmd.d[a]);
          line += buf;
        }
        line += "G92.3";
      } else {
        why = "work offset index " + std::to_string(idx) + ": expected 0 (G92) or 1..9 (G54..G59.3)";
        break;
      }
      try {
        interp_->execute(line);
        items_.clear();  // offsets only: nothing for motion
        why = save_parameters();
      } catch (const interp::InterpError& e) {
        why = e.message();
      }
      break;
    }
    default:
      reporter_ = &reporter;
      return false;
  }
  if (!why.empty()) reporter.report(cmd, CommandState::Rejected, why);
  else if (waiters_.size() > waiters_before) reporter.report(cmd, CommandState::Executing);
  else reporter.report(cmd, CommandState::Done);
  return true;
}

std::string TaskController::set_state(const ipc::Command& c) {
  switch (static_cast<ipc::TaskState>(c.i[0])) {
    case ipc::TaskState::Estop:
      enter_estop("E-stop by the operator (" + describe_process(c.client_pid) + ")");
      return {};
    case ipc::TaskState::EstopReset: {
      if (state_ != ipc::TaskState::Estop) return {};
      if (motion_.servo_stalled()) return "cannot reset the E-stop: " + motion_.stall_reason();
      io_.set_user_enable(true, true);
      const int64_t deadline = monotonic_ns() + static_cast<int64_t>(io::IoConfig::from_ini(ini_).estop_reset_timeout_s * 1e9);
      // The chain closes, then motion clears its E-stop latch (which it
      // refuses while the chain is open): only then is the E-stop reset.
      waiters_.push_back(Waiter{c, [this, c, deadline, serial = uint64_t{0}]() mutable {
                                  const auto refuse = [&](std::string_view why) {
                                    io_.set_user_enable(false);
                                    reporter_->report(c, CommandState::Rejected, why);
                                    return true;
                                  };
                                  if (serial == 0) {
                                    if (!io_.estop_chain_closed()) {
                                      if (monotonic_ns() <= deadline) return false;
                                      return refuse("the E-stop chain did not close (iocontrol.0.emc-enable-in stayed "
                                                    "false): check the E-stop buttons and the HAL E-stop loop");
                                    }
                                    motion::MotionCommand reset;
                                    reset.type = Cmd::EstopReset;
                                    serial = send(reset);
                                    if (serial == 0) return refuse("the motion command queue is full");
                                    return false;
                                  }
                                  if (!motion_answered(serial) || ms_.last_serial < serial) return false;
                                  if (const motion::MotionResult* r = motion_result(serial); r && !r->accepted) {
                                    return refuse(r->reason.view());
                                  }
                                  if (ms_.traj.estop_latched) {
                                    return refuse(std::string("E-stop latched again (") +
                                                  ipc::to_string(ms_.traj.estop_cause) + ") as it was reset");
                                  }
                                  state_ = ipc::TaskState::EstopReset;
                                  reporter_->report(c, CommandState::Done);
                                  return true;
                                }});
      return {};
    }
    case ipc::TaskState::Off:
      if (state_ == ipc::TaskState::Estop) return "the machine is in E-stop";
      if (state_ == ipc::TaskState::On) machine_off("machine off");
      state_ = ipc::TaskState::Off;
      return {};
    case ipc::TaskState::On: {
      if (state_ == ipc::TaskState::Estop) return "the machine is in E-stop: reset it first (estop-reset)";
      if (state_ == ipc::TaskState::On) return {};
      motion::MotionCommand en;
      en.type = Cmd::Enable;
      const uint64_t serial = send(en);
      // The machine is on once motion is enabled and every amplifier has
      // answered the enable (joint.N.amp-ready-in): homing or a jog sent
      // right after "on" then finds drives that follow. If motion gets
      // disabled meanwhile (an amplifier fault, or one not ready within its
      // AMP_READY_TIMEOUT) the command is refused; the fault is on the
      // error channel.
      if (serial == 0) return "the motion command queue is full";
      waiters_.push_back(Waiter{c, [this, c, serial, waiting_joint = -1]() mutable {
                                  if (ms_.last_serial < serial || !motion_answered(serial)) return false;
                                  const motion::MotionResult* r = motion_result(serial);
                                  if (r && !r->accepted) {
                                    reporter_->report(c, CommandState::Rejected, r->reason.view());
                                    return true;
                                  }
                                  if (ms_.traj.enabled && !ms_.amps_ready) {
                                    if (ms_.amp_waiting_joint >= 0) waiting_joint = ms_.amp_waiting_joint;
                                    return false;
                                  }
                                  if (ms_.traj.enabled) {
                                    state_ = ipc::TaskState::On;
                                    was_enabled_ = true;
                                    reporter_->report(c, CommandState::Done);
                                    return true;
                                  }
                                  std::string why = "motion was disabled as the machine was turned on";
                                  if (waiting_joint >= 0) {
                                    why += " (joint " + std::to_string(waiting_joint) +
                                           "'s amplifier was not ready yet)";
                                  }
                                  reporter_->report(c, CommandState::Rejected, why + ": see the error channel");
                                  return true;
                                }});
      return {};
    }
  }
  return "unknown state " + std::to_string(c.i[0]) + ": expected 1 (E-stop), 2 (reset), 3 (off) or 4 (on)";
}

std::string TaskController::set_mode(const ipc::Command& c) {
  const auto target = static_cast<ipc::TaskMode>(c.i[0]);
  if (target != ipc::TaskMode::Manual && target != ipc::TaskMode::Auto && target != ipc::TaskMode::Mdi) {
    return "unknown mode " + std::to_string(c.i[0]) + ": expected 1 (MANUAL), 2 (AUTO) or 3 (MDI)";
  }
  if (target == mode_) return {};
  if (interp_state_ != ipc::InterpState::Idle || running_mdi_ || !mdi_queue_.empty()) {
    return std::string("cannot change to ") + ipc::to_string(target) + " mode while a program or MDI runs: abort it first";
  }
  if (target == ipc::TaskMode::Manual) {
    mode_ = target;
    if (ms_.traj.mode == ipc::MotionMode::Coord && ms_.tp_done) ensure_motion_mode(ipc::MotionMode::Free);
    return {};
  }
  if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
  if (!machine_homed() && !motion_.config().no_force_homing) {
    return std::string("home all joints before ") + ipc::to_string(target) + " (or set [TRAJ]NO_FORCE_HOMING = 1)";
  }
  motion::MotionCommand m;
  m.type = Cmd::Coord;
  answer_after(c, send(m), [this, target]() {
    mode_ = target;
    return true;
  });
  return {};
}

std::string TaskController::jog(const ipc::Command& c) {
  motion::MotionCommand m;
  m.type = c.type == CommandType::JogCont   ? Cmd::JogCont
           : c.type == CommandType::JogIncr ? Cmd::JogIncr
           : c.type == CommandType::JogAbs  ? Cmd::JogAbs
                                            : Cmd::JogStop;
  m.joint = static_cast<int16_t>(c.i[0]);
  m.axis_mode = c.i[1] == 0;
  m.value[0] = c.d[0];
  m.value[1] = c.d[1];
  if (m.type != Cmd::JogStop) {
    if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
    if (mode_ != ipc::TaskMode::Manual) return std::string("jogging needs MANUAL mode (now ") + ipc::to_string(mode_) + ")";
  }
  if (m.axis_mode && !machine_homed() && m.type != Cmd::JogStop) {
    // Before homing an axis jog moves the one joint of that axis, if there
    // is exactly one (trivial kinematics); otherwise joints must be jogged.
    int joint = -1, count = 0;
    for (int j = 0; j < ms_.traj.joints; ++j) {
      if (ms_.joints[j].axis == c.i[0]) {
        joint = j;
        ++count;
      }
    }
    if (count != 1) {
      return std::string("axis ") + kAxisLetters[std::clamp(c.i[0], 0, 8)] +
             " cannot be jogged before homing (its joints are coupled): jog joints, or home first";
    }
    m.joint = static_cast<int16_t>(joint);
    m.axis_mode = false;
  }
  if (m.type != Cmd::JogStop) {
    ensure_motion_mode(m.axis_mode ? ipc::MotionMode::Teleop : ipc::MotionMode::Free);
    report_jog_limit(m);
  } else if (m.axis_mode != (ms_.traj.mode == ipc::MotionMode::Teleop)) {
    // A stop for the other kind of jog: stop whatever moves.
    m.axis_mode = ms_.traj.mode == ipc::MotionMode::Teleop;
  }
  answer_after(c, send(m));
  return {};
}

std::string TaskController::home(const ipc::Command& c) {
  if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
  if (mode_ != ipc::TaskMode::Manual) return std::string("homing needs MANUAL mode (now ") + ipc::to_string(mode_) + ")";
  const int joint = c.i[0];
  ensure_motion_mode(ipc::MotionMode::Free);
  motion::MotionCommand m;
  m.type = Cmd::Home;
  m.joint = static_cast<int16_t>(joint);
  const uint64_t serial = send(m);
  answer_after(c, serial, [this, joint, serial]() {
    if (ms_.last_serial < serial) return false;
    if (ms_.any_homing) return false;
    const bool ok = joint < 0 ? ms_.all_homed || [&] {
      // home all: every joint with a sequence is homed
      return true;
    }() : ms_.joints[joint].homed;
    if (!ok) {
      // Report the failure as a rejection with the motion's reason.
      return true;
    }
    return true;
  });
  // Replace the generic answer with one that knows about failures.
  waiters_.back().check = [this, c, joint, serial]() {
    if (serial == 0) {
      reporter_->report(c, CommandState::Rejected, "the motion command queue is full");
      return true;
    }
    if (!motion_answered(serial)) return false;
    if (const motion::MotionResult* r = motion_result(serial); r && !r->accepted) {
      reporter_->report(c, CommandState::Rejected, r->reason.view());
      return true;
    }
    if (ms_.last_serial < serial || ms_.any_homing) return false;
    const bool homed = joint < 0 ? ms_.all_homed : ms_.joints[joint].homed;
    if (homed || (joint < 0 && !ms_.faulted)) {
      reporter_->report(c, CommandState::Done);
    } else {
      reporter_->report(c, CommandState::Rejected,
                        joint < 0 ? "homing failed (see the error messages)"
                                  : "homing of joint " + std::to_string(joint) + " failed (see the error messages)");
    }
    return true;
  };
  return {};
}

std::string TaskController::set_parameter(const ipc::Command& c) {
  const auto idx = motion::find_param(c.text.view());
  if (!idx) {
    std::size_t n = 0;
    const motion::ParamSpec* t = motion::param_table(n);
    std::string names;
    for (std::size_t i = 0; i < n; ++i) names += (i ? ", " : "") + std::string(t[i].name);
    return "unknown parameter \"" + std::string(c.text.view()) + "\"; known: " + names;
  }
  motion::MotionCommand m;
  m.type = Cmd::SetParameter;
  m.param = *idx;
  m.joint = static_cast<int16_t>(c.i[0]);
  m.value[0] = c.d[0];
  answer_after(c, send(m));
  return {};
}

std::string TaskController::tool_command(const ipc::Command& c) {
  const char* err = nullptr;
  switch (c.type) {
    case CommandType::ToolLoadTable:
      err = io_.reload_table();
      break;
    case CommandType::ToolSetOffset: {
      tooltable::Tool t;
      t.number = c.i[0];
      const auto existing = io_.table().find_tool_anywhere(t.number);
      if (existing) t = io_.table().at(*existing);
      t.number = c.i[0];
      if (c.i[1] >= 0) t.pocket = c.i[1];
      else if (!existing) return "tool " + std::to_string(c.i[0]) + " is new: give its pocket";
      for (int a = 0; a < kNumAxes; ++a) t.offset[a] = c.d[a];
      t.diameter = c.d[9];
      t.front_angle = c.d[10];
      t.back_angle = c.d[11];
      t.orientation = c.i[2];
      if (!c.text.empty()) t.comment = std::string(c.text.view());
      err = io_.update_tool(t);
      break;
    }
    case CommandType::ToolSetNumber: {
      int index = 0;
      if (c.i[0] != 0) {
        const auto idx = io_.table().find_tool_anywhere(c.i[0]);
        if (!idx) return "tool " + std::to_string(c.i[0]) + " is not in the tool table";
        index = *idx;
      }
      err = io_.set_tool_number(index);
      break;
    }
    case CommandType::ToolDelete:
      err = io_.delete_tool(c.i[0]);
      break;
    default:
      return "not a tool command";
  }
  if (err) return err;
  view_.tool_in_spindle = io_.tool_in_spindle();
  interp_->synch();  // the interpreter re-reads the table
  return {};
}

std::string TaskController::program_open(const std::string& path) {
  // A regular file only: a FIFO, a device or a folder is refused here
  // without blocking (the interpreter checks the same when it opens it).
  try {
    ::close(interp::open_regular_file(path));
  } catch (const interp::InterpError& e) {
    return "cannot read program " + path + ": " + e.message();
  }
  try {
    interp_->open(path);
  } catch (const interp::InterpError& e) {
    return describe(e);
  }
  file_ = path;
  total_lines_ = count_lines(path);
  read_line_ = current_line_ = 0;
  return {};
}

std::string TaskController::program_run(const ipc::Command& c) {
  if (mode_ != ipc::TaskMode::Auto) return std::string("running a program needs AUTO mode (now ") + ipc::to_string(mode_) + ")";
  if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
  if (interp_state_ != ipc::InterpState::Idle) return "a program is already running";
  if (file_.empty()) return "no program is open";
  if (!machine_homed() && !motion_.config().no_force_homing) return "home all joints before running a program";
  if (!motion_idle()) return "the machine is still moving";
  items_.clear();
  try {
    if (interp_config_.block_delete != block_delete_) {
      // The interpreter takes block delete from its configuration: start a
      // fresh one (parameters go through the parameter file).
      if (const std::string unsaved = save_parameters(); !unsaved.empty()) return unsaved;
      interp_config_.block_delete = block_delete_;
      interp_ = std::make_unique<interp::Interpreter>(*canon_, interp_config_);
      interp_->init();
      items_.clear();
    }
    interp_->reset();
    interp_->open(file_);
  } catch (const interp::InterpError& e) {
    return e.message();
  }
  // The interpreter starts where the machine stands, not where its reset
  // left it (machine zero): otherwise the first move would carry every axis
  // the program does not name back to 0.
  view_.position = ms_.traj.position;
  canon_->set_end_position(ms_.traj.position);
  interp_->synch();
  program_started_ns_ = monotonic_ns();
  program_elapsed_ns_ = 0;
  blocks_ = 0;
  errors_ = 0;
  program_ended_ = false;
  waiting_synch_ = false;
  paused_ = false;
  interp_state_ = ipc::InterpState::Reading;
  const int start = c.i[0];
  if (start > 1) {
    // Reconstructed stepwise in the task cycles that follow (the lines
    // before may be many, or loop); the command is answered when it is done.
    reconstruct_ = std::make_shared<Reconstruction>();
    reconstruct_->line = start;
    waiters_.push_back(Waiter{c, [this, c, r = reconstruct_]() {
                                if (!r->done) return false;
                                if (r->error.empty()) reporter_->report(c, CommandState::Done);
                                else reporter_->report(c, CommandState::Rejected, r->error);
                                return true;
                              }});
  }
  post(MessageKind::Text, "running " + file_ + (start > 1 ? " from line " + std::to_string(start) : ""));
  return {};
}

bool TaskController::reconstruct_step(int64_t deadline) {
  Reconstruction& r = *reconstruct_;
  try {
    for (;;) {
      const interp::Status rs = interp_->read();
      if (rs == interp::Status::Yield) {
        if (monotonic_ns() > deadline) return false;
        continue;
      }
      if (rs == interp::Status::SynchRequired) {
        canon_->set_end_position(canon_->end_position());
        interp_->synch();
        continue;
      }
      if (rs == interp::Status::ProgramEnd || rs == interp::Status::EndOfFile) {
        reconstruction_failed("run from line " + std::to_string(r.line) + ": the program ends before that line");
        return false;
      }
      if (interp_->line() >= r.line) break;
      interp_->execute();
      for (Item& it : items_) {
        switch (it.kind) {
          case Item::Kind::MotionAtRest:
            if (it.motion.type == Cmd::SetSpindle) {
              r.spindle = it;
              r.have_spindle = true;
            } else {
              r.kept.push_back(it);  // override enables
            }
            break;
          case Item::Kind::Motion:
            if (it.motion.type == Cmd::SetToolOffset) {
              r.tool_offset = it;
              r.have_offset = true;
            }
            break;
          case Item::Kind::Flood: r.flood = it; r.have_flood = true; break;
          case Item::Kind::Mist: r.mist = it; r.have_mist = true; break;
          case Item::Kind::ToolChange:
          case Item::Kind::ToolNumber: r.tool_change = it; r.have_tool = true; break;
          case Item::Kind::ToolSetEntry: r.kept.push_back(it); break;
          default: break;
        }
      }
      items_.clear();
      if (interp_->is_synch_pending()) interp_->synch();
      if (monotonic_ns() > deadline) return false;
    }
  } catch (const interp::InterpError& e) {
    reconstruction_failed(describe(e));
    return false;
  }
  finish_reconstruction();
  return reconstruct_ == nullptr && interp_state_ != ipc::InterpState::Idle;
}

void TaskController::reconstruction_failed(const std::string& what) {
  reconstruct_->error = "run from line " + std::to_string(reconstruct_->line) + " failed: " + what;
  program_error(what);  // aborts, which ends the reconstruction
}

// The block at the target line is read: queue what restores the state the
// lines before left (tool, offsets, coolant, spindle), an approach (up,
// over, down) to where the program would be, then execute that block.
void TaskController::finish_reconstruction() {
  const std::shared_ptr<Reconstruction> keep = reconstruct_;
  Reconstruction& r = *keep;
  const int line = r.line;
  const Pose target = canon_->end_position();
  run_from_start_ = target;
  items_ = std::move(r.kept);
  if (r.have_tool) {
    const int index = r.tool_change.i0;
    if (io_.table().at(index).number != io_.tool_in_spindle()) items_.push_back(r.tool_change);
  }
  if (r.have_offset) items_.push_back(r.tool_offset);
  if (r.have_flood) items_.push_back(r.flood);
  if (r.have_mist) items_.push_back(r.mist);
  if (r.have_spindle) items_.push_back(r.spindle);
  // Approach: up to the higher Z, across, then down at the feed.
  const Pose here = ms_.traj.position;
  Pose up = here;
  up[2] = std::max(here[2], target[2]);
  Pose over = target;
  over[2] = up[2];
  uint32_t id = canon_->next_id();
  for (const Pose& p : {up, over, target}) {
    Item it;
    it.kind = Item::Kind::Motion;
    it.motion.type = Cmd::SetLine;
    it.motion.end = p;
    it.motion.segment.type = &p == &target ? tp::MotionType::Feed : tp::MotionType::Traverse;
    it.motion.segment.feed = ms_.traj.max_linear_velocity < 1e98 ? ms_.traj.max_linear_velocity / 4 : 10;
    it.motion.segment.max_velocity = ms_.traj.max_linear_velocity;
    it.motion.segment.max_acceleration = ms_.traj.max_linear_acceleration;
    it.motion.segment.term = tp::TermCond::ExactStop;
    it.motion.segment.id = id++;
    it.motion.segment.line = line;
    items_.push_back(it);
  }
  canon_->set_id_base(id);
  r.done = true;  // the state is restored: the run command is answered
  reconstruct_.reset();
  // The block at `line` was read by the last step; execute it now.
  try {
    const interp::Status st = interp_->execute();
    if (st == interp::Status::ExecuteFinish) waiting_synch_ = true;
    if (st == interp::Status::ProgramEnd) {
      program_ended_ = true;
      interp_state_ = ipc::InterpState::Waiting;
    }
  } catch (const interp::InterpError& e) {
    program_error(describe(e));
  }
}

std::string TaskController::run_from_line_preview(const ipc::Command& c) {
  const int line = c.i[0];
  if (file_.empty()) return "no program is open";
  if (line < 1) return "run from line: the line must be 1 or more";
  // Interpret up to the line on a scratch interpreter, stepwise in the task
  // cycles that follow, and report where the program would be: the
  // approach shown before it is executed.
  auto job = std::make_shared<PreviewJob>();
  job->line = line;
  job->view = view_;
  job->canon = std::make_unique<TaskCanon>(canon_cfg_, job->items, job->view);
  job->canon->set_end_position(ms_.traj.position);
  job->interp = std::make_unique<interp::Interpreter>(*job->canon, interp_config_);
  try {
    job->interp->init();
    job->interp->open(file_);
  } catch (const interp::InterpError& e) {
    return describe(e);
  }
  waiters_.push_back(Waiter{c, [this, c, job]() { return preview_step(c, *job); }});
  return {};
}

bool TaskController::preview_step(const ipc::Command& c, PreviewJob& job) {
  const int64_t deadline = monotonic_ns() + kReadBudgetNs;
  interp::Interpreter& in = *job.interp;
  std::string error;
  try {
    for (;;) {
      const interp::Status rs = in.read();
      if (rs == interp::Status::Yield) {
        if (monotonic_ns() > deadline) return false;
        continue;
      }
      if (rs == interp::Status::SynchRequired) {
        in.synch();
        continue;
      }
      if (rs != interp::Status::Ok) {
        error = "run from line " + std::to_string(job.line) + ": the program ends before that line";
        break;
      }
      if (in.line() >= job.line) break;
      in.execute();
      job.items.clear();
      if (in.is_synch_pending()) in.synch();
      if (monotonic_ns() > deadline) return false;
    }
  } catch (const interp::InterpError& e) {
    error = describe(e);
  }
  if (!error.empty()) {
    reporter_->report(c, CommandState::Rejected, error);
    return true;
  }
  run_from_line_ = job.line;
  run_from_start_ = job.canon->end_position();
  char buf[200];
  std::snprintf(buf, sizeof buf, "run from line %d: approach up to Z%.4f, then to X%.4f Y%.4f, then down to Z%.4f (machine)",
                job.line, std::max(ms_.traj.position[2], run_from_start_[2]), run_from_start_[0], run_from_start_[1],
                run_from_start_[2]);
  post(MessageKind::Display, buf);
  reporter_->report(c, CommandState::Done);
  return true;
}

std::string TaskController::mdi(const ipc::Command& c) {
  if (mode_ != ipc::TaskMode::Mdi) return std::string("MDI needs MDI mode (now ") + ipc::to_string(mode_) + ")";
  if (state_ != ipc::TaskState::On) return std::string("the machine is not on (state ") + ipc::to_string(state_) + ")";
  if (interp_state_ != ipc::InterpState::Idle && !running_mdi_) return "a program is running";
  if (static_cast<int>(mdi_queue_.size()) >= cfg_.max_queued_mdi) {
    return "too many MDI commands queued (" + std::to_string(cfg_.max_queued_mdi) + ")";
  }
  std::vector<std::string> lines;
  if (c.i[0] >= 0) {
    if (c.i[0] >= static_cast<int>(cfg_.mdi_macros.size())) {
      return "no [MDI_COMMAND_LIST]MDI_COMMAND_MACRO" + std::to_string(c.i[0]) + " (there are " +
             std::to_string(cfg_.mdi_macros.size()) + ")";
    }
    std::string macro = cfg_.mdi_macros[static_cast<std::size_t>(c.i[0])];
    const auto comma = macro.find(',');
    if (comma != std::string::npos) macro = macro.substr(0, comma);  // the rest is the button label
    for (const auto& part : split(macro, ';', true)) lines.emplace_back(trim(part));
  } else {
    lines.emplace_back(trim(c.text.view()));
  }
  if (lines.empty() || lines.front().empty()) return "empty MDI command";
  for (const auto& l : lines) mdi_queue_.emplace_back(c, l);
  const uint32_t serial = c.serial;
  waiters_.push_back(Waiter{c, [this, c, serial]() {
                              for (const auto& q : mdi_queue_) {
                                if (q.first.serial == serial) return false;
                              }
                              if (running_mdi_ && mdi_current_.serial == serial) return false;
                              // Finished (errors were reported when they happened).
                              return true;
                            }});
  return {};
}

// ------------------------------------------------------------ running

void TaskController::stop_motion() {
  motion::MotionCommand a;
  a.type = Cmd::Abort;
  send(a);
  a.type = Cmd::Disable;
  send(a);
  a.type = Cmd::Unhome;
  a.joint = -2;  // VOLATILE_HOME joints forget their home
  send(a);
}

void TaskController::on_controller_shutdown() { enter_estop("E-stop: the controller is shutting down"); }

void TaskController::enter_estop(const std::string& why) {
  stop_motion();
  io_.set_user_enable(false);
  io_.set_flood(false);
  io_.set_mist(false);
  io_.set_lube(false);
  abort_all(why, true);
  if (state_ != ipc::TaskState::Estop) post(MessageKind::Text, why);
  state_ = ipc::TaskState::Estop;
  was_enabled_ = false;
}

void TaskController::machine_off(const std::string& why) {
  stop_motion();
  abort_all(why, true);
  state_ = ipc::TaskState::Off;
  was_enabled_ = false;
}

void TaskController::abort_all(const std::string& why, bool quiet) {
  const bool was_running = interp_state_ != ipc::InterpState::Idle || running_mdi_ || !mdi_queue_.empty();
  motion::MotionCommand a;
  a.type = Cmd::Abort;
  send(a);
  // Deterministic stop: spindle and coolant off on abort.
  if (was_running) {
    for (int s = 0; s < ms_.traj.spindles && s < ipc::kMaxSpindles; ++s) {
      motion::MotionCommand sp;
      sp.type = Cmd::SetSpindle;
      sp.joint = static_cast<int16_t>(s);
      send(sp);
    }
    io_.set_flood(false);
    io_.set_mist(false);
  }
  io_.abort();
  items_.clear();
  if (running_mdi_ && reporter_ && mdi_current_.serial) {
    reporter_->report(mdi_current_, CommandState::Rejected, "aborted: " + why);
  }
  for (auto& q : mdi_queue_) {
    if (reporter_) reporter_->report(q.first, CommandState::Rejected, "aborted: " + why);
  }
  mdi_queue_.clear();
  running_mdi_ = mdi_reading_ = mdi_line_started_ = false;
  mdi_current_ = ipc::Command{};
  if (reconstruct_) {
    reconstruct_->done = true;
    if (reconstruct_->error.empty()) reconstruct_->error = "aborted: " + why;
    reconstruct_.reset();
  }
  try {
    interp_->reset();
  } catch (const interp::InterpError&) {
  }
  if (!file_.empty()) {
    try {
      interp_->open(file_);
    } catch (const interp::InterpError&) {
    }
  }
  interp_state_ = ipc::InterpState::Idle;
  exec_state_ = ipc::ExecState::Done;
  paused_ = stepping_ = program_ended_ = waiting_synch_ = false;
  item_started_ = false;
  if (user_m_pid_ > 0) {
    ::kill(user_m_pid_, SIGTERM);
    ::waitpid(user_m_pid_, nullptr, 0);
    user_m_pid_ = 0;
  }
  if (was_running && !quiet) post(MessageKind::Text, "aborted: " + why);
}

void TaskController::program_error(const std::string& what) {
  ++errors_;
  messages_.post(MessageKind::Error, "interp", what);
  if (running_mdi_ && reporter_) {
    reporter_->report(mdi_current_, CommandState::Rejected, what);
    // Other lines of the same command are dropped.
    std::deque<std::pair<ipc::Command, std::string>> rest;
    for (auto& q : mdi_queue_) {
      if (q.first.serial != mdi_current_.serial) rest.push_back(q);
    }
    mdi_queue_.swap(rest);
    running_mdi_ = mdi_reading_ = mdi_line_started_ = false;
    mdi_current_ = ipc::Command{};
  }
  const auto mdi_left = mdi_queue_;
  mdi_queue_.clear();
  abort_all(what, true);
  mdi_queue_ = mdi_left;
}

void TaskController::program_finished() {
  program_elapsed_ns_ = monotonic_ns() - program_started_ns_;
  char buf[256];
  std::snprintf(buf, sizeof buf, "program finished: %s, %lld blocks, %.2f s, %d errors", file_.c_str(),
                static_cast<long long>(blocks_), static_cast<double>(program_elapsed_ns_) * 1e-9, errors_);
  post(MessageKind::Text, buf);
  interp_state_ = ipc::InterpState::Idle;
  exec_state_ = ipc::ExecState::Done;
  program_ended_ = false;
  paused_ = stepping_ = false;
  save_parameters();
  try {
    interp_->reset();
    interp_->open(file_);
  } catch (const std::exception& e) {
    post(MessageKind::Error, std::string("after the program: ") + e.what());
  }
}

void TaskController::pause(bool) {
  motion::MotionCommand p;
  p.type = Cmd::Pause;
  send(p);
  paused_ = true;
  if (interp_state_ != ipc::InterpState::Idle) interp_state_ = ipc::InterpState::Paused;
}

void TaskController::resume() {
  motion::MotionCommand r;
  r.type = Cmd::Resume;
  send(r);
  paused_ = false;
  if (interp_state_ == ipc::InterpState::Paused) interp_state_ = ipc::InterpState::Reading;
}

void TaskController::start_mdi_line(const std::string& line, const ipc::Command& cmd) {
  running_mdi_ = true;
  mdi_reading_ = true;
  mdi_line_started_ = false;
  mdi_current_ = cmd;
  mdi_text_ = line;
  view_.position = ms_.traj.position;
  canon_->set_end_position(ms_.traj.position);
  interp_->synch();
  waiting_synch_ = false;
}

void TaskController::synch_interpreter() {
  view_.position = ms_.traj.position;
  view_.probed_position = ms_.traj.probed_position;
  view_.probe_tripped = ms_.traj.probe_tripped;
  view_.tool_in_spindle = io_.tool_in_spindle();
  canon_->set_end_position(ms_.traj.position);
  interp_->synch();
  waiting_synch_ = false;
}

// MDI runs like a program: the line, then any subroutine it called, read
// and executed within the cycle's budget, synchronised where it must wait.
void TaskController::run_mdi() {
  if (!mdi_reading_ || paused_) return;
  const int64_t deadline = monotonic_ns() + kReadBudgetNs;
  while (mdi_reading_ && items_.size() < cfg_.readahead_items) {
    if (waiting_synch_) {
      if (!(items_.empty() && motion_idle())) return;
      synch_interpreter();
    }
    try {
      const interp::Status rs = mdi_line_started_ ? interp_->read() : interp_->read(mdi_text_);
      if (rs != interp::Status::SynchRequired) mdi_line_started_ = true;
      if (rs == interp::Status::SynchRequired) {
        waiting_synch_ = true;
        continue;
      }
      if (rs == interp::Status::EndOfFile || rs == interp::Status::ProgramEnd) {
        mdi_reading_ = false;  // the line and what it called are read
        return;
      }
      if (rs == interp::Status::Ok) {
        const interp::Status st = interp_->execute();
        if (const std::string e = canon_->take_error(); !e.empty()) {
          program_error(e);
          return;
        }
        if (st == interp::Status::ExecuteFinish) waiting_synch_ = true;
        if (st == interp::Status::ProgramEnd) {
          mdi_reading_ = false;
          return;
        }
      }
    } catch (const interp::InterpError& e) {
      program_error(describe(e));
      return;
    }
    if (monotonic_ns() > deadline) return;
  }
}

void TaskController::run_interpreter() {
  if (interp_state_ == ipc::InterpState::Idle || paused_ || program_ended_) return;
  const int64_t deadline = monotonic_ns() + kReadBudgetNs;
  if (reconstruct_ && !reconstruct_step(deadline)) return;
  while (items_.size() < cfg_.readahead_items) {
    if (waiting_synch_) {
      if (!(items_.empty() && motion_idle())) {
        exec_state_ = ipc::ExecState::WaitingForMotion;
        return;
      }
      synch_interpreter();
    }
    if (stepping_ && !items_.empty()) return;
    try {
      const interp::Status rs = interp_->read();
      if (rs == interp::Status::Yield) {
        // Lines without a block (a loop computing): the cycle goes on.
        if (monotonic_ns() > deadline) return;
        continue;
      }
      if (rs == interp::Status::SynchRequired) {
        waiting_synch_ = true;
        continue;
      }
      if (rs == interp::Status::ProgramEnd || rs == interp::Status::EndOfFile) {
        program_ended_ = true;
        interp_state_ = ipc::InterpState::Waiting;
        return;
      }
      read_line_ = interp_->line();
      const interp::Status st = interp_->execute();
      ++blocks_;
      if (const std::string e = canon_->take_error(); !e.empty()) {
        program_error(file_ + ":" + std::to_string(read_line_) + ": " + e);
        return;
      }
      if (stepping_) {
        Item mark;
        mark.kind = Item::Kind::StepMark;
        mark.line = read_line_;
        items_.push_back(mark);
      }
      if (st == interp::Status::ExecuteFinish) waiting_synch_ = true;
      if (st == interp::Status::ProgramEnd) {
        program_ended_ = true;
        interp_state_ = ipc::InterpState::Waiting;
        return;
      }
    } catch (const interp::InterpError& e) {
      program_error(describe(e));
      return;
    }
    if (stepping_) return;
    if (monotonic_ns() > deadline) return;
  }
}

double TaskController::read_input(int index, bool digital) const {
  char name[48];
  std::snprintf(name, sizeof name, digital ? "motion.digital-in-%02d" : "motion.analog-in-%02d", index);
  try {
    const std::string v = hal_.get_value(name);
    if (digital) return v == "TRUE" ? 1.0 : 0.0;
    return parse_double(v).value_or(0.0);
  } catch (const hal::HalError&) {
    return -1;
  }
}

bool TaskController::execute_item(Item& it, int64_t now_ns) {
  switch (it.kind) {
    case Item::Kind::Motion:
    case Item::Kind::MotionAtRest:
      send(it.motion);
      return true;
    case Item::Kind::ProbeCheck:
      view_.probe_tripped = ms_.traj.probe_tripped;
      view_.probed_position = ms_.traj.probed_position;
      if (it.probe_must_touch && !ms_.traj.probe_tripped) {
        program_error(file_ + ":" + std::to_string(it.line) + ": the probe move ended without contact");
        return false;
      }
      return true;
    case Item::Kind::ToolPrepare:
    case Item::Kind::ToolChange: {
      if (!item_started_) {
        const char* err = it.kind == Item::Kind::ToolPrepare ? io_.prepare(it.i0) : io_.change(it.i0);
        if (err) {
          program_error(std::string(it.kind == Item::Kind::ToolPrepare ? "tool prepare: " : "tool change: ") + err);
          return false;
        }
        item_started_ = true;
      }
      exec_state_ = ipc::ExecState::WaitingForIo;
      switch (io_.poll()) {
        case io::Handshake::Done:
          item_started_ = false;
          view_.tool_in_spindle = io_.tool_in_spindle();
          return true;
        case io::Handshake::Failed:
          item_started_ = false;
          program_error(io_.failure());
          return false;
        default:
          return false;
      }
    }
    case Item::Kind::ToolNumber:
      if (const char* err = io_.set_tool_number(it.i0)) {
        program_error(std::string("M61: ") + err);
        return false;
      }
      view_.tool_in_spindle = io_.tool_in_spindle();
      return true;
    case Item::Kind::ToolSetEntry:
      if (const char* err = io_.update_tool(it.tool)) {
        program_error(std::string("G10 L1: ") + err);
        return false;
      }
      return true;
    case Item::Kind::Flood:
      io_.set_flood(it.i0 != 0);
      return true;
    case Item::Kind::Mist:
      io_.set_mist(it.i0 != 0);
      return true;
    case Item::Kind::Message:
      messages_.post(MessageKind::Display, "program", it.text);
      return true;
    case Item::Kind::WaitOrient: {
      // M19 Q: the spindle must report is-oriented within the timeout.
      if (!item_started_) {
        item_started_ = true;
        item_started_ns_ = now_ns;
      }
      const int s = it.i0 >= 0 && it.i0 < ipc::kMaxSpindles ? it.i0 : 0;
      const ipc::SpindleStatus& sp = ms_.spindles[s];
      if (sp.orient_fault != 0) {
        item_started_ = false;
        program_error("M19: spindle " + std::to_string(s) + " orientation fault " + std::to_string(sp.orient_fault));
        return false;
      }
      if (sp.orient_state == 2) {
        item_started_ = false;
        return true;
      }
      if (static_cast<double>(now_ns - item_started_ns_) * 1e-9 > it.d0) {
        item_started_ = false;
        program_error("M19: spindle " + std::to_string(s) + " not oriented within Q " + format_double(it.d0) + " s");
        return false;
      }
      exec_state_ = ipc::ExecState::WaitingForSpindleOriented;
      return false;
    }
    case Item::Kind::WaitInput: {
      if (!item_started_) {
        item_started_ = true;
        item_started_ns_ = now_ns;
      }
      const double v = read_input(it.i0, it.i1 != 0);
      const auto type = static_cast<interp::WaitType>(it.i2);
      bool met = true;
      if (it.i1 != 0) {
        if (type == interp::WaitType::High || type == interp::WaitType::Rise) met = v > 0.5;
        if (type == interp::WaitType::Low || type == interp::WaitType::Fall) met = v < 0.5;
      }
      if (met) {
        view_.input_value = v;
        item_started_ = false;
        return true;
      }
      if (static_cast<double>(now_ns - item_started_ns_) * 1e-9 > it.d0) {
        view_.input_value = -1;  // timeout
        item_started_ = false;
        return true;
      }
      return false;
    }
    case Item::Kind::UserMCode: {
      if (!item_started_) {
        std::string prog;
        for (const auto& dir : interp_config_.user_m_path) {
          const auto p = dir / ("M" + std::to_string(it.i0));
          if (::access(p.c_str(), X_OK) == 0) {
            prog = p.string();
            break;
          }
        }
        if (prog.empty()) {
          program_error("M" + std::to_string(it.i0) + ": no executable M" + std::to_string(it.i0) +
                        " in [RS274NGC]USER_M_PATH");
          return false;
        }
        const std::string p = format_double(it.d0), q = format_double(it.d1);
        user_m_pid_ = ::fork();
        if (user_m_pid_ == 0) {
          ::execl(prog.c_str(), prog.c_str(), p.c_str(), q.c_str(), nullptr);
          ::_exit(127);
        }
        item_started_ = true;
      }
      exec_state_ = ipc::ExecState::WaitingForSystemCmd;
      int status = 0;
      if (::waitpid(user_m_pid_, &status, WNOHANG) == 0) return false;
      user_m_pid_ = 0;
      item_started_ = false;
      if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        program_error("M" + std::to_string(it.i0) + " exited with status " + std::to_string(WEXITSTATUS(status)));
        return false;
      }
      return true;
    }
    case Item::Kind::ProgramStop:
      pause(false);
      return true;
    case Item::Kind::OptionalStop:
      if (optional_stop_) pause(false);
      return true;
    case Item::Kind::ProgramEnd:
      program_ended_ = true;
      return true;
    case Item::Kind::StepMark:
      stepping_ = false;
      pause(false);
      return true;
  }
  return true;
}

void TaskController::execute_items(int64_t now_ns) {
  exec_state_ = ipc::ExecState::Done;
  while (!items_.empty()) {
    Item& it = items_.front();
    if (it.kind == Item::Kind::Motion) {
      if (motion_.free_queue_slots() < 16) {
        exec_state_ = ipc::ExecState::WaitingForMotionQueue;
        return;
      }
      send(it.motion);
      if (it.line > 0) current_line_ = it.line;
      items_.pop_front();
      continue;
    }
    if (!motion_idle()) {
      exec_state_ = ipc::ExecState::WaitingForMotion;
      return;
    }
    if (paused_ && it.kind != Item::Kind::StepMark) return;
    if (it.line > 0) current_line_ = it.line;
    if (!execute_item(it, now_ns)) return;
    if (!items_.empty()) items_.pop_front();  // an error may have cleared the list
  }
}

void TaskController::update(int64_t now_ns) {
  // Answers from motion first, then the status they belong to.
  motion::MotionResult r;
  while (motion_.poll_result(r)) {
    last_answered_ = r.serial;
    if (!r.accepted) {
      // A segment or a spindle command (M4 on a spindle that may not turn
      // in reverse) refused while a program runs is a program error.
      if ((r.type == Cmd::SetLine || r.type == Cmd::SetCircle || r.type == Cmd::Probe || r.type == Cmd::SetDwell ||
           r.type == Cmd::SetSpindle) &&
          (interp_state_ != ipc::InterpState::Idle || running_mdi_)) {
        program_error(std::string(r.reason.view()));
      }
    }
    results_[r.serial] = r;
  }
  while (results_.size() > 4096) results_.erase(results_.begin());
  ms_ = motion_.status();
  view_.position = waiting_synch_ ? view_.position : ms_.traj.position;
  view_limits(view_);
  report_spindle_limits();

  check_safety(now_ns);
  // Motion paused itself because the servo thread was late (OVERRUN_ACTION
  // = HOLD): a running program or MDI is paused as if the operator had
  // paused it, so that `resume` continues it; with nothing running there
  // is nothing to hold, and motion is resumed at once.
  if (ms_.overrun_holds != overrun_holds_seen_) {
    overrun_holds_seen_ = ms_.overrun_holds;
    const bool running = interp_state_ != ipc::InterpState::Idle || running_mdi_;
    if (running && !paused_) {
      paused_ = true;
      if (interp_state_ != ipc::InterpState::Idle) interp_state_ = ipc::InterpState::Paused;
      post(MessageKind::Text, "paused: the servo thread is late ([EMCMOT]OVERRUN_ACTION = HOLD); resume when ready");
    } else if (!running) {
      motion::MotionCommand r;
      r.type = Cmd::Resume;
      send(r);
    }
  }

  // A feed move waited past [SPINDLE_n]AT_SPEED_TIMEOUT: motion has dropped
  // the queued moves; the program (or MDI) is aborted with the reason.
  if (ms_.spindle_timeouts != spindle_timeouts_seen_) {
    spindle_timeouts_seen_ = ms_.spindle_timeouts;
    const std::string why = std::string(ms_.spindle_timeout_reason.view());
    if (interp_state_ != ipc::InterpState::Idle) {
      program_error("program aborted" + (ms_.traj.motion_line > 0 ? " at line " + std::to_string(ms_.traj.motion_line)
                                                                   : std::string()) + ": " + why);
    } else if (running_mdi_ || !mdi_queue_.empty()) {
      program_error("MDI aborted: " + why);
    } else {
      messages_.post(MessageKind::Error, "motion", why);
    }
  }

  // Program.
  if (interp_state_ != ipc::InterpState::Idle) {
    run_interpreter();
    execute_items(now_ns);
    if (program_ended_ && items_.empty() && motion_idle()) program_finished();
  } else if (running_mdi_ || !mdi_queue_.empty()) {
    if (!running_mdi_ && !mdi_queue_.empty() && motion_idle()) {
      auto [cmd, line] = mdi_queue_.front();
      mdi_queue_.pop_front();
      start_mdi_line(line, cmd);
    }
    if (running_mdi_) {
      run_mdi();
      if (running_mdi_) execute_items(now_ns);
      if (running_mdi_ && !mdi_reading_ && items_.empty() && !waiting_synch_ && motion_idle() && !paused_) {
        running_mdi_ = false;
        bool more = false;  // a macro's later lines belong to the same command
        for (const auto& q : mdi_queue_) more = more || q.first.serial == mdi_current_.serial;
        // "done" follows the durable write of what the line changed (G10,
        // G92, #5xxx): an acknowledged offset is never lost.
        const std::string unsaved = save_parameters();
        if (reporter_ && mdi_current_.serial && !more) {
          reporter_->report(mdi_current_, unsaved.empty() ? CommandState::Done : CommandState::Rejected, unsaved);
        }
        mdi_current_ = ipc::Command{};
        mdi_text_.clear();
      }
    }
  }
  if (!running_mdi_ && interp_state_ == ipc::InterpState::Idle && items_.empty()) exec_state_ = ipc::ExecState::Done;

  // Commands answered later.
  for (std::size_t i = 0; i < waiters_.size();) {
    if (reporter_ && waiters_[i].check()) waiters_.erase(waiters_.begin() + static_cast<long>(i));
    else ++i;
  }
  if (program_started_ns_ && interp_state_ != ipc::InterpState::Idle) program_elapsed_ns_ = now_ns - program_started_ns_;
}

std::string TaskController::save_parameters() {
  try {
    interp_->save_parameters();
    return {};
  } catch (const std::exception& e) {
    const std::string why = std::string("the parameter file could not be written, so work offsets and other "
                                        "persistent parameters changed since are lost at a restart: ") +
                            e.what();
    post(MessageKind::Error, why);
    return why;
  }
}

// Motion has already acted on an E-stop or a fault in the servo thread; the
// task follows with its state, the program and the reason.
void TaskController::check_safety(int64_t now_ns) {
  if (state_ != ipc::TaskState::Estop) {
    if (motion_.servo_stalled()) {
      messages_.post(MessageKind::Error, "task", "E-stop: " + motion_.stall_reason());
      enter_estop("E-stop: motion stopped running");
    } else if (ms_.traj.estop_latched && ms_.traj.estop_cause == ipc::EstopCause::Request) {
      enter_estop("E-stop requested by " + describe_process(ms_.traj.estop_pid));
    } else if (ms_.traj.estop_latched || !io_.estop_chain_closed()) {
      messages_.post(MessageKind::Error, "iocontrol", "E-stop chain opened (iocontrol.0.emc-enable-in went false)");
      enter_estop("E-stop chain opened");
    }
  }
  if (state_ == ipc::TaskState::On && was_enabled_ && !ms_.traj.enabled) {
    FaultReport& f = fault_report_;
    f = FaultReport{};
    f.pending = true;
    f.since_ns = now_ns;
    f.program = interp_state_ != ipc::InterpState::Idle;
    f.mdi = running_mdi_ || !mdi_queue_.empty();
    f.line = f.program ? (ms_.traj.motion_line > 0 ? ms_.traj.motion_line : current_line_) : 0;
    f.reason = ms_.fault_reason.empty() ? std::string("motion was disabled") : std::string(ms_.fault_reason.view());
    f.joint = ms_.fault_joint;
    f.spindle = ms_.fault_spindle;
    if (f.program) ++errors_;  // the program did not end well
    abort_all(f.reason, true);
    state_ = ipc::TaskState::Off;
    was_enabled_ = false;
  }
  if (state_ == ipc::TaskState::On && ms_.traj.enabled) was_enabled_ = true;
  report_motion_fault(now_ns);
}

// Says why motion was disabled, with the drive layer's explanation (which
// drive, which fault) when the fault is an amplifier's: that text comes
// from the drive a few cycles later, so it is waited for a little.
void TaskController::report_motion_fault(int64_t now_ns) {
  FaultReport& f = fault_report_;
  if (!f.pending) return;
  std::string drives;
  bool any_drive = false;
  for (const ipc::DriveStatus& d : drives_) {
    const bool concerned = d.present && ((f.joint >= 0 && d.joint == f.joint) || (f.spindle >= 0 && d.joint < 0));
    if (!concerned) continue;
    any_drive = true;
    if (d.fault_text.empty()) continue;
    drives += std::string("; drive ") + d.name.c_str() + ": " + d.fault_text.c_str();
  }
  constexpr int64_t kWaitForDriveNs = 250'000'000;
  if (any_drive && drives.empty() && now_ns - f.since_ns < kWaitForDriveNs) return;
  f.pending = false;
  std::string text = f.reason + drives;
  if (f.program) {
    text = "program aborted" + (f.line > 0 ? " at line " + std::to_string(f.line) : std::string()) + ": " + text;
  } else if (f.mdi) {
    text = "MDI aborted: " + text;
  }
  messages_.post(MessageKind::Error, "task", text);
  post(MessageKind::Text, "machine off: motion was disabled by a fault");
}

void TaskController::contribute_status(ipc::Status& s) {
  ipc::TaskStatus& t = s.task;
  t.available = true;
  t.state = state_;
  t.mode = mode_;
  t.interp_state = running_mdi_ ? ipc::InterpState::Reading : interp_state_;
  t.exec_state = exec_state_;
  t.paused = paused_;
  t.block_delete = block_delete_;
  t.optional_stop = optional_stop_;
  t.file.assign(file_);
  t.command.assign(mdi_text_);
  const bool moving = !ms_.tp_done && ms_.traj.motion_line > 0;
  t.current_line = interp_state_ == ipc::InterpState::Idle ? 0 : (moving ? ms_.traj.motion_line : current_line_);
  t.read_line = read_line_;
  t.total_lines = total_lines_;
  t.g5x_index = canon_->g5x_index();
  t.g5x_offset = canon_->g5x_offset();
  t.g92_offset = canon_->g92_offset();
  t.rotation_xy = canon_->rotation();
  t.tool_offset = canon_->tool_offset();
  t.program_units = canon_->program_units() == interp::Units::Inch ? 1 : 2;
  const auto g = interp_->active_g_codes();
  for (std::size_t i = 0; i < 17; ++i) t.active_gcodes[i] = i < g.size() ? g[i] : -1;
  const auto m = interp_->active_m_codes();
  for (std::size_t i = 0; i < 10; ++i) t.active_mcodes[i] = i < m.size() ? m[i] : -1;
  t.active_settings[1] = canon_->feed_rate_units_min();
  t.active_settings[2] = canon_->spindle_speed(0);
  t.queued_mdi = static_cast<int32_t>(mdi_queue_.size());
  t.program_started_ns = program_started_ns_;
  t.program_elapsed_ns = program_elapsed_ns_;
  t.blocks_executed = blocks_;
  t.errors_since_start = errors_;
  t.run_from_line_pending = run_from_line_;
  t.run_from_line_start = run_from_start_;
  // The drive layer contributed its panel before the task (lower service
  // order): kept for naming a faulted drive in messages.
  for (std::size_t i = 0; i < drives_.size(); ++i) drives_[i] = s.drives[i];
}

bool TaskController::is_safe_to_stop() const { return !ms_.traj.enabled; }

}  // namespace cnc::task
