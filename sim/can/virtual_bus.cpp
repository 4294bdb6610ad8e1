#include "sim/can/virtual_bus.hpp"

#include "sim/can/bus_share.hpp"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "core/util/strings.hpp"
#include "core/util/time.hpp"

namespace cnc::can {
namespace {

// Bit-level arbitration order: the identifier bits are compared first;
// after the 11 base bits a standard frame sends RTR (dominant for data)
// and IDE = 0, an extended frame SRR = 1 and IDE = 1, so standard frames
// win against extended ones with the same base identifier.
uint64_t arbitration_key(const Frame& f) noexcept {
  const bool rtr = f.is_remote();
  if (!f.is_extended()) {
    return (static_cast<uint64_t>(f.id & kStandardIdMask) << 21) | (static_cast<uint64_t>(rtr) << 20);
  }
  const uint64_t base = (f.id >> 18) & kStandardIdMask;
  return (base << 21) | (1ULL << 20) | (1ULL << 19) | (static_cast<uint64_t>(f.id & 0x3FFFF) << 1) | rtr;
}

long futex_wait(std::atomic<uint32_t>* word, uint32_t expected, int64_t timeout_ns) noexcept {
  timespec ts = to_timespec(timeout_ns < 0 ? 0 : timeout_ns);
  return ::syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), FUTEX_WAIT_PRIVATE, expected, &ts, nullptr, 0);
}

void futex_wake(std::atomic<uint32_t>* word) noexcept {
  ::syscall(SYS_futex, reinterpret_cast<uint32_t*>(word), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr, nullptr, 0);
}

}  // namespace

// ---------------------------------------------------------------- VirtualBus

VirtualBus::VirtualBus(VirtualBusOptions options) : options_(options) {
  if (options_.bitrate == 0) throw std::invalid_argument("virtual CAN bus: bit rate must be positive");
  stats_start_ns_ = now_ns();
  bus_free_ns_ = stats_start_ns_;
}

VirtualBus::~VirtualBus() = default;

std::shared_ptr<VirtualBus> VirtualBus::create(VirtualBusOptions options) {
  return std::shared_ptr<VirtualBus>(new VirtualBus(options));
}

std::shared_ptr<VirtualBus> VirtualBus::named(const std::string& name, VirtualBusOptions options) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<VirtualBus>> buses;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = buses[name];
  if (!slot) slot = create(options);
  return slot;
}

void VirtualBus::lock() const noexcept {
  while (!try_lock()) std::this_thread::yield();
}

int64_t VirtualBus::now_ns() const noexcept {
  return options_.manual_clock ? manual_now_.load(std::memory_order_acquire) : monotonic_ns();
}

