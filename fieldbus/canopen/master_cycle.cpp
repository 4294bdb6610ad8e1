// The CANopen master, cyclic side (servo thread): TPDOs in, SYNC and
// RPDOs out, the master's heartbeat, process-image slots.
#include "fieldbus/canopen/master_internal.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {

using namespace master_detail;

// ------------------------------------------------------------ cyclic side

bool Master::is_cyclic_running() const noexcept {
  return cyclic_enabled_.load(std::memory_order_acquire) && !sync_stalled_.load(std::memory_order_acquire);
}

void Master::cyclic_read(int64_t now_ns) noexcept {
  (void)now_ns;
  const uint64_t serial = cyclic_.sync_serial;
  can::Frame f;
  while (cyclic_port_->receive(f)) {
    if (f.is_error()) {
      if (bus_tracker_.on_error_frame(f)) {
        cyclic_.bus_state = bus_tracker_.state();
        bus_state_.store(static_cast<int>(bus_tracker_.state()), std::memory_order_relaxed);
        if (messages_) {
          char text[128];
          can::describe_error(can::decode_error_frame(f), text, sizeof text);
          messages_->postf(bus_tracker_.state() == can::BusState::ErrorActive ? MessageKind::Text : MessageKind::Error,
                           config_.name, "CAN controller %s (%s)", can::to_string(bus_tracker_.state()), text);
        }
      }
      continue;
    }
    if (f.is_extended() || f.is_remote()) continue;
    const int16_t i = tpdo_by_cob_[f.id & 0x7FF];
    if (i < 0) continue;
    TpdoRt& t = tpdos_[static_cast<std::size_t>(i)];
    if (f.len < t.bytes) {
      ++cyclic_.pdo_length_errors;
      continue;
    }
    std::memcpy(t.image.data(), f.data.data(), t.bytes);
    t.received_serial = serial;
    t.rx_sequence = ++rx_sequence_;
    t.ever = true;
  }
  cyclic_.rx_overruns = static_cast<uint32_t>(cyclic_port_->stats().rx_overruns);
  if (!cyclic_enabled_.load(std::memory_order_acquire) || serial == 0) {
    cyclic_.inputs_fresh = false;
    cyclic_.reads_without_sync = 0;
    sync_stalled_.store(false, std::memory_order_release);
    last_read_serial_ = serial;
    last_read_cycle_ = cycle_;
    return;
  }
  // No SYNC since the previous read: write() did not run (its function
  // removed, canopen.N.enable FALSE) or the SYNC was refused. The inputs
  // are then stale and the nodes get no set-points; a few such cycles in a
  // row make the cycle "not running" for the drives' link health.
  const bool no_sync = serial == last_read_serial_;
  const bool write_ran = cycle_ != last_read_cycle_;  // else the SYNC was refused (bus-off, down: reported as such)
  last_read_serial_ = serial;
  last_read_cycle_ = cycle_;
  if (no_sync) {
    if (++cyclic_.reads_without_sync == kSyncStallReads) {
      sync_stalled_.store(true, std::memory_order_release);
      if (messages_ && !write_ran) {
        sync_stall_reported_ = true;
        messages_->postf(MessageKind::Error, config_.name,
                         "no SYNC sent for %u cycles (%s.write not running or %s.enable FALSE): "
                         "the nodes get no set-points",
                         kSyncStallReads, config_.name.c_str(), config_.name.c_str());
      }
    }
  } else {
    if (sync_stall_reported_ && messages_) {
      messages_->postf(MessageKind::Text, config_.name, "SYNC sent again after %u cycles without", cyclic_.reads_without_sync);
    }
    sync_stall_reported_ = false;
    cyclic_.reads_without_sync = 0;
    sync_stalled_.store(false, std::memory_order_release);
  }
  // Every synchronous TPDO should have answered the last SYNC (type n: one
  // in n SYNCs).
  bool fresh = true;
  uint64_t oldest = serial;
  for (auto& n : nodes_) n->inputs_serial = serial;
  for (TpdoRt& t : tpdos_) {
    NodeRt& n = *nodes_[t.node];
    if (!n.in_cycle.load(std::memory_order_relaxed)) {
      // Out of the cycle (booting, rebooting): start afresh when it returns.
      t.ever = false;
      t.consecutive_missed = 0;
      n.pdo_fault_reported = false;
      continue;
    }
    if (t.type == 0 || t.type > kTransmissionSyncMax) continue;
    const bool missing = t.ever ? serial - t.received_serial >= t.type : serial > static_cast<uint64_t>(t.type) + 1;
    if (missing && no_sync) {
      // No SYNC since the last read (refused, or write() not running): the
      // TPDO is still the one missing for the last SYNC, not a new miss.
      fresh = false;
    } else if (missing) {
      fresh = false;
      ++t.consecutive_missed;
      ++cyclic_.pdo_missed;
      n.pdo_missed.fetch_add(1, std::memory_order_relaxed);
      if (config_.pdo_miss_limit && t.consecutive_missed == config_.pdo_miss_limit && !n.pdo_fault_reported) {
        n.pdo_fault_reported = true;
        n.fault.store(true, std::memory_order_relaxed);
        if (messages_) {
          messages_->postf(n.cfg.mandatory ? MessageKind::Error : MessageKind::Text, n.source.c_str(),
                           "node %u: TPDO%u missed %u SYNCs in a row (COB-ID 0x%03X)", n.cfg.id, t.number,
                           t.consecutive_missed, t.cob);
        }
      }
    } else {
      t.consecutive_missed = 0;
    }
    const uint64_t sampled = t.ever ? t.received_serial : 0;
    oldest = std::min(oldest, sampled);
    n.inputs_serial = std::min(n.inputs_serial, sampled);
  }
  cyclic_.inputs_fresh = fresh && !no_sync;
  cyclic_.inputs_sync_serial = oldest;
}

