// SocketCAN raw socket transport (Linux AF_CAN): receive filters, error
// frames with bus-off / error-passive tracking, non-blocking send and
// receive for the servo thread, kernel receive timestamps converted to
// CLOCK_MONOTONIC, receive-queue overruns counted (SO_RXQ_OVFL). Opening
// throws; send/receive never block, allocate or throw.
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <string>

#include "fieldbus/can/transport.hpp"

namespace cnc::can {

struct SocketCanOptions {
  bool fd = false;              // accept and send CAN FD frames (CAN_RAW_FD_FRAMES)
  bool error_reports = true;    // receive error frames (all classes)
  bool receive_own = false;     // receive our own transmissions (CAN_RAW_RECV_OWN_MSGS)
  int receive_buffer_bytes = 0; // SO_RCVBUF; 0 = kernel default
  // The configuration's bitrate (spec option bitrate=N): an interface the
  // kernel reports at another bitrate is refused, naming both. 0 = not
  // checked. Interfaces without bit timing (vcan) are never refused.
  uint32_t expected_bitrate = 0;
};

// The bitrate in an rtnetlink RTM_NEWLINK message (nlmsghdr, ifinfomsg,
// then IFLA_LINKINFO > IFLA_INFO_DATA > IFLA_CAN_BITTIMING), 0 when it has
// none (vcan, not a CAN interface, a truncated message).
uint32_t can_bitrate_in_link_message(std::span<const uint8_t> message) noexcept;
// Asks the kernel (rtnetlink RTM_GETLINK) for the interface's bitrate; 0
// when it has none or cannot be asked.
uint32_t read_can_bitrate(unsigned ifindex) noexcept;

class SocketCanTransport final : public Transport {
 public:
  // Throws std::system_error naming the interface and the failing call,
  // and std::runtime_error for an interface that is down or at another
  // bitrate than options.expected_bitrate (saying how to bring it up).
  explicit SocketCanTransport(const std::string& ifname, SocketCanOptions options = {});
  ~SocketCanTransport() override;
  SocketCanTransport(const SocketCanTransport&) = delete;
  SocketCanTransport& operator=(const SocketCanTransport&) = delete;

  const std::string& name() const noexcept override { return name_; }
  SendStatus send(const Frame& f) noexcept override;
  bool receive(Frame& out) noexcept override;
  bool wait(int64_t timeout_ns) noexcept override;
  void set_filters(std::span<const Filter> filters) override;
  void set_error_reports(bool on) override;
  BusState state() const noexcept override { return state_.load(std::memory_order_relaxed); }
  TransportStats stats() const noexcept override;
  uint32_t bitrate() const noexcept override { return bitrate_; }

  int fd() const noexcept { return fd_; }
  // True when the kernel offers AF_CAN raw sockets at all (for tests to skip).
  static bool available() noexcept;

 private:
  int fd_ = -1;
  std::string name_;
  SocketCanOptions options_;
  uint32_t bitrate_ = 0;
  BusStateTracker tracker_;
  std::atomic<BusState> state_{BusState::ErrorActive};
  uint32_t last_drop_count_ = 0;
  // CLOCK_REALTIME - CLOCK_MONOTONIC, for turning the kernel's receive
  // stamps into monotonic time. Kept while the clocks agree with it to within
  // kClockStepNs, so that stamps of successive frames keep their order (a
  // fresh offset per frame carries the jitter between its two clock reads).
  int64_t clock_offset_ns_ = 0;
  bool clock_offset_valid_ = false;
  int64_t monotonic_from_realtime(int64_t real_ns) noexcept;
  TransportStats stats_;
};

}  // namespace cnc::can
