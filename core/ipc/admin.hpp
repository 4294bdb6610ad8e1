// The administration channel: request/response text over a Unix socket
// (/dev/shm/cnc-<instance>.hal, mode 0660) for halcmd. Machine commands go
// through the shared segment; this channel carries only halcmd lines and
// their printed answers, which can be long and have no place in a ring.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <thread>

namespace cnc::ipc {

struct AdminReply {
  bool ok = true;
  std::string text;  // output, or the error message when !ok
};

class AdminServer {
 public:
  using Handler = std::function<AdminReply(const std::string& line)>;

  // Listens on the instance's socket; handles requests on its own thread.
  AdminServer(const std::string& instance, Handler handler);
  ~AdminServer();
  AdminServer(const AdminServer&) = delete;
  AdminServer& operator=(const AdminServer&) = delete;

 private:
  void loop();

  std::string path_;
  Handler handler_;
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
