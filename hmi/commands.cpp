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

Command run_preview(int line) {
  Command c = make(CommandType::TaskPlanRunPreview);
  c.i[0] = line;
  return c;
}

Command tool_set(const tooltable::Tool& t, bool pocket_given) {
  const std::size_t cap = decltype(Command{}.text)::capacity();
  const std::string comment = t.comment.size() > cap ? t.comment.substr(0, cap) : t.comment;
  return ipc::commands::tool_set_offset(t.number, pocket_given ? t.pocket : -1, t.offset, t.diameter, t.front_angle,
                                        t.back_angle, t.orientation, comment);
}

Command tool_reload() { return ipc::commands::tool_load_table(); }

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
