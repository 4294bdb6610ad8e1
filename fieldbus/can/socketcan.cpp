#include "fieldbus/can/socketcan.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/netlink.h>
#include <linux/can/raw.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "core/util/time.hpp"

namespace cnc::can {
namespace {

[[noreturn]] void fail(const std::string& ifname, const char* what) {
  throw std::system_error(errno, std::generic_category(), "SocketCAN " + ifname + ": " + what);
}

uint32_t to_kernel_id(const Frame& f) noexcept {
  uint32_t id = f.is_extended() ? ((f.id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (f.id & CAN_SFF_MASK);
  if (f.is_remote()) id |= CAN_RTR_FLAG;
  return id;
}

void from_kernel_id(canid_t id, Frame& f) noexcept {
  f.flags = 0;
  if (id & CAN_ERR_FLAG) {
    f.flags |= kError;
    f.id = id & CAN_ERR_MASK;
    return;
  }
  if (id & CAN_EFF_FLAG) {
    f.flags |= kExtended;
    f.id = id & CAN_EFF_MASK;
  } else {
    f.id = id & CAN_SFF_MASK;
  }
  if (id & CAN_RTR_FLAG) f.flags |= kRemote;
}

// The attribute of `type` among the rtattrs in [data, data + len), or null.
const rtattr* find_attribute(const uint8_t* data, std::size_t len, unsigned short type) noexcept {
  std::size_t off = 0;
  while (off + sizeof(rtattr) <= len) {
    rtattr a;
    std::memcpy(&a, data + off, sizeof a);
    if (a.rta_len < sizeof(rtattr) || off + a.rta_len > len) return nullptr;
    if ((a.rta_type & NLA_TYPE_MASK) == type) return reinterpret_cast<const rtattr*>(data + off);
    off += RTA_ALIGN(a.rta_len);
  }
  return nullptr;
}

std::string bring_up_hint(const std::string& ifname, uint32_t bitrate) {
  return "bring it up at the bus's bitrate: sudo cnc-can-up MACHINE.ini, or sudo cnc-can-up " + ifname + " " +
         std::to_string(bitrate ? bitrate : 1000000) + " (docs/install.md, \"CAN interfaces\")";
}

}  // namespace

uint32_t can_bitrate_in_link_message(std::span<const uint8_t> m) noexcept {
  const std::size_t head = NLMSG_LENGTH(sizeof(ifinfomsg));
  if (m.size() < head) return 0;
  nlmsghdr h;
  std::memcpy(&h, m.data(), sizeof h);
  if (h.nlmsg_type != RTM_NEWLINK || h.nlmsg_len < head || h.nlmsg_len > m.size()) return 0;
  const uint8_t* attrs = m.data() + NLMSG_ALIGN(head);
  const std::size_t attrs_len = h.nlmsg_len - NLMSG_ALIGN(head);
  const rtattr* info = find_attribute(attrs, attrs_len, IFLA_LINKINFO);
  if (!info) return 0;
  const auto* info_data = reinterpret_cast<const uint8_t*>(RTA_DATA(info));
  const rtattr* data = find_attribute(info_data, RTA_PAYLOAD(info), IFLA_INFO_DATA);
  if (!data) return 0;
  const rtattr* timing =
      find_attribute(reinterpret_cast<const uint8_t*>(RTA_DATA(data)), RTA_PAYLOAD(data), IFLA_CAN_BITTIMING);
  if (!timing || RTA_PAYLOAD(timing) < sizeof(can_bittiming)) return 0;
  can_bittiming bt;
  std::memcpy(&bt, RTA_DATA(timing), sizeof bt);
  return bt.bitrate;
}

uint32_t read_can_bitrate(unsigned ifindex) noexcept {
  const int s = ::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
  if (s < 0) return 0;
  struct {
    nlmsghdr h;
    ifinfomsg i;
  } req{};
  req.h.nlmsg_len = NLMSG_LENGTH(sizeof(ifinfomsg));
  req.h.nlmsg_type = RTM_GETLINK;
  req.h.nlmsg_flags = NLM_F_REQUEST;
  req.h.nlmsg_seq = 1;
  req.i.ifi_family = AF_UNSPEC;
  req.i.ifi_index = static_cast<int>(ifindex);
  uint32_t bitrate = 0;
  if (::send(s, &req, req.h.nlmsg_len, 0) == static_cast<ssize_t>(req.h.nlmsg_len)) {
    std::vector<uint8_t> buf(16384);
    pollfd p{s, POLLIN, 0};
    if (::poll(&p, 1, 1000) > 0) {
      const ssize_t n = ::recv(s, buf.data(), buf.size(), 0);
      if (n > 0) bitrate = can_bitrate_in_link_message({buf.data(), static_cast<std::size_t>(n)});
    }
  }
  ::close(s);
  return bitrate;
}

bool SocketCanTransport::available() noexcept {
  const int s = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (s < 0) return false;
  ::close(s);
  return true;
}

SocketCanTransport::SocketCanTransport(const std::string& ifname, SocketCanOptions options)
    : name_("socketcan:" + ifname), options_(options) {
  if (ifname.empty() || ifname.size() >= IFNAMSIZ) {
    errno = EINVAL;
    fail(ifname, "interface name");
  }
  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) fail(ifname, "socket(PF_CAN, SOCK_RAW, CAN_RAW) (is the can-raw module loaded?)");
  try {
    const unsigned index = ::if_nametoindex(ifname.c_str());
    if (index == 0) fail(ifname, "no such interface");
    // An interface that is down or at another bitrate than the bus is
    // configured for would only show as missing devices: say what it is.
    ifreq ifr{};
    std::memcpy(ifr.ifr_name, ifname.c_str(), ifname.size() + 1);
    if (::ioctl(fd_, SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) {
      throw std::runtime_error("SocketCAN " + ifname + ": the interface is down: " +
                               bring_up_hint(ifname, options_.expected_bitrate));
    }
    bitrate_ = read_can_bitrate(index);
    if (options_.expected_bitrate != 0 && bitrate_ != 0 && bitrate_ != options_.expected_bitrate) {
      throw std::runtime_error("SocketCAN " + ifname + ": the interface runs at " + std::to_string(bitrate_) +
                               " bit/s, the configuration says " + std::to_string(options_.expected_bitrate) +
                               " (BITRATE): " + bring_up_hint(ifname, options_.expected_bitrate));
    }
    if (options_.fd) {
      const int on = 1;
      if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) fail(ifname, "CAN_RAW_FD_FRAMES");
    }
    if (options_.receive_own) {
      const int on = 1;
      if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &on, sizeof on) < 0) fail(ifname, "CAN_RAW_RECV_OWN_MSGS");
    }
    const can_err_mask_t err_mask = options_.error_reports ? CAN_ERR_MASK : 0;
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) fail(ifname, "CAN_RAW_ERR_FILTER");
    const int on = 1;
    if (::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0) fail(ifname, "SO_TIMESTAMPNS");
    if (::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) fail(ifname, "SO_RXQ_OVFL");
    if (options_.receive_buffer_bytes > 0) {
      ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &options_.receive_buffer_bytes, sizeof(int));
    }
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(index);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) fail(ifname, "bind");
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

