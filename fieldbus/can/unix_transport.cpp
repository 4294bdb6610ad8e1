#include "fieldbus/can/unix_transport.hpp"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <type_traits>

#include "core/util/time.hpp"

namespace cnc::can {

static_assert(std::is_trivially_copyable_v<UnixWireFrame>, "frames travel as their bytes");
static_assert(std::is_trivially_copyable_v<UnixWireHello>);

UnixSocketTransport::UnixSocketTransport(const std::string& spec, const std::string& path) : name_("unix:" + path) {
  const auto fail = [&](const std::string& why) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    throw std::runtime_error("CAN interface \"" + spec + "\": " + why);
  };
  sockaddr_un addr{};
  if (path.empty() || path.size() >= sizeof(addr.sun_path)) fail("expected unix:<socket path> of at most 107 characters");
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
  fd_ = ::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  if (fd_ < 0) fail(std::string("socket: ") + std::strerror(errno));
  if (::connect(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int e = errno;
    fail("nothing offers a bus at " + path + " (" + std::strerror(e) +
         "): is the controller that owns it running (cncd with INTERFACE = virtual:<bus>,share)?");
  }
  // The hello, within a second.
  pollfd p{fd_, POLLIN, 0};
  if (::poll(&p, 1, 1000) != 1) fail(path + " did not greet within 1 s: not a CAN bus socket");
  UnixWireHello hello;
  const ssize_t n = ::recv(fd_, &hello, sizeof(hello), 0);
  if (n != static_cast<ssize_t>(sizeof(hello)) || hello.magic != UnixWireHello{}.magic) {
    fail(path + " answered something other than a CAN bus greeting");
  }
  bitrate_ = hello.bitrate;
}

UnixSocketTransport::~UnixSocketTransport() {
  if (fd_ >= 0) ::close(fd_);
}

SendStatus UnixSocketTransport::send(const Frame& f) noexcept {
  if (f.is_error() || !is_valid_length(f)) {
    tx_rejected_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::Invalid;
  }
  if (!connected_.load(std::memory_order_relaxed)) {
    tx_rejected_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::Down;
  }
  const ssize_t n = ::send(fd_, &f, sizeof(UnixWireFrame), MSG_DONTWAIT | MSG_NOSIGNAL);
  if (n == static_cast<ssize_t>(sizeof(UnixWireFrame))) {
    tx_frames_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::Ok;
  }
  tx_rejected_.fetch_add(1, std::memory_order_relaxed);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) return SendStatus::WouldBlock;
  if (n < 0 && (errno == EPIPE || errno == ECONNRESET || errno == ENOTCONN)) {
    connected_.store(false, std::memory_order_relaxed);
    return SendStatus::Down;
  }
  return SendStatus::Error;
}

bool UnixSocketTransport::accepts(const Frame& f) const noexcept {
  if (f.is_error()) return error_reports_;
  if (filter_count_ == 0) return true;
  for (std::size_t i = 0; i < filter_count_; ++i) {
    if (filters_[i].matches(f)) return true;
  }
  return false;
}

bool UnixSocketTransport::receive(Frame& out) noexcept {
  while (connected_.load(std::memory_order_relaxed)) {
    Frame f;
    const ssize_t n = ::recv(fd_, &f, sizeof(f), MSG_DONTWAIT);
    if (n == 0) {  // the owner closed the bus
      connected_.store(false, std::memory_order_relaxed);
      return false;
    }
    if (n < 0) {
      if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) connected_.store(false, std::memory_order_relaxed);
      return false;
    }
    if (n != static_cast<ssize_t>(sizeof(f)) || !is_valid_length(f)) {  // not a frame of this build
      malformed_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    if (f.is_error()) error_frames_.fetch_add(1, std::memory_order_relaxed);
    if (!accepts(f)) continue;
    if (f.timestamp_ns == 0) f.timestamp_ns = monotonic_ns();
    rx_frames_.fetch_add(1, std::memory_order_relaxed);
    out = f;
    return true;
  }
  return false;
}

bool UnixSocketTransport::wait(int64_t timeout_ns) noexcept {
  if (!connected_.load(std::memory_order_relaxed)) return false;
  pollfd p{fd_, POLLIN, 0};
  const int ms = timeout_ns <= 0 ? 0 : static_cast<int>((timeout_ns + 999'999) / 1'000'000);
  return ::poll(&p, 1, ms) > 0;
}

void UnixSocketTransport::set_filters(std::span<const Filter> filters) {
  if (filters.size() > kMaxFilters) {
    throw std::runtime_error(name_ + ": at most " + std::to_string(kMaxFilters) + " receive filters");
  }
  filter_count_ = 0;
  for (const Filter& f : filters) filters_[filter_count_++] = f;
}

TransportStats UnixSocketTransport::stats() const noexcept {
  TransportStats s;
  s.tx_frames = tx_frames_.load(std::memory_order_relaxed);
  s.rx_frames = rx_frames_.load(std::memory_order_relaxed);
  s.tx_rejected = tx_rejected_.load(std::memory_order_relaxed);
  s.error_frames = error_frames_.load(std::memory_order_relaxed);
  s.rx_overruns = malformed_.load(std::memory_order_relaxed);  // messages that were no frame: lost
  return s;
}

}  // namespace cnc::can