void Master::cyclic_write(int64_t now_ns) noexcept {
  if (cyclic_enabled_.load(std::memory_order_acquire)) write_process_data();
  // While a (re)boot keeps the process data off, the heartbeat still goes:
  // the cycle is alive.
  produce_heartbeat(now_ns);
}

void Master::write_process_data() noexcept {
  ++cycle_;
  for (const RpdoRt& r : rpdos_) {
    if (!nodes_[r.node]->in_cycle.load(std::memory_order_relaxed)) continue;
    cyclic_send(can::Frame::make(r.cob, r.image.data(), r.bytes));
  }
  can::Frame sync;
  sync.id = config_.sync_cob_id & 0x7FF;
  if (config_.sync_overflow > 0) {
    cyclic_.sync_counter = static_cast<uint8_t>(cyclic_.sync_counter % config_.sync_overflow + 1);
    sync.len = 1;
    sync.data[0] = cyclic_.sync_counter;
  }
  if (!cyclic_send(sync)) return;  // no SYNC on the bus: no TPDO is due
  ++cyclic_.sync_serial;
  sync_serial_.store(cyclic_.sync_serial, std::memory_order_relaxed);
}

// The master's heartbeat from the servo thread: one 1-byte frame per
// period (a non-blocking send, no allocation), after the SYNC so that it
// never delays it. The first call takes the producer over from the acyclic
// thread and sends at once, so the devices see no gap at the hand-over.
void Master::produce_heartbeat(int64_t now_ns) noexcept {
  if (config_.master_heartbeat_ms == 0) return;
  const int64_t period = int64_t{config_.master_heartbeat_ms} * 1'000'000;
  if (!heartbeat_in_cycle_.load(std::memory_order_relaxed)) {
    heartbeat_in_cycle_.store(true, std::memory_order_release);
    next_cyclic_heartbeat_ns_ = now_ns;
  }
  if (now_ns < next_cyclic_heartbeat_ns_) return;
  const uint8_t state = boot_state() == BootState::Succeeded ? 0x05 : 0x7F;
  cyclic_send(can::Frame::make(cob::heartbeat(config_.master_node_id), {state}));
  // Keep the phase; after a stall start afresh instead of sending a burst.
  next_cyclic_heartbeat_ns_ += period;
  if (next_cyclic_heartbeat_ns_ <= now_ns) next_cyclic_heartbeat_ns_ = now_ns + period;
}

