// The client library: how the CLI, halcmd and the HMI talk to a running
// controller. It maps the controller's shared segment, reads status without
// ever blocking the controller, sends commands on a channel of its own and
// follows the message channel. A client never links the controller.
#pragma once

#include <chrono>
#include <map>
#include <stdexcept>
#include <string>

#include "core/ipc/segment.hpp"

namespace cnc::ipc {

class ClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Client {
 public:
  // Throws ClientError: controller not running, stale segment of a dead
  // controller, or a segment of another layout version.
  explicit Client(const std::string& instance = default_instance());
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const std::string& instance() const noexcept { return instance_; }
  // The controller process still exists (not just its segment).
  bool controller_alive() const;
  bool controller_ready() const;
  // The controller's process id (from the segment's header).
  int32_t owner_pid() const;
  // A consistent copy of the status block.
  Status status() const;

  // Sends a command and returns its serial. Throws ClientError when the
  // controller is gone or this client's queue is full.
  uint32_t send(Command cmd);
  // Like send, but returns false instead of throwing when the queue is full.
  bool try_send(Command cmd, uint32_t& serial);
  // Waits until the command is Done or Rejected; on timeout returns the last
  // state seen (Received/Executing, or None if not even received).
  CommandResult wait(uint32_t serial, std::chrono::milliseconds timeout);
  // send + wait.
  CommandResult execute(const Command& cmd, std::chrono::milliseconds timeout);

  // E-stop without a command channel: bumps the segment's E-stop request
  // (one atomic operation, whatever the channels or the task cycle do) and
  // returns the request word. Motion acts on it in the servo thread within
  // a cycle or two and acknowledges it. Throws ClientError when the
  // controller is gone.
  uint64_t request_estop();
  // Waits until the servo thread acknowledged `request`; false on timeout
  // or when the controller stopped.
  bool wait_estop_acknowledged(uint64_t request, std::chrono::milliseconds timeout) const;
  // The ages of the status and of the servo heartbeat, judged; `s` is a
  // status just read (it carries the task cycle and the servo period).
  Liveness liveness(const Status& s) const;

  // Messages from the controller, in order. Reading starts with what is
  // posted after the client connected; call rewind_messages() for the oldest
  // still held. `lost` (optional) counts messages overwritten unread.
  bool next_message(Message& out, uint64_t* lost = nullptr);
  void rewind_messages();

 private:
  void claim_channel();
  void check_alive() const;
  void drain_results();

  std::string instance_;
  int fd_ = -1;
  Segment* seg_ = nullptr;
  int channel_ = -1;
  uint64_t results_cursor_ = 0;
  uint64_t messages_cursor_ = 0;
  std::map<uint32_t, CommandResult> results_;
};

// Builds a command of a type with optional integer/double arguments.
Command make_command(CommandType type);

}  // namespace cnc::ipc
