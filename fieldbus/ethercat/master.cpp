#include "fieldbus/ethercat/master.hpp"

#include <time.h>

#include <algorithm>
#include <cstdarg>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <future>

#include "core/util/messages.hpp"
#include "cia402/error_codes.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#ifdef CNC_ETHERCAT_ESI
#include "fieldbus/ethercat/esi.hpp"
#endif

#include "fieldbus/ethercat/master_internal.hpp"

namespace cnc::ethercat {

using namespace master_detail;


Master::Master(MasterConfig config, MessageQueue* messages) : cfg_(std::move(config)), messages_(messages) {}

Master::Master(MasterConfig config, MessageQueue* messages, std::unique_ptr<Link> cyclic, std::unique_ptr<Link> acyclic)
    : cfg_(std::move(config)), messages_(messages), cyclic_link_(std::move(cyclic)), acyclic_link_(std::move(acyclic)) {}

Master::~Master() { stop(); }

void Master::stop() {
  stop_.store(true);
  jobs_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  // Requests queued while the worker stopped still get their answer.
  run_queued_jobs();
}

void Master::release() {
  stop();
  if (!acyclic_link_ || phase() == BusPhase::Down) return;
  phase_.store(BusPhase::Down, std::memory_order_release);
  uint8_t init[2] = {0x01, 0};
  (void)transact(Command::BWR, physical_address(0, reg::kAlControl), init, 2);
}

void Master::drain(Link& link) noexcept {
  uint8_t buf[kMaxFrame];
  for (int i = 0; i < 100000 && link.receive(buf, 0) > 0; ++i) {
  }
}

void Master::fail(const std::string& what) const { throw StartupError(cfg_.name + ": start-up stopped: " + what); }
void Master::fail_slave(const SlaveInfo& s, const std::string& what) const { fail(slave_label(s.position) + ": " + what); }

std::string Master::slave_label(unsigned position) const {
  std::string name;
  if (const SlaveConfig* c = cfg_.slave(position); c && !c->name.empty()) name = c->name;
  else if (position >= 1 && position <= slaves_.size()) name = slaves_[position - 1].name;
  return name.empty() ? fmt("slave %u", position) : fmt("slave %u (%s)", position, name.c_str());
}

void Master::post(bool error, const std::string& text) {
  if (messages_) messages_->post(error ? MessageKind::Error : MessageKind::Text, cfg_.name, text);
  else std::fprintf(stderr, "%s: %s\n", cfg_.name.c_str(), text.c_str());
}

// ---------------------------------------------------------------- datagrams

std::optional<uint16_t> Master::transact(Command c, uint32_t address, uint8_t* data, uint16_t length) {
  uint8_t frame[kMaxFrame];
  uint8_t reply[kMaxFrame];
  for (int attempt = 0; attempt < 3; ++attempt) {
    const uint8_t idx = acyclic_index_;
    acyclic_index_ = static_cast<uint8_t>(acyclic_index_ == 0xFF ? 0x80 : acyclic_index_ + 1);
    FrameBuilder fb;
    fb.begin(frame, acyclic_link_->mac());
    if (!fb.add(c, idx, address, length, data)) return std::nullopt;
    const std::size_t n = fb.finish();
    if (!acyclic_link_->send(frame, n)) {
      sleep_ns(1'000'000);
      continue;
    }
    const int64_t deadline = monotonic_ns() + 50'000'000;
    for (;;) {
      const int64_t left = deadline - monotonic_ns();
      if (left <= 0) break;
      const std::size_t m = acyclic_link_->receive(reply, left);
      if (m == 0) {
        if (acyclic_link_->name().rfind("sim:", 0) == 0) break;  // in-process: no reply means lost
        continue;
      }
      FrameView v;
      if (parse_frame(reply, m, v) != ParseResult::Ok) continue;
      const DatagramRef& d = v.datagrams[0];
      if (d.index() != idx || d.command() != c || d.length() != length) continue;
      std::memcpy(data, d.data(), length);
      return d.wkc();
    }
  }
  return std::nullopt;
}

uint16_t Master::fprd(const SlaveInfo& s, uint16_t ado, uint8_t* data, uint16_t len) {
  return transact(Command::FPRD, physical_address(s.station, ado), data, len).value_or(0);
}
uint16_t Master::fpwr(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len) {
  uint8_t tmp[kMaxDatagramData];
  std::memcpy(tmp, data, len);
  return transact(Command::FPWR, physical_address(s.station, ado), tmp, len).value_or(0);
}
void Master::must_write(const SlaveInfo& s, uint16_t ado, const uint8_t* data, uint16_t len, const char* what) {
  if (fpwr(s, ado, data, len) != 1) fail_slave(s, fmt("writing %s (register 0x%04X) got no answer", what, ado));
}

SlaveInfo* Master::find(unsigned position) {
  return position >= 1 && position <= slaves_.size() ? &slaves_[position - 1] : nullptr;
}

// ---------------------------------------------------------------- status

std::string Master::fault_text() const {
  std::lock_guard lock(fault_mutex_);
  return fault_text_;
}

uint8_t Master::slave_al_state(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].al_state.load() : 0;
}
uint16_t Master::slave_al_code(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].al_code.load() : 0;
}
uint16_t Master::slave_emcy_code(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].emcy_code.load() : 0;
}
uint16_t Master::slave_port_rx_errors(unsigned position, unsigned port) const noexcept {
  return position >= 1 && position <= slaves_.size() && port < 4 ? state_[position - 1].port_rx_errors[port].load() : 0;
}
uint8_t Master::slave_port_lost_links(unsigned position, unsigned port) const noexcept {
  return position >= 1 && position <= slaves_.size() && port < 4 ? state_[position - 1].port_lost_links[port].load() : 0;
}
uint32_t Master::slave_emcy_count(unsigned position) const noexcept {
  return position >= 1 && position <= slaves_.size() ? state_[position - 1].emcy_count.load() : 0;
}

}  // namespace cnc::ethercat
