// The controller's side of the shared segment: creates it (refusing a
// second controller on the same instance), publishes status, takes
// commands from every client channel, reports command results and posts
// messages. Non-realtime: used by the controller's task thread only.
#pragma once

#include <string>

#include "core/ipc/access.hpp"
#include "core/ipc/segment.hpp"

namespace cnc::ipc {

class Server {
 public:
  // Takes the instance lock, removes a stale segment left by a crashed
  // controller, creates and initialises a fresh one (mode and group from
  // `access`). Throws std::runtime_error when another controller runs on
  // this instance, or when another user's file sits where the lock or the
  // segment belongs (naming that user).
  explicit Server(const std::string& instance, const AccessPolicy& access = AccessPolicy::for_current_user());
  ~Server();  // removes the segment and the lock
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  const std::string& instance() const noexcept { return instance_; }
  Segment& segment() noexcept { return *seg_; }

  void set_ready(bool ready) noexcept;
  void publish(const Status& status) noexcept;

  // Next command from any client, round-robin so that no client starves.
  // Frees the channels of clients that died.
  bool poll_command(Command& out) noexcept;

  void report(const Command& cmd, CommandState state, std::string_view reason = {}) noexcept;
  void post(const Message& m) noexcept;

  // Number of client channels in use.
  int clients_connected() const noexcept;

 private:
  void reap_dead_clients() noexcept;

  std::string instance_;
  int lock_fd_ = -1;
  int shm_fd_ = -1;
  Segment* seg_ = nullptr;
  int next_client_ = 0;
  int64_t last_reap_ns_ = 0;
  CommandEcho echo_;
};

}  // namespace cnc::ipc