int64_t VirtualBus::bit_time_ns(uint64_t bits) const noexcept {
  return static_cast<int64_t>((bits * 1'000'000'000ULL + options_.bitrate / 2) / options_.bitrate);
}

std::unique_ptr<VirtualPort> VirtualBus::open_port(const std::string& name) {
  std::unique_ptr<VirtualPort> port(new VirtualPort(shared_from_this(), name));
  lock();
  if (port_count_ == kMaxPorts) {
    unlock();
    throw std::runtime_error("virtual CAN bus: more than " + std::to_string(kMaxPorts) + " ports");
  }
  ports_[port_count_++] = port.get();
  unlock();
  return port;
}

void VirtualBus::detach(VirtualPort* p) noexcept {
  lock();
  for (std::size_t i = 0; i < port_count_; ++i) {
    if (ports_[i] == p) {
      ports_[i] = ports_[--port_count_];
      ports_[port_count_] = nullptr;
      break;
    }
  }
  if (in_flight_.active && in_flight_.port == p) in_flight_ = InFlight{};  // the controller vanished mid-frame
  for (auto& r : drop_rules_) {
    if (r.receiver == p) r = Rule{};
  }
  unlock();
}

void VirtualBus::advance(int64_t ns) { advance_to(now_ns() + (ns > 0 ? ns : 0)); }

void VirtualBus::advance_to(int64_t t_ns) {
  if (!options_.manual_clock) throw std::logic_error("virtual CAN bus: advance() needs the manual clock");
  lock();
  if (t_ns > manual_now_.load(std::memory_order_relaxed)) {
    run_until(t_ns);
    manual_now_.store(t_ns, std::memory_order_release);
  } else {
    run_until(manual_now_.load(std::memory_order_relaxed));
  }
  unlock();
}

void VirtualBus::service() noexcept {
  if (!try_lock()) return;
  run_until(now_ns());
  unlock();
}

int64_t VirtualBus::next_event_ns() const noexcept { return next_event_.load(std::memory_order_acquire); }

void VirtualBus::drain_tx() noexcept {
  for (std::size_t i = 0; i < port_count_; ++i) {
    VirtualPort& p = *ports_[i];
    VirtualPort::Pending pending;
    while (p.staged_count_ < p.staged_.size() && p.tx_.pop(pending)) {
      if (p.engine_state_ == BusState::BusOff) {
        p.tx_rejected_.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      p.staged_[(p.staged_head_ + p.staged_count_) % p.staged_.size()] = pending;
      ++p.staged_count_;
    }
  }
}

// The engine: transmissions in time order up to `t`.
void VirtualBus::run_until(int64_t t) noexcept {
  drain_tx();
  for (;;) {
    if (in_flight_.active) {
      if (in_flight_.end_ns > t) break;
      finish(in_flight_.end_ns);
      continue;
    }
    // Recoveries due before the next transmission could start.
    int64_t restart = INT64_MAX;
    VirtualPort* restarting = nullptr;
    for (std::size_t i = 0; i < port_count_; ++i) {
      VirtualPort* p = ports_[i];
      if (p->restart_at_ns_ >= 0 && p->restart_at_ns_ < restart) {
        restart = p->restart_at_ns_;
        restarting = p;
      }
    }
    if (restarting && restart <= t) {
      restarting->restart_at_ns_ = -1;
      restarting->tec_.store(0, std::memory_order_relaxed);
      restarting->rec_.store(0, std::memory_order_relaxed);
      restarting->engine_state_ = BusState::ErrorActive;
      restarting->state_.store(BusState::ErrorActive, std::memory_order_relaxed);
      report(*restarting, make_error_frame(kErrRestarted | kErrCounters, 0, 0, 0, 0), restart);
      if (bus_free_ns_ < restart) bus_free_ns_ = restart;
      continue;
    }
    if (!start_next(t)) break;
  }
  // When something will happen next, for waiters that sleep meanwhile.
  int64_t next = in_flight_.active ? in_flight_.end_ns : INT64_MAX;
  for (std::size_t i = 0; i < port_count_; ++i) {
    const VirtualPort* p = ports_[i];
    if (p->restart_at_ns_ >= 0 && p->restart_at_ns_ < next) next = p->restart_at_ns_;
    if (!in_flight_.active && p->staged_count_ > 0) {
      const int64_t s = std::max(bus_free_ns_, p->earliest_staged_ns());
      if (s < next) next = s;
    }
  }
  if (next < next_event_.load(std::memory_order_relaxed)) changed_ = true;
  next_event_.store(next, std::memory_order_release);
  stats_.elapsed_ns = t - stats_start_ns_;
  if (changed_) {
    changed_ = false;
    signal_.fetch_add(1, std::memory_order_release);
    if (waiters_.load(std::memory_order_acquire) > 0) futex_wake(&signal_);
  }
}

// Arbitration among the heads of all ports' queues; starts the winner.
bool VirtualBus::start_next(int64_t t) noexcept {
  int64_t earliest = INT64_MAX;
  for (std::size_t i = 0; i < port_count_; ++i) {
    const VirtualPort* p = ports_[i];
    if (p->staged_count_ == 0 || p->engine_state_ == BusState::BusOff) continue;
    earliest = std::min(earliest, p->earliest_staged_ns());
  }
  if (earliest == INT64_MAX) return false;
  const int64_t start = std::max(bus_free_ns_, earliest);
  if (start > t) return false;

  VirtualPort* winner = nullptr;
  uint64_t best = 0;
  unsigned contenders = 0;
  for (std::size_t i = 0; i < port_count_; ++i) {
    VirtualPort* p = ports_[i];
    if (p->staged_count_ == 0 || p->engine_state_ == BusState::BusOff) continue;
    if (!p->head_ready(start)) continue;
    const auto& head = p->staged_[p->staged_head_];
    ++contenders;
    const uint64_t key = arbitration_key(head.frame);
    if (!winner || key < best) {
      winner = p;
      best = key;
    }
  }
  if (contenders > 1) stats_.arbitration_losses += contenders - 1;

  const Frame& f = winner->staged_[winner->staged_head_].frame;
  in_flight_ = InFlight{};
  in_flight_.active = true;
  in_flight_.port = winner;
  in_flight_.start_ns = start;
  in_flight_.bits = frame_bits(f, options_.stuffing);
  for (auto& r : corrupt_rules_) {
    if (r.remaining > 0 && r.which.matches(f)) {
      --r.remaining;
      in_flight_.corrupted = true;
      in_flight_.bits += kErrorFrameBits;
      break;
    }
  }
  in_flight_.end_ns = start + bit_time_ns(in_flight_.bits);
  stats_.bits += in_flight_.bits;
  stats_.busy_ns += in_flight_.end_ns - start;
  winner->tx_bits_.fetch_add(in_flight_.bits, std::memory_order_relaxed);
  return true;
}

void VirtualBus::finish(int64_t t) noexcept {
  VirtualPort& sender = *in_flight_.port;
  const bool corrupted = in_flight_.corrupted;
  in_flight_.active = false;
  bus_free_ns_ = t;
  if (corrupted) {
    // The frame stays at the head of the sender's queue: retransmitted.
    ++stats_.error_frames;
    for (std::size_t i = 0; i < port_count_; ++i) {
      VirtualPort& p = *ports_[i];
      if (p.engine_state_ == BusState::BusOff) continue;
      const bool tx = &p == &sender;
      report(p, make_error_frame(kErrProtocol | kErrCounters, 0, static_cast<uint8_t>(kProtBit | (tx ? kProtTx : 0)),
                                 p.tec_.load(std::memory_order_relaxed) + (tx ? 8 : 0),
                                 p.rec_.load(std::memory_order_relaxed) + (tx ? 0 : 1)),
             t);
      count_error(p, tx, t);
    }
    return;
  }
  Frame f = sender.staged_[sender.staged_head_].frame;
  sender.staged_head_ = (sender.staged_head_ + 1) % sender.staged_.size();
  --sender.staged_count_;
  ++stats_.frames;
  sender.tx_frames_.fetch_add(1, std::memory_order_relaxed);
  if (const unsigned tec = sender.tec_.load(std::memory_order_relaxed); tec > 0) {
    sender.tec_.store(tec - 1, std::memory_order_relaxed);
    update_state(sender, t);
  }
  f.timestamp_ns = t;
  deliver(sender, f, t);
}

void VirtualBus::deliver(VirtualPort& from, const Frame& f, int64_t t) noexcept {
  const VirtualPort* drop_for = nullptr;
  bool drop_all = false;
  for (auto& r : drop_rules_) {
    if (r.remaining > 0 && r.which.matches(f)) {
      --r.remaining;
      ++stats_.dropped;
      if (r.receiver) drop_for = r.receiver;
      else drop_all = true;
      break;
    }
  }
  for (std::size_t i = 0; i < port_count_; ++i) {
    VirtualPort& p = *ports_[i];
    if ((&p == &from && !p.receive_own_) || p.engine_state_ == BusState::BusOff) continue;
    if (const unsigned rec = p.rec_.load(std::memory_order_relaxed); rec > 0) {
      p.rec_.store(rec > 127 ? 119 : rec - 1, std::memory_order_relaxed);  // ISO 11898-1: 119..127 after passive
      update_state(p, t);
    }
    if (drop_all || drop_for == &p || !p.accepts(f)) continue;
    if (p.rx_.push(f)) {
      p.rx_frames_.fetch_add(1, std::memory_order_relaxed);
      changed_ = true;
    } else {
      p.rx_overruns_.fetch_add(1, std::memory_order_relaxed);
      ++stats_.rx_overruns;
    }
  }
}

void VirtualBus::count_error(VirtualPort& p, bool transmitter, int64_t t) noexcept {
  if (transmitter) p.tec_.fetch_add(8, std::memory_order_relaxed);
  else p.rec_.store(std::min(255u, p.rec_.load(std::memory_order_relaxed) + 1), std::memory_order_relaxed);
  update_state(p, t);
}

void VirtualBus::update_state(VirtualPort& p, int64_t t) noexcept {
  if (p.engine_state_ == BusState::BusOff) return;  // only a restart ends bus-off
  const unsigned tec = p.tec_.load(std::memory_order_relaxed);
  const unsigned rec = p.rec_.load(std::memory_order_relaxed);
  const BusState next = bus_state_from_counters(tec, rec);
  if (next == p.engine_state_) return;
  const BusState before = p.engine_state_;
  p.engine_state_ = next;
  p.state_.store(next, std::memory_order_relaxed);
  switch (next) {
    case BusState::BusOff:
      // Nothing more leaves this controller: its queue is discarded.
      p.tx_rejected_.fetch_add(p.staged_count_, std::memory_order_relaxed);
      p.staged_count_ = 0;
      if (in_flight_.active && in_flight_.port == &p && !in_flight_.corrupted) in_flight_ = InFlight{};
      if (options_.auto_restart_ns >= 0) {
        p.restart_at_ns_ = t + options_.auto_restart_ns + bit_time_ns(kBusOffRecoveryBits);
      }
      report(p, make_error_frame(kErrBusOff | kErrCounters, 0, 0, tec, rec), t);
      break;
    case BusState::ErrorPassive:
      report(p, make_error_frame(kErrController | kErrCounters,
                                 static_cast<uint8_t>((tec >= 128 ? kCtrlTxPassive : 0) | (rec >= 128 ? kCtrlRxPassive : 0)),
                                 0, tec, rec),
             t);
      break;
    case BusState::ErrorWarning:
      report(p, make_error_frame(kErrController | kErrCounters,
                                 static_cast<uint8_t>((tec >= 96 ? kCtrlTxWarning : 0) | (rec >= 96 ? kCtrlRxWarning : 0)),
                                 0, tec, rec),
             t);
      break;
    case BusState::ErrorActive:
      if (before != BusState::ErrorActive) {
        report(p, make_error_frame(kErrController | kErrCounters, kCtrlActive, 0, tec, rec), t);
      }
      break;
  }
}

void VirtualBus::report(VirtualPort& p, const Frame& error, int64_t t) noexcept {
  if (!p.error_reports_) return;
  Frame f = error;
  f.timestamp_ns = t;
  if (p.rx_.push(f)) {
    p.error_frames_.fetch_add(1, std::memory_order_relaxed);
    changed_ = true;
  } else {
    p.rx_overruns_.fetch_add(1, std::memory_order_relaxed);
  }
}

void VirtualBus::drop_next(const Filter& which, unsigned count, const VirtualPort* receiver) {
  lock();
  for (auto& r : drop_rules_) {
    if (r.remaining == 0) {
      r = Rule{which, count, receiver};
      unlock();
      return;
    }
  }
  unlock();
  throw std::runtime_error("virtual CAN bus: too many drop rules pending");
}

void VirtualBus::corrupt_next(const Filter& which, unsigned count) {
  lock();
  for (auto& r : corrupt_rules_) {
    if (r.remaining == 0) {
      r = Rule{which, count, nullptr};
      unlock();
      return;
    }
  }
  unlock();
  throw std::runtime_error("virtual CAN bus: too many corruption rules pending");
}

void VirtualBus::inject_error_frames(unsigned count) {
  lock();
  const int64_t now = now_ns();
  run_until(now);
  // The noise occupies the bus from the next idle moment.
  const int64_t start = std::max(bus_free_ns_, in_flight_.active ? in_flight_.end_ns : now);
  const int64_t end = start + bit_time_ns(static_cast<uint64_t>(count) * kErrorFrameBits);
  bus_free_ns_ = end;
  stats_.bits += static_cast<uint64_t>(count) * kErrorFrameBits;
  stats_.busy_ns += end - start;
  stats_.error_frames += count;
  for (unsigned n = 0; n < count; ++n) {
    for (std::size_t i = 0; i < port_count_; ++i) {
      VirtualPort& p = *ports_[i];
      if (p.engine_state_ == BusState::BusOff) continue;
      report(p, make_error_frame(kErrProtocol | kErrCounters, 0, kProtForm, p.tec_.load(std::memory_order_relaxed),
                                 std::min(255u, p.rec_.load(std::memory_order_relaxed) + 1)),
             end);
      count_error(p, false, end);
    }
  }
  unlock();
}

void VirtualBus::force_bus_off(VirtualPort& port) {
  lock();
  port.tec_.store(256, std::memory_order_relaxed);
  update_state(port, now_ns());
  run_until(now_ns());
  unlock();
}

VirtualBusStats VirtualBus::stats() const {
  lock();
  VirtualBusStats s = stats_;
  unlock();
  return s;
}

void VirtualBus::reset_stats() {
  lock();
  stats_ = VirtualBusStats{};
  stats_start_ns_ = now_ns();
  unlock();
}

// ------------------------------------------------------- as a transport kind

VirtualBusOptions parse_virtual_options(std::string_view spec, const std::vector<std::string>& options) {
  VirtualBusOptions o;
  o.manual_clock = false;
  for (const std::string& opt : options) {
    const auto eq = opt.find('=');
    const std::string key(trim(std::string_view(opt).substr(0, eq)));
    const std::string_view value = eq == std::string::npos ? std::string_view{} : trim(std::string_view(opt).substr(eq + 1));
    if (key == "bitrate") {
      const auto n = parse_uint(value);
      if (!n || *n == 0 || *n > 1'000'000) throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": bitrate must be 1..1000000");
      o.bitrate = static_cast<uint32_t>(*n);
    } else if (key == "stuffing") {
      if (value == "worst") o.stuffing = Stuffing::WorstCase;
      else if (value == "exact") o.stuffing = Stuffing::Exact;
      else if (value == "nominal") o.stuffing = Stuffing::Nominal;
      else throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": stuffing must be worst, exact or nominal");
    } else if (key == "share") {
      o.share = true;
      o.share_path = std::string(value);
      if (eq != std::string::npos && value.empty()) {
        throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": share= needs a socket path (or plain share)");
      }
    } else {
      throw std::runtime_error("CAN interface \"" + std::string(spec) + "\": unknown option \"" + opt + "\"");
    }
  }
  return o;
}

