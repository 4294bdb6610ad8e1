#include "core/ipc/admin.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <map>
#include <vector>
#include <stdexcept>

#include "core/ipc/segment.hpp"

namespace cnc::ipc {
namespace {

constexpr std::size_t kMaxRequestBytes = 65536;  // one halcmd line

sockaddr_un make_address(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (path.size() >= sizeof(addr.sun_path)) throw std::runtime_error("socket path too long: " + path);
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  return addr;
}

bool write_all(int fd, const std::string& data) {
  std::size_t off = 0;
  while (off < data.size()) {
    const ssize_t n = ::send(fd, data.data() + off, data.size() - off, MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    off += static_cast<std::size_t>(n);
  }
  return true;
}

std::string encode(const AdminReply& r) {
  return std::string(r.ok ? "OK " : "ERR ") + std::to_string(r.text.size()) + "\n" + r.text;
}

}  // namespace

AdminServer::AdminServer(const std::string& instance, Handler handler, const AccessPolicy& access)
    : path_(admin_socket_path(instance)), handler_(std::move(handler)), access_(access) {
  ::unlink(path_.c_str());
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) throw std::runtime_error("cannot create admin socket: " + std::string(std::strerror(errno)));
  const sockaddr_un addr = make_address(path_);
  if (::bind(listen_fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    throw std::runtime_error("cannot bind admin socket " + path_ + ": " + std::strerror(errno));
  }
  access_.apply(path_, "the HAL socket " + path_);
  ::listen(listen_fd_, 8);
  if (::pipe2(wake_fd_, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
  thread_ = std::thread([this] { loop(); });
}

AdminServer::~AdminServer() {
  if (wake_fd_[1] >= 0) {
    const char c = 'q';
    (void)::write(wake_fd_[1], &c, 1);
  }
  if (thread_.joinable()) thread_.join();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  for (int fd : wake_fd_) {
    if (fd >= 0) ::close(fd);
  }
  ::unlink(path_.c_str());
}

void AdminServer::loop() {
  std::map<int, std::string> clients;  // fd -> partial request
  for (;;) {
    std::vector<pollfd> fds;
    fds.push_back({wake_fd_[0], POLLIN, 0});
    fds.push_back({listen_fd_, POLLIN, 0});
    for (const auto& [fd, buf] : clients) fds.push_back({fd, POLLIN, 0});
    if (::poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if (fds[0].revents) break;
    if (fds[1].revents & POLLIN) {
      const int c = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (c >= 0) {
        ucred peer{};
        socklen_t len = sizeof peer;
        if (::getsockopt(c, SOL_SOCKET, SO_PEERCRED, &peer, &len) == 0 && access_.permits(peer.uid)) {
          clients[c] = {};
        } else {
          write_all(c, encode({false, "not permitted: uid " + std::to_string(peer.uid) +
                                          " is neither the controller's user nor in its trusted group "
                                          "(docs/security.md)"}));
          ::close(c);
        }
      }
    }
    for (std::size_t i = 2; i < fds.size(); ++i) {
      if (!fds[i].revents) continue;
      const int fd = fds[i].fd;
      char buf[4096];
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) {
        ::close(fd);
        clients.erase(fd);
        continue;
      }
      std::string& pending = clients[fd];
      pending.append(buf, static_cast<std::size_t>(n));
      if (pending.size() > kMaxRequestBytes && pending.find('\n') == std::string::npos) {
        write_all(fd, encode({false, "request longer than " + std::to_string(kMaxRequestBytes) + " bytes"}));
        ::close(fd);
        clients.erase(fd);
        continue;
      }
      std::size_t nl;
      bool alive = true;
      while (alive && (nl = pending.find('\n')) != std::string::npos) {
        const std::string line = pending.substr(0, nl);
        pending.erase(0, nl + 1);
        AdminReply reply;
        try {
          reply = handler_(line);
        } catch (const std::exception& e) {
          reply = {false, e.what()};
        }
        alive = write_all(fd, encode(reply));
      }
      if (!alive) {
        ::close(fd);
        clients.erase(fd);
      }
    }
  }
  for (const auto& [fd, buf] : clients) ::close(fd);
}

AdminClient::AdminClient(const std::string& instance) {
  validate_instance_name(instance);
  fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  const sockaddr_un addr = make_address(admin_socket_path(instance));
  if (::connect(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    if (err == ENOENT || err == ECONNREFUSED) throw std::runtime_error("controller not running (instance \"" + instance + "\")");
    throw std::runtime_error("cannot connect to the controller's HAL socket: " + std::string(std::strerror(err)));
  }
}

AdminClient::~AdminClient() {
  if (fd_ >= 0) ::close(fd_);
}

AdminReply AdminClient::request(const std::string& line) {
  if (line.find('\n') != std::string::npos) throw std::runtime_error("a request is one line");
  if (!write_all(fd_, line + "\n")) throw std::runtime_error("controller closed the HAL socket");
  std::string buf;
  char chunk[65536];
  std::size_t header_end = std::string::npos;
  std::size_t body_len = 0;
  for (;;) {
    if (header_end == std::string::npos) {
      header_end = buf.find('\n');
      if (header_end != std::string::npos) body_len = std::stoul(buf.substr(buf.find(' ') + 1, header_end));
    }
    if (header_end != std::string::npos && buf.size() >= header_end + 1 + body_len) break;
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error("controller closed the HAL socket");
    buf.append(chunk, static_cast<std::size_t>(n));
  }
  AdminReply r;
  r.ok = buf.rfind("OK ", 0) == 0;
  r.text = buf.substr(header_end + 1, body_len);
  return r;
}

}  // namespace cnc::ipc