// Sends one frame of the cycle; counts a refusal and reports the interface
// going down (and coming back) once, in the servo thread (the message
// queue neither allocates nor blocks).
bool Master::cyclic_send(const can::Frame& f) noexcept {
  const can::SendStatus st = cyclic_port_->send(f);
  const bool down = st == can::SendStatus::Down;
  if (down != cyclic_.interface_down) {
    cyclic_.interface_down = down;
    interface_down_.store(down, std::memory_order_relaxed);
    if (messages_) {
      if (down) {
        messages_->postf(MessageKind::Error, config_.name, "CAN interface %s is down: no SYNC, PDO or heartbeat can be sent",
                         cyclic_port_->name().c_str());
      } else {
        messages_->postf(MessageKind::Text, config_.name, "CAN interface %s is up again", cyclic_port_->name().c_str());
      }
    }
  }
  if (st == can::SendStatus::Ok) {
    consecutive_send_errors_.store(0, std::memory_order_relaxed);
    return true;
  }
  consecutive_send_errors_.store(consecutive_send_errors_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  ++cyclic_.send_errors;
  send_errors_.store(cyclic_.send_errors, std::memory_order_relaxed);
  last_send_error_.store(static_cast<uint8_t>(st), std::memory_order_relaxed);
  return false;
}

ProcessSlot Master::output(uint8_t node, uint16_t index, uint8_t sub) const noexcept {
  for (const auto& n : nodes_) {
    if (n->cfg.id != node) continue;
    for (std::size_t k = 0; k < n->cfg.rpdos.size(); ++k) {
      const PdoConfig& p = n->cfg.rpdos[k];
      unsigned bit = 0;
      for (const auto& e : p.map) {
        if (e.index == index && e.sub == sub && !e.is_dummy()) {
          for (const RpdoRt& r : rpdos_) {
            if (nodes_[r.node].get() == n.get() && r.number == p.number) {
              return ProcessSlot{const_cast<uint8_t*>(r.image.data()), static_cast<uint16_t>(bit), e.bits};
            }
          }
        }
        bit += e.bits;
      }
    }
  }
  return {};
}

uint64_t Master::input_sequence(const ProcessSlot& s) const noexcept {
  for (const TpdoRt& t : tpdos_) {
    if (s.bytes == t.image.data()) return t.rx_sequence;
  }
  return 0;
}

ProcessSlot Master::input(uint8_t node, uint16_t index, uint8_t sub) const noexcept {
  for (const auto& n : nodes_) {
    if (n->cfg.id != node) continue;
    for (std::size_t k = 0; k < n->cfg.tpdos.size(); ++k) {
      const PdoConfig& p = n->cfg.tpdos[k];
      unsigned bit = 0;
      for (const auto& e : p.map) {
        if (e.index == index && e.sub == sub && !e.is_dummy()) {
          for (const TpdoRt& t : tpdos_) {
            if (nodes_[t.node].get() == n.get() && t.number == p.number) {
              return ProcessSlot{const_cast<uint8_t*>(t.image.data()), static_cast<uint16_t>(bit), e.bits};
            }
          }
        }
        bit += e.bits;
      }
    }
  }
  return {};
}

void Master::request_reboot(uint8_t node) noexcept {
  for (const auto& n : nodes_) {
    if (n->cfg.id == node) n->reboot_request.store(true, std::memory_order_release);
  }
}

uint64_t Master::inputs_sync_serial(uint8_t node) const noexcept {
  const NodeRt* n = find(node);
  return n ? n->inputs_serial : 0;
}

}  // namespace cnc::canopen