void register_virtual_transport() {
  register_transport_kind("virtual", [](std::string_view spec, const std::string& name,
                                        const std::vector<std::string>& options) -> std::unique_ptr<Transport> {
    const VirtualBusOptions o = parse_virtual_options(spec, options);
    auto bus = VirtualBus::named(name, o);
    if (o.share) share_virtual_bus(bus, name, o.share_path.empty() ? default_share_path(name) : o.share_path);
    return bus->open_port("port");
  });
}

// --------------------------------------------------------------- VirtualPort

VirtualPort::VirtualPort(std::shared_ptr<VirtualBus> bus, std::string name)
    : bus_(std::move(bus)), name_("virtual:" + std::move(name)) {}

VirtualPort::~VirtualPort() { bus_->detach(this); }

bool VirtualPort::accepts(const Frame& f) const noexcept {
  if (filter_count_ == 0) return true;
  for (std::size_t i = 0; i < filter_count_; ++i) {
    if (filters_[i].matches(f)) return true;
  }
  return false;
}

SendStatus VirtualPort::send(const Frame& f) noexcept {
  if (f.is_error() || f.is_fd() || !is_valid_length(f)) {
    tx_rejected_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::Invalid;
  }
  if (state_.load(std::memory_order_relaxed) == BusState::BusOff) {
    tx_rejected_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::BusOff;
  }
  if (!tx_.push(Pending{f, bus_->now_ns()})) {
    tx_rejected_.fetch_add(1, std::memory_order_relaxed);
    return SendStatus::WouldBlock;
  }
  if (!bus_->options().manual_clock) bus_->service();
  return SendStatus::Ok;
}

