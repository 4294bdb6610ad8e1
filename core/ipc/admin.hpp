// The administration channel: request/response text over a Unix socket
// (/dev/shm/cnc-<instance>.hal, mode 0600, or 0660 for a trusted group) for
// halcmd; each peer's credentials are checked against the access policy. Machine commands go
// through the shared segment; this channel carries only halcmd lines and
// their printed answers, which can be long and have no place in a ring.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <thread>

#include "core/ipc/access.hpp"

namespace cnc::ipc {

struct AdminReply {
  bool ok = true;
  std::string text;  // output, or the error message when !ok
};

class AdminServer {
 public:
  using Handler = std::function<AdminReply(const std::string& line)>;

  // Listens on the instance's socket; handles requests on its own thread.
  // A peer `access` does not permit is answered with an error and dropped.
  AdminServer(const std::string& instance, Handler handler,
              const AccessPolicy& access = AccessPolicy::for_current_user());
  ~AdminServer();
  AdminServer(const AdminServer&) = delete;
  AdminServer& operator=(const AdminServer&) = delete;

 private:
  void loop();

  std::string path_;
  Handler handler_;
  AccessPolicy access_;
  int listen_fd_ = -1;
  int wake_fd_[2] = {-1, -1};
  std::thread thread_;
};

// A connection from halcmd. Throws std::runtime_error when the controller
// is not running.
class AdminClient {
 public:
  explicit AdminClient(const std::string& instance);
  ~AdminClient();
  AdminClient(const AdminClient&) = delete;
  AdminClient& operator=(const AdminClient&) = delete;
  AdminReply request(const std::string& line);

 private:
  int fd_ = -1;
};

}  // namespace cnc::ipc
