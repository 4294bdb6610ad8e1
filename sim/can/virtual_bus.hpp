// An in-process CAN bus for simulation and tests that models what vcan does
// not: every frame occupies the bus for its bit time (nominal, worst-case or
// exact stuffing), pending frames of all ports arbitrate by identifier
// (lowest wins, data before remote, standard before extended), the bus
// accounts its load, and faults can be injected: lost frames, corrupted
// frames (error frame, error counters, automatic retransmission), noise,
// bus-off with recovery after 128 x 11 recessive bits.
//
// Time is either manual (tests call advance(); fully deterministic) or the
// real CLOCK_MONOTONIC (simulated machines; every port call catches the bus
// up). Ports are lock-free queues; the bus engine runs under a try-lock that
// a realtime caller never waits for, so send/receive are realtime-safe.
// Simulation only (sim/): the product opens it as "virtual:<bus>" through
// can::open_transport once register_virtual_transport() has run.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/util/mpmc_ring.hpp"
#include "fieldbus/can/frame_timing.hpp"
#include "fieldbus/can/transport.hpp"

namespace cnc::can {

struct VirtualBusOptions {
  uint32_t bitrate = 1'000'000;
  Stuffing stuffing = Stuffing::WorstCase;
  bool manual_clock = true;     // false: CLOCK_MONOTONIC
  int64_t auto_restart_ns = -1; // bus-off recovery starts by itself after this delay; -1: only on restart()
  // "share" / "share=<path>": also offered to other processes
  // (bus_share.hpp); an empty path with `share` set is the default path.
  bool share = false;
  std::string share_path;
};

struct VirtualBusStats {
  uint64_t frames = 0;              // frames transmitted successfully
  uint64_t bits = 0;                // bit times used, error frames and retransmissions included
  int64_t busy_ns = 0;
  int64_t elapsed_ns = 0;           // since the last reset_stats()
  uint64_t error_frames = 0;
  uint64_t dropped = 0;             // frames lost by injection
  uint64_t arbitration_losses = 0;  // contenders that lost and waited
  uint64_t rx_overruns = 0;         // deliveries refused by full receive queues
  double load() const noexcept {
    return elapsed_ns > 0 ? static_cast<double>(busy_ns) / static_cast<double>(elapsed_ns) : 0.0;
  }
};

class VirtualPort;

// The options of "virtual:<bus>[,bitrate=N][,stuffing=worst|exact|nominal]
// [,share[=<path>]]" after the bus name (`options`, trimmed), on the
// real-time clock; throws
// std::runtime_error naming `spec` and the option at fault.
VirtualBusOptions parse_virtual_options(std::string_view spec, const std::vector<std::string>& options);
// Registers the kind "virtual" with can::open_transport: a port on the
// process-wide bus of that name (VirtualBus::named), created on first use,
// offered to other processes too when the specification says `share`.
void register_virtual_transport();

class VirtualBus : public std::enable_shared_from_this<VirtualBus> {
 public:
  static constexpr std::size_t kMaxPorts = 64;
  static constexpr std::size_t kQueueDepth = 256;
  static constexpr std::size_t kMaxFilters = 32;

  static std::shared_ptr<VirtualBus> create(VirtualBusOptions options = {});
  // A process-wide bus by name, created on first use with `options` (later
  // callers get the existing bus). How in-process simulated devices and the
  // master meet: both open "virtual:<name>".
  static std::shared_ptr<VirtualBus> named(const std::string& name, VirtualBusOptions options);

  ~VirtualBus();
  VirtualBus(const VirtualBus&) = delete;
  VirtualBus& operator=(const VirtualBus&) = delete;

  // A new controller on the bus. Non-realtime. Throws when kMaxPorts are open.
  std::unique_ptr<VirtualPort> open_port(const std::string& name);

  const VirtualBusOptions& options() const noexcept { return options_; }
  int64_t now_ns() const noexcept;
  int64_t bit_time_ns(uint64_t bits) const noexcept;

  // Manual clock: lets `ns` of bus time pass (transmissions, deliveries).
  void advance(int64_t ns);
  void advance_to(int64_t t_ns);
  // Real-time clock: catch up now (ports do this on every call).
  void service() noexcept;
  // Time of the next transmission end or recovery, or INT64_MAX if idle.
  int64_t next_event_ns() const noexcept;

  // --- fault injection (non-realtime) ---
  // The next `count` frames matching `which` are transmitted but never
  // received (by `receiver` only, or by every port when null).
  void drop_next(const Filter& which, unsigned count, const VirtualPort* receiver = nullptr);
  // The next `count` transmissions matching `which` fail with a bit error:
  // an error frame follows, the transmitter's TX error counter rises by 8,
  // every receiver's RX counter by 1, and the frame is retransmitted.
  void corrupt_next(const Filter& which, unsigned count);
  // Noise: `count` error frames on the bus; every controller's RX counter +1.
  void inject_error_frames(unsigned count);
  // Drives the port's controller to bus-off (TX error counter above 255).
  void force_bus_off(VirtualPort& port);

  VirtualBusStats stats() const;
  void reset_stats();

 private:
  explicit VirtualBus(VirtualBusOptions options);
  friend class VirtualPort;

