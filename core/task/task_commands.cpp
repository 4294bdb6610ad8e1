// The task controller's commands: what the operator (cnc, the screen) asks
// for, checked and answered: state, mode, jog, home, tools, programs, MDI.
#include "core/task/task_internal.hpp"

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

using namespace detail;

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
      interp_ = make_interpreter(*canon_);
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
  job->interp = make_interpreter(*job->canon);
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

}  // namespace cnc::task
