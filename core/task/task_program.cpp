// The task controller running programs and MDI: the interpreter read ahead
// within a budget, the items executed in order, aborts and program errors,
// and the task cycle.
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
  mdi_text_.clear();  // the status shows no MDI line as running any more
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
  // errors_since_start counts the program's errors: an MDI line's error is
  // answered to its sender and logged, not counted against a program.
  if (interp_state_ != ipc::InterpState::Idle) ++errors_;
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
    mdi_text_.clear();
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
        const std::size_t before = items_.size();
        const interp::Status st = interp_->execute();
        tag_new_items(before, interp_->line());
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
      const std::size_t before = items_.size();
      const interp::Status st = interp_->execute();
      tag_new_items(before, read_line_);
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
      // A drive's latch may arrive after the move stopped: motion says
      // when it is still waiting for one (bounded there).
      if (ms_.traj.probe_latch_pending) return false;
      view_.probe_tripped = ms_.traj.probe_tripped;
      view_.probed_position = ms_.traj.probed_position;
      if (it.probe_must_touch && !ms_.traj.probe_tripped) {
        // an MDI line's error names the line, not the program that happens to be open
        program_error((running_mdi_ ? "MDI " + mdi_text_ : file_ + ":" + std::to_string(it.line)) +
                      ": the probe move ended without contact");
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
          sigset_t none;  // no signal blocked in the program (cncd blocks SIGINT and SIGTERM)
          sigemptyset(&none);
          ::sigprocmask(SIG_SETMASK, &none, nullptr);
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
      if (it.tag.valid) executed_tag_ = it.tag;
      items_.pop_front();
      continue;
    }
    if (!motion_idle()) {
      exec_state_ = ipc::ExecState::WaitingForMotion;
      return;
    }
    if (paused_ && it.kind != Item::Kind::StepMark) return;
    if (it.line > 0) current_line_ = it.line;
    const tp::StateTag tag = it.tag;
    if (!execute_item(it, now_ns)) return;
    if (tag.valid) executed_tag_ = tag;
    if (!items_.empty()) items_.pop_front();  // an error may have cleared the list
  }
}

void TaskController::tag_new_items(std::size_t from, int line) {
  if (items_.size() <= from) return;
  tp::StateTag tag;
  tag.valid = true;
  tag.line = line;
  const auto g = interp_->active_g_codes();
  for (std::size_t i = 0; i < tp::StateTag::kGCodes; ++i) tag.gcodes[i] = static_cast<int16_t>(i < g.size() ? g[i] : -1);
  const auto m = interp_->active_m_codes();
  for (std::size_t i = 0; i < tp::StateTag::kMCodes; ++i) tag.mcodes[i] = static_cast<int16_t>(i < m.size() ? m[i] : -1);
  tag.feed = canon_->feed_rate_units_min();
  tag.speed = canon_->spindle_speed(0);
  for (std::size_t i = from; i < items_.size(); ++i) {
    items_[i].tag = tag;
    if (items_[i].kind == Item::Kind::Motion || items_[i].kind == Item::Kind::MotionAtRest) {
      items_[i].motion.segment.tag = tag;
    }
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

}  // namespace cnc::task