  struct Rule {
    Filter which;
    unsigned remaining = 0;
    const VirtualPort* receiver = nullptr;
  };
  struct InFlight {
    bool active = false;
    bool corrupted = false;
    VirtualPort* port = nullptr;
    int64_t start_ns = 0;
    int64_t end_ns = 0;
    uint32_t bits = 0;
  };

  bool try_lock() const noexcept { return !busy_.test_and_set(std::memory_order_acquire); }
  void lock() const noexcept;
  void unlock() const noexcept { busy_.clear(std::memory_order_release); }

  void run_until(int64_t t) noexcept;       // engine, locked
  void drain_tx() noexcept;
  bool start_next(int64_t t) noexcept;
  void finish(int64_t t) noexcept;
  void deliver(VirtualPort& from, const Frame& f, int64_t t) noexcept;
  void count_error(VirtualPort& p, bool transmitter, int64_t t) noexcept;
  void update_state(VirtualPort& p, int64_t t) noexcept;
  void report(VirtualPort& p, const Frame& error, int64_t t) noexcept;
  void detach(VirtualPort* p) noexcept;

  VirtualBusOptions options_;
  mutable std::atomic_flag busy_ = ATOMIC_FLAG_INIT;
  std::atomic<int64_t> manual_now_{0};
  std::array<VirtualPort*, kMaxPorts> ports_{};
  std::size_t port_count_ = 0;
  std::array<Rule, 16> drop_rules_{};
  std::array<Rule, 16> corrupt_rules_{};
  InFlight in_flight_;
  int64_t bus_free_ns_ = 0;
  std::atomic<int64_t> next_event_{INT64_MAX};
  // Waiters sleep on one word; the engine bumps it after deliveries or when
  // the next event moves earlier, and wakes them only if there are any.
  std::atomic<uint32_t> signal_{0};
  std::atomic<int> waiters_{0};
  bool changed_ = false;
  VirtualBusStats stats_;
  int64_t stats_start_ns_ = 0;
};

class VirtualPort final : public Transport {
 public:
  ~VirtualPort() override;

  const std::string& name() const noexcept override { return name_; }
  SendStatus send(const Frame& f) noexcept override;
  bool receive(Frame& out) noexcept override;
  bool wait(int64_t timeout_ns) noexcept override;
  void set_filters(std::span<const Filter> filters) override;
  void set_error_reports(bool on) override;
  BusState state() const noexcept override { return state_.load(std::memory_order_relaxed); }
  TransportStats stats() const noexcept override;
  uint32_t bitrate() const noexcept override { return bus_->options().bitrate; }
  int64_t now_ns() const noexcept override { return bus_->now_ns(); }

  // Receive this port's own transmissions too (off by default, as SocketCAN).
  void set_receive_own(bool on);
  // The order in which this controller offers its queued frames to
  // arbitration: Fifo (one transmit buffer, as SocketCAN's queue; the
  // default) or Priority (several mailboxes, the pending frame with the
  // lowest identifier first, as most CANopen devices' controllers).
  enum class TxOrder : uint8_t { Fifo, Priority };
  void set_tx_order(TxOrder order);
  // Requests bus-off recovery (as `ip link set canX type can restart`): the
  // controller rejoins after 128 x 11 bit times with cleared counters.
  void restart();
  unsigned tx_error_counter() const noexcept { return tec_.load(std::memory_order_relaxed); }
  unsigned rx_error_counter() const noexcept { return rec_.load(std::memory_order_relaxed); }
  uint64_t tx_bits() const noexcept { return tx_bits_.load(std::memory_order_relaxed); }
  VirtualBus& bus() noexcept { return *bus_; }

 private:
  friend class VirtualBus;
  VirtualPort(std::shared_ptr<VirtualBus> bus, std::string name);

  struct Pending {
    Frame frame;
    int64_t enqueue_ns;
  };
  bool accepts(const Frame& f) const noexcept;
  // Engine side: the earliest enqueue time among the staged frames, and
  // (Priority order) moves the best frame queued by `start` to the head.
  int64_t earliest_staged_ns() const noexcept;
  bool head_ready(int64_t start) noexcept;

  std::shared_ptr<VirtualBus> bus_;
  std::string name_;
  MpmcRing<Pending, VirtualBus::kQueueDepth> tx_;
  MpmcRing<Frame, VirtualBus::kQueueDepth> rx_;

  // Engine-owned (changed under the bus lock).
  std::array<Filter, VirtualBus::kMaxFilters> filters_{};
  std::size_t filter_count_ = 0;
  bool error_reports_ = true;
  bool receive_own_ = false;
  TxOrder tx_order_ = TxOrder::Fifo;
  std::array<Pending, VirtualBus::kQueueDepth> staged_{};
  std::size_t staged_head_ = 0;
  std::size_t staged_count_ = 0;
  int64_t restart_at_ns_ = -1;
  BusState engine_state_ = BusState::ErrorActive;

  std::atomic<unsigned> tec_{0};
  std::atomic<unsigned> rec_{0};
  std::atomic<BusState> state_{BusState::ErrorActive};
  std::atomic<uint64_t> tx_frames_{0}, rx_frames_{0}, tx_rejected_{0}, rx_overruns_{0}, error_frames_{0};
  std::atomic<uint64_t> tx_bits_{0};
};

}  // namespace cnc::can