bool VirtualPort::receive(Frame& out) noexcept {
  if (!bus_->options().manual_clock) bus_->service();
  return rx_.pop(out);
}

bool VirtualPort::wait(int64_t timeout_ns) noexcept {
  const int64_t deadline = monotonic_ns() + timeout_ns;
  VirtualBus& bus = *bus_;
  bus.waiters_.fetch_add(1, std::memory_order_acq_rel);
  bool ready = false;
  for (;;) {
    const uint32_t seen = bus.signal_.load(std::memory_order_acquire);
    // Real time: run the engine unless another port runs it right now.
    // Never spin for the lock here: a realtime waiter spinning on a core
    // where a normal-priority holder was preempted would keep it (and the
    // whole bus) from running for as long as the scheduler allows.
    bool ran = bus.options().manual_clock;
    if (!ran && bus.try_lock()) {
      bus.run_until(bus.now_ns());
      bus.unlock();
      ran = true;
    }
    if (rx_.size_approx() > 0) {
      ready = true;
      break;
    }
    const int64_t now = monotonic_ns();
    if (now >= deadline) break;
    int64_t until = deadline;
    if (!bus.options().manual_clock) until = std::min(until, bus.next_event_ns());
    // The holder of the engine signals when it delivers; meanwhile sleep
    // rather than poll, so that it gets the CPU (next_event_ns is stale
    // while it has not finished).
    futex_wait(&bus.signal_, seen, std::max<int64_t>(until - now, ran ? 1000 : 100'000));
  }
  bus.waiters_.fetch_sub(1, std::memory_order_acq_rel);
  return ready;
}

void VirtualPort::set_filters(std::span<const Filter> filters) {
  if (filters.size() > VirtualBus::kMaxFilters) {
    throw std::invalid_argument(name_ + ": at most " + std::to_string(VirtualBus::kMaxFilters) + " filters");
  }
  bus_->lock();
  filter_count_ = filters.size();
  for (std::size_t i = 0; i < filters.size(); ++i) filters_[i] = filters[i];
  bus_->unlock();
}

void VirtualPort::set_error_reports(bool on) {
  bus_->lock();
  error_reports_ = on;
  bus_->unlock();
}

void VirtualPort::set_tx_order(TxOrder order) {
  bus_->lock();
  tx_order_ = order;
  bus_->unlock();
}

int64_t VirtualPort::earliest_staged_ns() const noexcept {
  if (tx_order_ == TxOrder::Fifo || staged_count_ == 0) return staged_count_ ? staged_[staged_head_].enqueue_ns : INT64_MAX;
  int64_t e = INT64_MAX;
  for (std::size_t k = 0; k < staged_count_; ++k) e = std::min(e, staged_[(staged_head_ + k) % staged_.size()].enqueue_ns);
  return e;
}

bool VirtualPort::head_ready(int64_t start) noexcept {
  if (tx_order_ == TxOrder::Fifo) return staged_[staged_head_].enqueue_ns <= start;
  // Mailboxes: of the frames queued by `start`, the one that wins
  // arbitration goes first; it is rotated to the head (the others keep
  // their order), where the engine sends and pops it.
  std::size_t best = staged_.size();
  uint64_t best_key = 0;
  for (std::size_t k = 0; k < staged_count_; ++k) {
    const Pending& q = staged_[(staged_head_ + k) % staged_.size()];
    if (q.enqueue_ns > start) continue;
    const uint64_t key = arbitration_key(q.frame);
    if (best == staged_.size() || key < best_key) {
      best = k;
      best_key = key;
    }
  }
  if (best == staged_.size()) return false;
  const Pending chosen = staged_[(staged_head_ + best) % staged_.size()];
  for (std::size_t k = best; k > 0; --k) {
    staged_[(staged_head_ + k) % staged_.size()] = staged_[(staged_head_ + k - 1) % staged_.size()];
  }
  staged_[staged_head_] = chosen;
  return true;
}

void VirtualPort::set_receive_own(bool on) {
  bus_->lock();
  receive_own_ = on;
  bus_->unlock();
}

void VirtualPort::restart() {
  bus_->lock();
  if (engine_state_ == BusState::BusOff && restart_at_ns_ < 0) {
    restart_at_ns_ = bus_->now_ns() + bus_->bit_time_ns(kBusOffRecoveryBits);
    bus_->run_until(bus_->now_ns());
  }
  bus_->unlock();
}

TransportStats VirtualPort::stats() const noexcept {
  TransportStats s;
  s.tx_frames = tx_frames_.load(std::memory_order_relaxed);
  s.rx_frames = rx_frames_.load(std::memory_order_relaxed);
  s.tx_rejected = tx_rejected_.load(std::memory_order_relaxed);
  s.rx_overruns = rx_overruns_.load(std::memory_order_relaxed);
  s.error_frames = error_frames_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace cnc::can
