// The raw AF_PACKET link: one socket bound to the interface and to
// EtherType 0x88A4; the kernel delivers every incoming EtherCAT frame to
// every such socket, so each user filters by datagram index. Our own
// outgoing frames are not delivered (a socket bound to one protocol is not
// a tap, and PACKET_IGNORE_OUTGOING says so explicitly); the source MAC is
// no filter because a veth MAC has the bit a returning ESC sets.
#include <arpa/inet.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "fieldbus/ethercat/link.hpp"

#ifndef PACKET_IGNORE_OUTGOING
#define PACKET_IGNORE_OUTGOING 23
#endif

namespace cnc::ethercat {
namespace {

class RawLink final : public Link {
 public:
  explicit RawLink(const std::string& iface) : name_("raw:" + iface) {
    if (iface.empty() || iface.size() >= IFNAMSIZ) throw std::runtime_error("raw link: bad interface name \"" + iface + "\"");
    fd_ = ::socket(AF_PACKET, SOCK_RAW | SOCK_CLOEXEC, htons(kEtherType));
    if (fd_ < 0) {
      throw std::runtime_error("raw link on " + iface + ": socket(AF_PACKET): " + std::strerror(errno) +
                               (errno == EPERM ? " (needs root or CAP_NET_RAW)" : ""));
    }
    ifreq ifr{};
    std::strncpy(ifr.ifr_name, iface.c_str(), IFNAMSIZ - 1);
    if (::ioctl(fd_, SIOCGIFINDEX, &ifr) < 0) fail(iface, "no such interface");
    const int ifindex = ifr.ifr_ifindex;
    if (::ioctl(fd_, SIOCGIFHWADDR, &ifr) == 0) std::memcpy(mac_, ifr.ifr_hwaddr.sa_data, 6);
    if (::ioctl(fd_, SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) fail(iface, "interface is down");
    sockaddr_ll sll{};
    sll.sll_family = AF_PACKET;
    sll.sll_protocol = htons(kEtherType);
    sll.sll_ifindex = ifindex;
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&sll), sizeof sll) < 0) fail(iface, "bind");
    int one = 1;
    (void)::setsockopt(fd_, SOL_PACKET, PACKET_IGNORE_OUTGOING, &one, sizeof one);
    int buf = 1 << 20;
    (void)::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &buf, sizeof buf);
    (void)::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &buf, sizeof buf);
  }
  ~RawLink() override {
    if (fd_ >= 0) ::close(fd_);
  }

  const std::string& name() const noexcept override { return name_; }
  const Mac& mac() const noexcept override { return mac_; }

  bool send(const uint8_t* frame, std::size_t size) noexcept override {
    const ssize_t n = ::send(fd_, frame, size, MSG_DONTWAIT);
    return n == static_cast<ssize_t>(size);
  }

  std::size_t receive(uint8_t* buffer, int64_t timeout_ns) noexcept override {
    for (;;) {
      const ssize_t n = ::recv(fd_, buffer, kMaxFrame, MSG_DONTWAIT);
      if (n > 0) {
        if (static_cast<std::size_t>(n) < kEthHeader) continue;
        return static_cast<std::size_t>(n);
      }
      if (n < 0 && errno == EINTR) continue;
      if (timeout_ns <= 0) return 0;
      pollfd p{fd_, POLLIN, 0};
      const int ms = static_cast<int>((timeout_ns + 999'999) / 1'000'000);
      const int r = ::poll(&p, 1, ms);
      if (r <= 0) return 0;
      timeout_ns = 0;  // one wait only; then drain what arrived
      const ssize_t m = ::recv(fd_, buffer, kMaxFrame, MSG_DONTWAIT);
      if (m > 0 && static_cast<std::size_t>(m) >= kEthHeader) {
        return static_cast<std::size_t>(m);
      }
      if (m <= 0) return 0;
    }
  }

 private:
  [[noreturn]] void fail(const std::string& iface, const char* what) {
    const std::string e = std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error("raw link on " + iface + ": " + what + ": " + e);
  }

  std::string name_;
  int fd_ = -1;
  Mac mac_{};
};

}  // namespace

std::unique_ptr<Link> open_raw_link(const std::string& interface) { return std::make_unique<RawLink>(interface); }

}  // namespace cnc::ethercat
