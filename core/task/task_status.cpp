// The task controller following motion's state (E-stop, faults) and
// publishing its status.
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
  // Modal codes, F and S of the line being executed (LinuxCNC 2.9's state
  // tags): while a program or MDI runs, the tag of the move motion executes,
  // or with motion at rest the tag of the last item executed; otherwise
  // (idle) the interpreter's own state, which then is the machine's.
  const bool running = interp_state_ != ipc::InterpState::Idle || running_mdi_;
  if (!running) executed_tag_ = tp::StateTag{};
  const tp::StateTag* tag = nullptr;
  if (running && !ms_.tp_done && ms_.tag.valid) {
    tag = &ms_.tag;
  } else if (running && executed_tag_.valid) {
    tag = &executed_tag_;
  }
  if (tag) {
    for (int i = 0; i < 17; ++i) t.active_gcodes[i] = i < tp::StateTag::kGCodes ? tag->gcodes[i] : -1;
    for (int i = 0; i < 10; ++i) t.active_mcodes[i] = i < tp::StateTag::kMCodes ? tag->mcodes[i] : -1;
    t.active_settings[1] = tag->feed;
    t.active_settings[2] = tag->speed;
  } else {
    const auto g = interp_->active_g_codes();
    for (std::size_t i = 0; i < 17; ++i) t.active_gcodes[i] = i < g.size() ? g[i] : -1;
    const auto m = interp_->active_m_codes();
    for (std::size_t i = 0; i < 10; ++i) t.active_mcodes[i] = i < m.size() ? m[i] : -1;
    t.active_settings[1] = canon_->feed_rate_units_min();
    t.active_settings[2] = canon_->spindle_speed(0);
  }
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