SocketCanTransport::~SocketCanTransport() {
  if (fd_ >= 0) ::close(fd_);
}

SendStatus SocketCanTransport::send(const Frame& f) noexcept {
  if (f.is_error() || !is_valid_length(f) || (f.is_fd() && !options_.fd)) {
    ++stats_.tx_rejected;
    return SendStatus::Invalid;
  }
  ssize_t n;
  if (f.is_fd()) {
    canfd_frame k{};
    k.can_id = to_kernel_id(f);
    k.len = f.len;
    k.flags = static_cast<uint8_t>(((f.flags & kBitRateSwitch) ? CANFD_BRS : 0) |
                                   ((f.flags & kErrorStateIndicator) ? CANFD_ESI : 0));
    std::memcpy(k.data, f.data.data(), f.len);
    n = ::send(fd_, &k, sizeof k, MSG_DONTWAIT);
  } else {
    can_frame k{};
    k.can_id = to_kernel_id(f);
    k.len = f.len;
    if (!f.is_remote()) std::memcpy(k.data, f.data.data(), f.len);
    n = ::send(fd_, &k, sizeof k, MSG_DONTWAIT);
  }
  if (n > 0) {
    ++stats_.tx_frames;
    return SendStatus::Ok;
  }
  ++stats_.tx_rejected;
  switch (errno) {
    case EAGAIN:
    case ENOBUFS:
      // A bus-off controller stops the interface queue.
      return state_.load(std::memory_order_relaxed) == BusState::BusOff ? SendStatus::BusOff : SendStatus::WouldBlock;
    case ENETDOWN:
    case ENXIO:
    case ENODEV: return SendStatus::Down;
    case EINVAL: return SendStatus::Invalid;
    default: return SendStatus::Error;
  }
}

