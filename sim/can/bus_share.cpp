#include "sim/can/bus_share.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/ipc/segment.hpp"
#include "fieldbus/can/unix_transport.hpp"
#include "sim/can/virtual_bus.hpp"

namespace cnc::can {

std::string default_share_path(const std::string& bus_name) {
  return "/dev/shm/cnc-" + ipc::default_instance() + ".can-" + bus_name;
}

namespace {

constexpr int kMaxClients = 8;

sockaddr_un address(const std::string& path) {
  sockaddr_un a{};
  if (path.empty() || path.size() >= sizeof(a.sun_path)) {
    throw std::runtime_error("virtual bus share \"" + path + "\": expected a socket path of 1 to 107 characters");
  }
  a.sun_family = AF_UNIX;
  std::memcpy(a.sun_path, path.c_str(), path.size() + 1);
  return a;
}

// Another live process listens at `a`?
bool someone_listens(const sockaddr_un& a) {
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  const bool yes = ::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) == 0;
  ::close(fd);
  return yes;
}

class BusShare {
 public:
  BusShare(std::shared_ptr<VirtualBus> bus, std::string bus_name, std::string path, int listen_fd)
      : bus_(std::move(bus)), bus_name_(std::move(bus_name)), path_(std::move(path)), listen_fd_(listen_fd) {
    thread_ = std::thread([this] { run(); });
  }
  ~BusShare() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
    for (int c : clients_) ::close(c);
    ::close(listen_fd_);
    ::unlink(path_.c_str());
  }
  BusShare(const BusShare&) = delete;
  BusShare& operator=(const BusShare&) = delete;

 private:
  void accept_client() {
    const int c = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (c < 0) return;
    if (static_cast<int>(clients_.size()) >= kMaxClients) {
      std::fprintf(stderr, "virtual:%s share %s: a client refused, %d are connected already\n", bus_name_.c_str(),
                   path_.c_str(), kMaxClients);
      ::close(c);
      return;
    }
    UnixWireHello hello;
    hello.bitrate = bus_->options().bitrate;
    if (::send(c, &hello, sizeof(hello), MSG_NOSIGNAL) != static_cast<ssize_t>(sizeof(hello))) {
      ::close(c);
      return;
    }
    if (!port_) port_ = bus_->open_port("share:" + path_);  // a controller on the bus while someone listens
    clients_.push_back(c);
  }

  void to_clients(const Frame& f, int except) {
    for (int c : clients_) {
      if (c == except) continue;
      // A client that does not read loses frames, as a controller whose
      // receive queue is full does.
      (void)::send(c, &f, sizeof(f), MSG_DONTWAIT | MSG_NOSIGNAL);
    }
  }

  void drop(std::size_t i) {
    ::close(clients_[i]);
    clients_.erase(clients_.begin() + static_cast<std::ptrdiff_t>(i));
    if (clients_.empty()) port_.reset();
  }

  void run() {
    std::vector<pollfd> fds;
    while (!stop_.load()) {
      fds.assign(1, pollfd{listen_fd_, POLLIN, 0});
      for (int c : clients_) fds.push_back(pollfd{c, POLLIN, 0});
      // With clients: every millisecond (the bus's frames are polled);
      // without: only a new client or the end.
      (void)::poll(fds.data(), fds.size(), clients_.empty() ? 100 : 1);
      if (fds[0].revents & POLLIN) accept_client();
      for (std::size_t i = clients_.size(); i-- > 0;) {
        if (i + 1 >= fds.size() || !(fds[i + 1].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        for (;;) {
          Frame f;
          const ssize_t n = ::recv(clients_[i], &f, sizeof(f), MSG_DONTWAIT);
          if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            drop(i);
            break;
          }
          if (n < 0) break;
          if (n != static_cast<ssize_t>(sizeof(f)) || !is_valid_length(f) || f.is_error()) continue;
          f.timestamp_ns = 0;
          if (port_) (void)port_->send(f);  // refused (queue full, bus-off): lost, as on a busy controller
          to_clients(f, clients_[i]);
        }
      }
      if (port_) {
        Frame f;
        while (port_->receive(f)) to_clients(f, -1);
      }
    }
  }

  std::shared_ptr<VirtualBus> bus_;
  std::string bus_name_, path_;
  int listen_fd_;
  std::unique_ptr<VirtualPort> port_;
  std::vector<int> clients_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace

void share_virtual_bus(const std::shared_ptr<VirtualBus>& bus, const std::string& bus_name, const std::string& path) {
  static std::mutex mutex;
  static std::map<std::string, std::unique_ptr<BusShare>> shares;
  std::lock_guard<std::mutex> lock(mutex);
  if (shares.count(path)) return;
  const sockaddr_un a = address(path);
  const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error("virtual bus share " + path + ": socket: " + std::strerror(errno));
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) != 0) {
    const int e = errno;
    if (e == EADDRINUSE && someone_listens(a)) {
      ::close(fd);
      std::fprintf(stderr,
                   "warning: virtual:%s is not shared with other processes: %s is offered by another process "
                   "(another controller of the same instance?)\n",
                   bus_name.c_str(), path.c_str());
      shares[path] = nullptr;
      return;
    }
    // A socket file left by a process that ended: replace it.
    if (e != EADDRINUSE || ::unlink(path.c_str()) != 0 ||
        ::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) != 0) {
      const int e2 = errno;
      ::close(fd);
      throw std::runtime_error("virtual bus share " + path + ": bind: " + std::strerror(e2));
    }
  }
  if (::listen(fd, kMaxClients) != 0) {
    const int e = errno;
    ::close(fd);
    throw std::runtime_error("virtual bus share " + path + ": listen: " + std::strerror(e));
  }
  shares[path] = std::make_unique<BusShare>(bus, bus_name, path, fd);
}

}  // namespace cnc::can
