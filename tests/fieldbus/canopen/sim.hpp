// Test harness: a deterministic virtual CAN bus (manual clock) and the
// participants stepped on it in small time steps, plus a sniffer port that
// records every frame for protocol-byte checks.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "sim/can/virtual_bus.hpp"

namespace cnc::canopen::test {

struct Sim {
  explicit Sim(uint32_t bitrate = 1'000'000) {
    can::VirtualBusOptions o;
    o.bitrate = bitrate;
    bus = can::VirtualBus::create(o);
    sniffer = bus->open_port("sniffer");
  }
  std::unique_ptr<can::VirtualPort> port(const std::string& name) { return bus->open_port(name); }
  int64_t now() const { return bus->now_ns(); }

  void step() {
    bus->advance(step_ns);
    can::Frame f;
    while (sniffer->receive(f)) {
      if (!f.is_error()) log.push_back(f);
    }
    for (auto& a : actors) a(bus->now_ns());
  }
  void run_for(int64_t ns) {
    const int64_t end = now() + ns;
    while (now() < end) step();
  }
  // Steps until pred() holds or max_ns passed; returns pred().
  bool run_until(const std::function<bool()>& pred, int64_t max_ns = 2'000'000'000) {
    const int64_t end = now() + max_ns;
    for (;;) {
      if (pred()) return true;  // evaluated once per step: predicates may consume
      if (now() >= end) return false;
      step();
    }
  }
  std::vector<can::Frame> frames_with_id(uint32_t id) const {
    std::vector<can::Frame> out;
    for (const auto& f : log) {
      if (f.id == id) out.push_back(f);
    }
    return out;
  }

  std::shared_ptr<can::VirtualBus> bus;
  std::unique_ptr<can::VirtualPort> sniffer;
  std::vector<std::function<void(int64_t)>> actors;
  std::vector<can::Frame> log;
  int64_t step_ns = 20'000;
};

inline std::vector<uint8_t> bytes_of(const can::Frame& f) { return std::vector<uint8_t>(f.data.begin(), f.data.begin() + f.len); }

}  // namespace cnc::canopen::test