int64_t SocketCanTransport::monotonic_from_realtime(int64_t real_ns) noexcept {
  // A clock step (settime, a leap) moves the offset by far more than this;
  // the error of one bracketed reading is half its bracket, microseconds.
  constexpr int64_t kClockStepNs = 500'000;
  // One reading of the offset between two monotonic reads; its error is at
  // most half the bracket's width.
  const auto read_offset = [](int64_t& width) noexcept {
    const int64_t m1 = monotonic_ns();
    const int64_t r = realtime_ns();
    const int64_t m2 = monotonic_ns();
    width = m2 - m1;
    return r - (m1 + width / 2);
  };
  int64_t width = 0;
  int64_t offset = read_offset(width);
  if (clock_offset_valid_ && std::llabs(offset - clock_offset_ns_) <= kClockStepNs) return real_ns - clock_offset_ns_;
  // First frame, a clock step or a reading that was preempted: the best of
  // a few readings decides.
  for (int i = 0; i < 3; ++i) {
    int64_t w = 0;
    const int64_t o = read_offset(w);
    if (w < width) {
      width = w;
      offset = o;
    }
  }
  const bool stepped = std::llabs(offset - clock_offset_ns_) > kClockStepNs;
  if (!clock_offset_valid_ || (stepped && width < kClockStepNs)) {
    clock_offset_ns_ = offset;
    clock_offset_valid_ = true;
  }
  return real_ns - clock_offset_ns_;
}

bool SocketCanTransport::receive(Frame& out) noexcept {
  canfd_frame k{};
  iovec iov{&k, sizeof k};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(uint32_t)) + 64];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
  if (n < static_cast<ssize_t>(CAN_MTU)) return false;

  out = Frame{};
  from_kernel_id(k.can_id, out);
  if (n == static_cast<ssize_t>(CANFD_MTU)) {
    out.flags |= kFd;
    if (k.flags & CANFD_BRS) out.flags |= kBitRateSwitch;
    if (k.flags & CANFD_ESI) out.flags |= kErrorStateIndicator;
    out.len = k.len > kFdMaxData ? kFdMaxData : k.len;
  } else {
    out.len = k.len > kClassicMaxData ? kClassicMaxData : k.len;
  }
  if (!(out.flags & kRemote)) std::memcpy(out.data.data(), k.data, out.len);

  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec ts;
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      const int64_t real = static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      out.timestamp_ns = monotonic_from_realtime(real);
    } else if (c->cmsg_type == SO_RXQ_OVFL) {
      uint32_t drops;
      std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
      stats_.rx_overruns += drops - last_drop_count_;
      last_drop_count_ = drops;
    }
  }
  if (out.is_error()) {
    ++stats_.error_frames;
    tracker_.on_error_frame(out);
    state_.store(tracker_.state(), std::memory_order_relaxed);
  } else {
    ++stats_.rx_frames;
  }
  return true;
}

bool SocketCanTransport::wait(int64_t timeout_ns) noexcept {
  pollfd p{fd_, POLLIN, 0};
  const int ms = timeout_ns <= 0 ? 0 : static_cast<int>((timeout_ns + 999'999) / 1'000'000);
  return ::poll(&p, 1, ms) > 0;
}

void SocketCanTransport::set_filters(std::span<const Filter> filters) {
  std::vector<can_filter> k;
  k.reserve(filters.size());
  for (const auto& f : filters) {
    can_filter c{};
    c.can_id = f.id & (f.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    c.can_mask = f.mask & CAN_EFF_MASK;
    if (f.extended) c.can_id |= CAN_EFF_FLAG;
    if (f.match_extended) c.can_mask |= CAN_EFF_FLAG;
    k.push_back(c);
  }
  if (k.empty()) {
    can_filter all{0, 0};
    k.push_back(all);
  }
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, k.data(), static_cast<socklen_t>(k.size() * sizeof(can_filter))) < 0) {
    fail(name_, "CAN_RAW_FILTER");
  }
}

void SocketCanTransport::set_error_reports(bool on) {
  const can_err_mask_t err_mask = on ? CAN_ERR_MASK : 0;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) fail(name_, "CAN_RAW_ERR_FILTER");
  options_.error_reports = on;
}

TransportStats SocketCanTransport::stats() const noexcept { return stats_; }

}  // namespace cnc::can
