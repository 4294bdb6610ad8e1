// A CAN bus offered by another process on a local socket: "unix:<path>".
//
// The process that owns a bus (the simulators' in-process bus shared by
// cncd, sim/can/bus_share.hpp) listens on a Unix SOCK_SEQPACKET socket;
// each connected process is one more controller on that bus. Every message
// is one frame (UnixWireFrame); on connection the owner first sends a
// UnixWireHello with the bus's bit rate. The owner forwards every frame of
// the bus to every client and every client's frame onto the bus (and to the
// other clients), so a client sees the bus as a controller on it does: not
// its own frames, everyone else's. Used by `cnc-commission scan` and
// `backup` to reach the simulated drives that live inside a running cncd,
// as they would reach real drives on socketcan:can0.
//
// send/receive never block and never allocate (non-blocking socket calls);
// wait() is for non-realtime threads. When the owner goes away, send()
// returns Down and state() says BusOff (nothing can be sent any more).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>

#include "fieldbus/can/transport.hpp"

namespace cnc::can {

struct UnixWireHello {
  std::array<char, 8> magic{{'C', 'N', 'C', 'C', 'A', 'N', '1', '\0'}};
  uint32_t bitrate = 0;
  uint32_t reserved = 0;
};

// One frame on the socket: the Frame as it is in memory (both ends are
// processes of the same build on the same machine).
using UnixWireFrame = Frame;

class UnixSocketTransport final : public Transport {
 public:
  static constexpr std::size_t kMaxFilters = 32;

  // Connects to the bus offered at `path` and reads its hello; throws
  // std::runtime_error naming `spec` and the path when nothing listens there
  // or the answer is not a bus.
  UnixSocketTransport(const std::string& spec, const std::string& path);
  ~UnixSocketTransport() override;
  UnixSocketTransport(const UnixSocketTransport&) = delete;
  UnixSocketTransport& operator=(const UnixSocketTransport&) = delete;

  const std::string& name() const noexcept override { return name_; }
  SendStatus send(const Frame& f) noexcept override;
  bool receive(Frame& out) noexcept override;
  bool wait(int64_t timeout_ns) noexcept override;
  void set_filters(std::span<const Filter> filters) override;
  void set_error_reports(bool on) override { error_reports_ = on; }
  BusState state() const noexcept override {
    return connected_.load(std::memory_order_relaxed) ? BusState::ErrorActive : BusState::BusOff;
  }
  TransportStats stats() const noexcept override;
  uint32_t bitrate() const noexcept override { return bitrate_; }

 private:
  bool accepts(const Frame& f) const noexcept;

  std::string name_;
  int fd_ = -1;
  uint32_t bitrate_ = 0;
  std::array<Filter, kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  bool error_reports_ = true;
  std::atomic<bool> connected_{true};
  std::atomic<uint64_t> tx_frames_{0}, rx_frames_{0}, tx_rejected_{0}, error_frames_{0}, malformed_{0};
};

}  // namespace cnc::can
