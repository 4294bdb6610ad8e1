// Every operator command the screen sends, built as the command channel
// documents them (core/ipc/command.hpp; the same semantics as the `cnc`
// CLI), and the tracker that follows each command's answer without
// blocking: the screen polls it once per cycle. Sequences send their next
// command only when the previous one is done (a mode change before MDI or a
// program run), and stop at the first rejection. No Qt.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/ipc/operator_commands.hpp"
#include "core/ipc/status.hpp"
#include "core/tooltable/tool_table.hpp"

namespace cnc::hmi {

class MachineLink;

namespace commands {
// Every operator command, encoded once for all clients
// (core/ipc/operator_commands.hpp); those taking text throw
// std::invalid_argument when it does not fit the channel (callers say so
// instead of sending a shortened line).
using namespace ipc::commands;
ipc::Command make(ipc::CommandType type);
// Run from a line with the preview's look (TaskPlanRunPreview).
ipc::Command run_preview(int line);
// A tool table row; a comment too long for the channel is shortened (it
// is only a comment).
ipc::Command tool_set(const tooltable::Tool& tool, bool pocket_given);
ipc::Command tool_reload();
}  // namespace commands

class CommandTracker {
 public:
  using Done = std::function<void(const ipc::CommandResult&)>;
  // Reports each rejection (or a command that could not be sent) with what
  // it was for, e.g. for the log.
  using RejectSink = std::function<void(const std::string& what, const std::string& reason)>;

  explicit CommandTracker(MachineLink& link) : link_(link) {}

  void set_reject_sink(RejectSink sink) { on_reject_ = std::move(sink); }
  // Sends now. `done` (optional) gets the final answer: Done, or Rejected
  // with the reason (also when the command could not be sent). Returns
  // whether it was sent.
  bool send(const ipc::Command& cmd, const std::string& what, Done done = {});
  // Sends the commands one after the other, each once the previous one is
  // Done; `done` gets the last answer or the first rejection.
  bool send_sequence(std::vector<ipc::Command> cmds, const std::string& what, Done done = {});
  // E-stop: the segment's E-stop word first (the servo thread acts on it,
  // whatever the channels and the task cycle do), then the task is told
  // (so that it records who asked) without tracking its answer. When the
  // word cannot be set the command is sent and tracked as any other.
  bool estop(const std::string& what);
  // Looks at the answers; call once per cycle. `now_ns`: monotonic time.
  void poll(int64_t now_ns);

  std::size_t pending() const noexcept { return pending_.size(); }
  // A command that no controller answered for this long is given up.
  static constexpr int64_t kNoAnswerNs = 10'000'000'000;

 private:
  struct Pending {
    uint32_t serial = 0;
    std::vector<ipc::Command> rest;
    std::string what;
    Done done;
    int64_t sent_ns = 0;
    ipc::CommandState last = ipc::CommandState::None;
  };
  bool start(Pending p, const ipc::Command& cmd);
  void finish(Pending& p, const ipc::CommandResult& r);

  MachineLink& link_;
  RejectSink on_reject_;
  std::vector<Pending> pending_;
  int64_t now_ns_ = 0;
};

}  // namespace cnc::hmi
