#include "sim/ethercat/segment.hpp"

#include <time.h>

#include <array>
#include <cstring>
#include <map>
#include <stdexcept>

namespace cnc::ethercat::sim {
namespace {

int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

bool is_logical(Command c) { return c == Command::LRD || c == Command::LWR || c == Command::LRW; }

std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, std::shared_ptr<Segment>>& registry() {
  static std::map<std::string, std::shared_ptr<Segment>> r;
  return r;
}

}  // namespace

Segment::Segment(std::function<int64_t()> clock) : clock_(clock ? std::move(clock) : std::function<int64_t()>(monotonic_ns)) {}

Esc& Segment::add(EscConfig config, SlaveApplication* app) {
  std::lock_guard lock(mutex_);
  slaves_.push_back(std::make_unique<Esc>(std::move(config), app, clock_()));
  return *slaves_.back();
}

void Segment::add_drives(unsigned n, const CoeDriveConfig& base) {
  for (unsigned i = 0; i < n; ++i) {
    CoeDriveConfig c = base;
    c.name = "drive-" + std::to_string(size() + 1);
    c.serial = static_cast<uint32_t>(size() + 1);
    // Every clock runs at its own rate and starts at its own value.
    static constexpr double kDrift[] = {25.0, -18.0, 7.5, -31.0, 12.0, -4.0, 40.0, -22.0, 3.0};
    c.drift_ppm = kDrift[(size()) % 9];
    c.clock_at_power_on_ns = static_cast<int64_t>(size() + 1) * 123'456'789;
    drives_.push_back(std::make_unique<CoeDrive>(c, clock_()));
    add(drives_.back()->esc_config(), drives_.back().get());
  }
}

void Segment::poll() {
  std::lock_guard lock(mutex_);
  const int64_t t = clock_();
  for (auto& s : slaves_) s->poll(t);
}

bool Segment::poll_if_idle() {
  const uint64_t passed = frames_.load() - dropped_.load();
  const bool frames_passed = passed != passed_at_idle_poll_ && break_after_.load() == 0;
  passed_at_idle_poll_ = passed;
  if (frames_passed) return false;
  poll();
  return true;
}

void Segment::execute(DatagramRef& d, std::size_t connected, int64_t t) noexcept {
  const Command c = d.command();
  constexpr int64_t kHop = 750;
  for (std::size_t i = 0; i < connected; ++i) {
    Esc& s = *slaves_[i];
    const int64_t t_fwd = t + static_cast<int64_t>(i) * kHop;
    const int64_t t_ret = t + static_cast<int64_t>(2 * (connected - 1) - i) * kHop;
    const bool port1 = i + 1 < connected;
    uint16_t inc = 0;
    switch (c) {
      case Command::APRD: case Command::APWR: case Command::APRW:
        if (d.adp() == 0) inc = s.execute(d, false, t_fwd, t_ret, port1);
        d.set_adp(static_cast<uint16_t>(d.adp() + 1));
        break;
      case Command::FPRD: case Command::FPWR: case Command::FPRW:
        if (d.adp() == s.station_address() || (s.alias_enabled() && d.adp() == s.alias())) {
          inc = s.execute(d, false, t_fwd, t_ret, port1);
        }
        break;
      case Command::BRD: case Command::BWR: case Command::BRW:
        inc = s.execute(d, false, t_fwd, t_ret, port1);
        d.set_adp(static_cast<uint16_t>(d.adp() + 1));
        break;
      case Command::ARMW:
        inc = s.execute(d, d.adp() == 0, t_fwd, t_ret, port1);
        d.set_adp(static_cast<uint16_t>(d.adp() + 1));
        break;
      case Command::FRMW:
        inc = s.execute(d, d.adp() == s.station_address(), t_fwd, t_ret, port1);
        break;
      case Command::LRD: case Command::LWR: case Command::LRW:
        inc = s.execute_logical(d, t_fwd);
        break;
      default: break;
    }
    if (inc) d.add_wkc(inc);
  }
}

bool Segment::process(uint8_t* frame, std::size_t size) {
  FrameView v;
  if (parse_frame(frame, size, v) != ParseResult::Ok) return false;
  std::lock_guard lock(mutex_);
  frames_.fetch_add(1, std::memory_order_relaxed);
  unsigned drop = drop_.load();
  while (drop > 0 && !drop_.compare_exchange_weak(drop, drop - 1)) {
  }
  if (drop > 0) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const unsigned brk = break_after_.load();
  const std::size_t connected = brk == 0 ? slaves_.size() : std::min<std::size_t>(brk, slaves_.size());
  const int64_t t = clock_();
  bool corrupted = false;
  for (std::size_t k = 0; k < v.count; ++k) {
    DatagramRef& d = v.datagrams[k];
    execute(d, connected, t);
    d.set_adp(d.adp());
    if (is_logical(d.command()) && !corrupted) {
      unsigned n = corrupt_.load();
      if (n > 0 && corrupt_.compare_exchange_strong(n, n - 1)) {
        d.set_wkc(static_cast<uint16_t>(d.wkc() + wkc_delta_));
        corrupted = true;
      }
    }
    // Circulating frames are not modelled: every datagram returns.
  }
  frame[6] |= 0x02;  // the first ESC marks the source MAC as locally administered
  return true;
}

void register_sim_link_kind() {
  register_link_kind("sim", [](const std::string& name) -> std::unique_ptr<Link> {
    auto seg = find_segment(name);
    if (!seg) {
      throw std::runtime_error("no simulated EtherCAT segment \"" + name + "\" (loadrt ethercat_sim name=" + name +
                               " before loadrt ethercat)");
    }
    return open_sim_link(seg, name);
  });
}

void register_segment(const std::string& name, std::shared_ptr<Segment> segment) {
  register_sim_link_kind();
  std::lock_guard lock(registry_mutex());
  if (!registry().emplace(name, std::move(segment)).second) {
    throw std::runtime_error("simulated EtherCAT segment \"" + name + "\" exists already");
  }
}
void unregister_segment(const std::string& name) {
  std::lock_guard lock(registry_mutex());
  registry().erase(name);
}
std::shared_ptr<Segment> find_segment(const std::string& name) {
  std::lock_guard lock(registry_mutex());
  auto it = registry().find(name);
  return it == registry().end() ? nullptr : it->second;
}

namespace {

class SimLink final : public Link {
 public:
  SimLink(std::shared_ptr<Segment> s, std::string name) : seg_(std::move(s)), name_("sim:" + std::move(name)) {
    mac_[0] = 0x02;
    mac_[5] = static_cast<uint8_t>(reinterpret_cast<uintptr_t>(this) >> 4);
  }
  const std::string& name() const noexcept override { return name_; }
  const Mac& mac() const noexcept override { return mac_; }
  bool send(const uint8_t* frame, std::size_t size) noexcept override {
    if (size > kMaxFrame) return false;
    Slot& s = ring_[head_ % ring_.size()];
    std::memcpy(s.data.data(), frame, size);
    s.size = size;
    if (!seg_->process(s.data.data(), size)) return true;  // sent, but lost on the wire
    if (head_ - tail_ == ring_.size()) ++tail_;              // overwrite the oldest unread reply
    ++head_;
    return true;
  }
  std::size_t receive(uint8_t* buffer, int64_t) noexcept override {
    if (tail_ == head_) return 0;
    const Slot& s = ring_[tail_++ % ring_.size()];
    std::memcpy(buffer, s.data.data(), s.size);
    return s.size;
  }

 private:
  struct Slot {
    std::array<uint8_t, kMaxFrame> data;
    std::size_t size = 0;
  };
  std::shared_ptr<Segment> seg_;
  std::string name_;
  Mac mac_{};
  std::array<Slot, 8> ring_{};
  uint64_t head_ = 0, tail_ = 0;
};

}  // namespace

std::unique_ptr<Link> open_sim_link(std::shared_ptr<Segment> segment, const std::string& name) {
  return std::make_unique<SimLink>(std::move(segment), name);
}

}  // namespace cnc::ethercat::sim
