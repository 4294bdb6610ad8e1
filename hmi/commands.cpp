#include "hmi/commands.hpp"

#include "core/util/time.hpp"
#include "hmi/link.hpp"

namespace cnc::hmi {
namespace commands {

using ipc::Command;
using ipc::CommandType;

Command make(CommandType type) {
  Command c;
  c.type = type;
  return c;
}

namespace {
Command with_i(CommandType t, int a, int b = 0) {
  Command c = make(t);
  c.i[0] = a;
  c.i[1] = b;
  return c;
}
Command with_d(CommandType t, double d, int i0 = 0) {
  Command c = make(t);
  c.d[0] = d;
  c.i[0] = i0;
  return c;
}
Command with_text(CommandType t, const std::string& text) {
  Command c = make(t);
  c.text.assign(text);
  return c;
}
}  // namespace

Command set_state(ipc::TaskState s) { return with_i(CommandType::TaskSetState, static_cast<int>(s)); }
Command set_mode(ipc::TaskMode m) { return with_i(CommandType::TaskSetMode, static_cast<int>(m)); }
Command abort() { return make(CommandType::TaskAbort); }
Command open(const std::string& path) { return with_text(CommandType::TaskPlanOpen, path); }
Command run(int line) { return with_i(CommandType::TaskPlanRun, line); }
Command run_preview(int line) { return with_i(CommandType::TaskPlanRunPreview, line); }
Command pause() { return make(CommandType::TaskPlanPause); }
Command resume() { return make(CommandType::TaskPlanResume); }
Command step() { return make(CommandType::TaskPlanStep); }
Command mdi(const std::string& line) {
  Command c = with_text(CommandType::TaskPlanExecute, line);
  c.i[0] = -1;
  return c;
}
Command macro(int index) { return with_i(CommandType::TaskPlanExecute, index); }
Command optional_stop(bool on) { return with_i(CommandType::TaskPlanSetOptionalStop, on ? 1 : 0); }
Command block_delete(bool on) { return with_i(CommandType::TaskPlanSetBlockDelete, on ? 1 : 0); }
Command home(int joint) { return with_i(CommandType::JointHome, joint); }
Command unhome(int joint) { return with_i(CommandType::JointUnhome, joint); }
Command feed_override(double ratio) { return with_d(CommandType::TrajSetScale, ratio); }
Command rapid_override(double ratio) { return with_d(CommandType::TrajSetRapidScale, ratio); }
Command spindle_override(double ratio, int spindle) { return with_d(CommandType::SpindleOverride, ratio, spindle); }
Command max_velocity(double v) { return with_d(CommandType::TrajSetMaxVelocity, v); }
Command spindle_on(double rpm, int spindle) { return with_d(CommandType::SpindleOn, rpm, spindle); }
Command spindle_off(int spindle) { return with_i(CommandType::SpindleOff, spindle); }
Command spindle_faster(int spindle) { return with_i(CommandType::SpindleIncrease, spindle); }
Command spindle_slower(int spindle) { return with_i(CommandType::SpindleDecrease, spindle); }
Command flood(bool on) { return make(on ? CommandType::CoolantFloodOn : CommandType::CoolantFloodOff); }
Command mist(bool on) { return make(on ? CommandType::CoolantMistOn : CommandType::CoolantMistOff); }

Command tool_set(const tooltable::Tool& t, bool pocket_given) {
  Command c = make(CommandType::ToolSetOffset);
  c.i[0] = t.number;
  c.i[1] = pocket_given ? t.pocket : -1;
  c.i[2] = t.orientation;
  for (int a = 0; a < kNumAxes; ++a) c.d[a] = t.offset[a];
  c.d[9] = t.diameter;
  c.d[10] = t.front_angle;
  c.d[11] = t.back_angle;
  c.text.assign(t.comment);
  return c;
}
Command tool_delete(int tool) { return with_i(CommandType::ToolDelete, tool); }
Command tool_reload() { return make(CommandType::ToolLoadTable); }

Command set_work_offset(int index, const Pose& offsets, double rotation_deg) {
  Command c = make(CommandType::SetWorkOffset);
  c.i[0] = index;
  for (int a = 0; a < kNumAxes; ++a) c.d[a] = offsets[a];
  c.d[9] = rotation_deg;
  return c;
}

}  // namespace commands

bool CommandTracker::start(Pending p, const ipc::Command& cmd) {
  std::string why;
  const auto serial = link_.send(cmd, why);
  if (!serial) {
    ipc::CommandResult r;
    r.type = cmd.type;
    r.state = ipc::CommandState::Rejected;
    r.reason.assign("not sent: " + why);
    finish(p, r);
    return false;
  }
  p.serial = *serial;
  p.sent_ns = now_ns_ ? now_ns_ : monotonic_ns();
  p.last = ipc::CommandState::None;
  pending_.push_back(std::move(p));
  return true;
}

bool CommandTracker::send(const ipc::Command& cmd, const std::string& what, Done done) {
  Pending p;
  p.what = what;
  p.done = std::move(done);
  return start(std::move(p), cmd);
}

bool CommandTracker::estop(const std::string& what) {
  std::string why;
  if (!link_.request_estop(why)) return send(commands::set_state(ipc::TaskState::Estop), what);
  std::string ignored;
  link_.send(commands::set_state(ipc::TaskState::Estop), ignored);  // best effort: the stop is done
  return true;
}

bool CommandTracker::send_sequence(std::vector<ipc::Command> cmds, const std::string& what, Done done) {
  if (cmds.empty()) return false;
  Pending p;
  p.what = what;
  p.done = std::move(done);
  const ipc::Command first = cmds.front();
  p.rest.assign(cmds.begin() + 1, cmds.end());
  return start(std::move(p), first);
}

void CommandTracker::finish(Pending& p, const ipc::CommandResult& r) {
  if (r.state == ipc::CommandState::Rejected && on_reject_) on_reject_(p.what, std::string(r.reason.view()));
  if (p.done) p.done(r);
}

void CommandTracker::poll(int64_t now_ns) {
  now_ns_ = now_ns;
  // Callbacks may send new commands: work on a detached list.
  std::vector<Pending> work = std::move(pending_);
  pending_.clear();
  std::vector<Pending> keep;
  for (auto& p : work) {
    ipc::CommandResult r = link_.poll_result(p.serial);
    if (r.state == ipc::CommandState::Done && !p.rest.empty()) {
      const ipc::Command next = p.rest.front();
      p.rest.erase(p.rest.begin());
      start(std::move(p), next);  // goes to pending_
      continue;
    }
    if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected) {
      finish(p, r);
      continue;
    }
    if (r.state != ipc::CommandState::None) p.last = r.state;
    if (p.last == ipc::CommandState::None && now_ns - p.sent_ns > kNoAnswerNs) {
      r.state = ipc::CommandState::Rejected;
      r.reason.assign("no answer from the controller");
      finish(p, r);
      continue;
    }
    keep.push_back(std::move(p));
  }
  for (auto& p : keep) pending_.push_back(std::move(p));
}

}  // namespace cnc::hmi
