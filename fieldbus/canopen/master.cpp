#include "fieldbus/canopen/master.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"
#include "fieldbus/canopen/master_internal.hpp"


namespace cnc::canopen {

const char* to_string(BootState s) noexcept {
  switch (s) {
    case BootState::Idle: return "idle";
    case BootState::Running: return "running";
    case BootState::Succeeded: return "succeeded";
    case BootState::Failed: return "failed";
  }
  return "?";
}

using namespace master_detail;


// ------------------------------------------------------------ construction

namespace {
// An in-process bus runs at the configured bit rate unless the interface
// names one itself ("virtual:sim,bitrate=500000").
// The bus's bitrate goes with the interface: a virtual bus is made at it,
// a SocketCAN interface at another bitrate is refused (can::open_transport).
std::string transport_spec(const BusConfig& c) {
  if ((c.interface.rfind("virtual:", 0) == 0 || c.interface.rfind("socketcan:", 0) == 0) &&
      c.interface.find("bitrate=") == std::string::npos) {
    return c.interface + ",bitrate=" + std::to_string(c.bitrate);
  }
  return c.interface;
}
}  // namespace

Master::Master(BusConfig config, MessageQueue* messages)
    : Master(config, can::open_transport(transport_spec(config)), can::open_transport(transport_spec(config)), messages) {}

Master::Master(BusConfig config, std::unique_ptr<can::Transport> cyclic, std::unique_ptr<can::Transport> acyclic,
               MessageQueue* messages)
    : config_(std::move(config)), messages_(messages), cyclic_port_(std::move(cyclic)), acyclic_port_(std::move(acyclic)) {
  config_.validate();
  init();
}

Master::~Master() {
  stop_thread();
  // Devices leave the cycle cleanly: pre-operational stops PDOs.
  for (const auto& n : nodes_) {
    if (n->booted.load()) send_nmt(NmtCommand::EnterPreOperational, n->cfg.id);
  }
}

void Master::init() {
  tpdo_by_cob_.fill(-1);
  std::vector<can::Filter> cyclic_filters;
  for (const NodeConfig& c : config_.nodes) {
    auto n = std::make_unique<NodeRt>();
    n->cfg = c;
    SdoClientOptions o;
    o.timeout_ns = config_.sdo_timeout_ns;
    o.pacer = &sdo_pacer_;
    n->sdo = std::make_unique<SdoClient>(*acyclic_port_, c.id, o);
    char src[48];
    std::snprintf(src, sizeof src, "%s.node.%02u", config_.name.c_str(), c.id);
    n->source = src;
    build_steps(*n);
    const std::size_t index = nodes_.size();
    for (const auto& p : c.tpdos) {
      TpdoRt t;
      t.node = index;
      t.number = p.number;
      t.cob = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(true, p.number, c.id);
      t.bytes = static_cast<uint8_t>(p.bytes());
      t.type = p.transmission;
      tpdo_by_cob_[t.cob] = static_cast<int16_t>(tpdos_.size());
      tpdos_.push_back(t);
      cyclic_filters.push_back(can::Filter::exact(t.cob));
    }
    for (const auto& p : c.rpdos) {
      RpdoRt r;
      r.node = index;
      r.number = p.number;
      r.cob = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(false, p.number, c.id);
      r.bytes = static_cast<uint8_t>(p.bytes());
      rpdos_.push_back(r);
    }
    nodes_.push_back(std::move(n));
  }
  if (cyclic_filters.size() > 32) {
    cyclic_filters = {can::Filter::range_mask(0x180, 0x780), can::Filter::range_mask(0x280, 0x780),
                      can::Filter::range_mask(0x380, 0x780), can::Filter::range_mask(0x480, 0x780)};
  }
  if (cyclic_filters.empty()) cyclic_filters.push_back(can::Filter::exact(0x7FF));  // nothing to receive
  cyclic_port_->set_filters(cyclic_filters);
  cyclic_port_->set_error_reports(true);
  // EMCY 0x081-0x0FF without the SYNC (0x080): the acyclic thread runs at
  // normal priority; while load delays it, its receive queue must hold
  // seconds of heartbeats, not fill up with a thousand SYNCs per second
  // (an overrun there would lose heartbeats and fault healthy nodes).
  const can::Filter acyclic_filters[] = {
      can::Filter::range_mask(0x081, 0x7FF), can::Filter::range_mask(0x082, 0x7FE),
      can::Filter::range_mask(0x084, 0x7FC), can::Filter::range_mask(0x088, 0x7F8),
      can::Filter::range_mask(0x090, 0x7F0), can::Filter::range_mask(0x0A0, 0x7E0),
      can::Filter::range_mask(0x0C0, 0x7C0),  // EMCY
      can::Filter::range_mask(0x580, 0x780),  // SDO responses
      can::Filter::range_mask(0x700, 0x780),  // heartbeat, boot-up
  };
  acyclic_port_->set_filters(acyclic_filters);
  acyclic_port_->set_error_reports(false);
}

void Master::build_steps(NodeRt& n) {
  const NodeConfig& c = n.cfg;
  auto expect = [&](ObjectAddress a, std::optional<uint32_t> v, const std::string& what) {
    Step s;
    s.kind = Step::Kind::Expect;
    s.addr = a;
    if (v) s.data = u32_bytes(*v);
    s.what = what;
    n.steps.push_back(std::move(s));
  };
  auto write = [&](ObjectAddress a, std::vector<uint8_t> data, const std::string& what, bool verify,
                   uint32_t mask = 0xFFFFFFFF, bool may_be_missing = false) {
    Step s;
    s.kind = Step::Kind::Write;
    s.addr = a;
    s.data = data;
    s.may_be_missing = may_be_missing;
    s.what = what;
    n.steps.push_back(s);
    if (verify) {
      s.kind = Step::Kind::Verify;
      s.mask = mask;
      n.steps.push_back(std::move(s));
    }
  };
  // CiA 302-2: device type and identity first.
  expect({0x1000, 0}, c.device_type, "device type");
  if (c.vendor_id) expect({0x1018, 1}, c.vendor_id, "vendor-ID");
  if (c.product_code) expect({0x1018, 2}, c.product_code, "product code");
  if (c.revision) expect({0x1018, 3}, c.revision, "revision number");
  if (c.serial) expect({0x1018, 4}, c.serial, "serial number");
  // Configuration download; each value is read back after it is written
  // (the Verify steps are gathered after all writes below).
  const std::size_t first_write = n.steps.size();
  write({0x1017, 0}, u32_bytes(c.heartbeat_ms, 2), "heartbeat producer time", true);
  if (c.master_heartbeat_timeout_ms > 0) {
    write({0x1016, 1}, u32_bytes((static_cast<uint32_t>(config_.master_node_id) << 16) | c.master_heartbeat_timeout_ms),
          "heartbeat consumer of the master", true);
  }
  if (config_.sync_cob_id != cob::kSync) write({0x1005, 0}, u32_bytes(config_.sync_cob_id), "SYNC COB-ID", true);
  for (bool tpdo : {false, true}) {
    const auto& list = tpdo ? c.tpdos : c.rpdos;
    const char* kind = tpdo ? "TPDO" : "RPDO";
    if (c.disable_unused_pdos) {
      for (unsigned number = 1; number <= 4; ++number) {
        if (std::any_of(list.begin(), list.end(), [&](const PdoConfig& p) { return p.number == number; })) continue;
        const uint16_t comm = tpdo ? tpdo_comm_index(number) : rpdo_comm_index(number);
        // Read back like every other write: the invalid bit must stick (a
        // device may keep a PDO it cannot switch off and still answer OK).
        write({comm, 1}, u32_bytes(default_pdo_cob(tpdo, number, c.id) | cob::kPdoInvalid),
              std::string(kind) + std::to_string(number) + " off (not configured)", true, cob::kPdoInvalid, true);
      }
    }
    for (const auto& p : list) {
      const std::string name = std::string(kind) + std::to_string(p.number);
      const uint16_t comm = tpdo ? tpdo_comm_index(p.number) : rpdo_comm_index(p.number);
      const uint16_t map = tpdo ? tpdo_map_index(p.number) : rpdo_map_index(p.number);
      const uint32_t cob = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(tpdo, p.number, c.id);
      // CiA 301 remap: invalidate, clear the count, entries, count, valid.
      write({comm, 1}, u32_bytes(cob | cob::kPdoInvalid), name + " COB-ID (disabled for remapping)", false);
      write({map, 0}, {0}, name + " mapping count (cleared)", false);
      for (std::size_t i = 0; i < p.map.size(); ++i) {
        write({map, static_cast<uint8_t>(i + 1)}, u32_bytes(p.map[i].encode()),
              name + " mapping entry " + std::to_string(i + 1), true);
      }
      write({map, 0}, {static_cast<uint8_t>(p.map.size())}, name + " mapping count", true);
      write({comm, 2}, {p.transmission}, name + " transmission type", true);
      if (tpdo && p.inhibit_100us) write({comm, 3}, u32_bytes(p.inhibit_100us, 2), name + " inhibit time", true);
      if (p.event_ms) write({comm, 5}, u32_bytes(p.event_ms, 2), name + " event timer", true);
      if (tpdo && p.sync_start) write({comm, 6}, {p.sync_start}, name + " SYNC start value", true);
      write({comm, 1}, u32_bytes(cob), name + " COB-ID", true, ~cob::kPdoNoRtr);
    }
  }
  for (const auto& w : c.sdo) write(w.addr, w.data, "value from " + w.origin, w.verify);
  // Writes first, then every read-back (so that a later write cannot
  // silently undo an earlier one).
  std::vector<Step> verifies;
  std::vector<Step> rest;
  for (std::size_t i = first_write; i < n.steps.size(); ++i) {
    (n.steps[i].kind == Step::Kind::Verify ? verifies : rest).push_back(std::move(n.steps[i]));
  }
  n.steps.resize(first_write);
  for (auto& s : rest) n.steps.push_back(std::move(s));
  for (auto& s : verifies) n.steps.push_back(std::move(s));
}

// ------------------------------------------------------------ acyclic side

void Master::message(bool error, const std::string& source, const std::string& text) {
  if (messages_) messages_->post(error ? MessageKind::Error : MessageKind::Text, source, text);
}

void Master::post(std::function<void(int64_t)> job) {
  std::lock_guard<std::mutex> lock(post_mutex_);
  posted_.push_back(std::move(job));
}

Master::NodeRt* Master::find(uint8_t node) const noexcept {
  for (const auto& n : nodes_) {
    if (n->cfg.id == node) return n.get();
  }
  return nullptr;
}

void Master::send_nmt(NmtCommand c, uint8_t node) {
  acyclic_port_->send(can::Frame::make(cob::kNmt, {static_cast<uint8_t>(c), node}));
}

void Master::nmt(NmtCommand command, uint8_t node) {
  post([this, command, node](int64_t) { send_nmt(command, node); });
}

void Master::set_cycle_ns(int64_t ns) {
  BusConfig c = config_;
  c.cycle_ns = ns;
  c.validate();
  config_.cycle_ns = ns;
}

void Master::start_thread() {
  if (thread_.joinable()) return;
  stop_.store(false);
  thread_ = std::thread([this] { thread_main(); });
}

void Master::stop_thread() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  acyclic_thread_id_ = {};
}

void Master::thread_main() {
  acyclic_thread_id_ = std::this_thread::get_id();
  while (!stop_.load(std::memory_order_acquire)) {
    const int64_t now = acyclic_port_->now_ns();  // the bus's clock: a simulated bus that stands still is not silent
    poll(now);
    last_poll_seen_ns_.store(now, std::memory_order_release);
    acyclic_port_->wait(1'000'000);
  }
}

void Master::poll(int64_t now_ns) {
  last_poll_ns_ = now_ns;
  // The SDO share applies while process data flows; the first boot, before
  // the cycle starts, has the bus to itself.
  sdo_pacer_.set_active(cyclic_enabled_.load(std::memory_order_acquire));
  std::vector<std::function<void(int64_t)>> jobs;
  {
    std::lock_guard<std::mutex> lock(post_mutex_);
    jobs.swap(posted_);
  }
  for (auto& j : jobs) j(now_ns);
  can::Frame f;
  while (acyclic_port_->receive(f)) handle_frame(f, now_ns);
  service_rt_sdo();
  for (const auto& n : nodes_) {
    if (n->reboot_request.exchange(false)) reboot_node(n->cfg.id);
  }
  for (const auto& n : nodes_) n->sdo->poll(now_ns);
  if (booting_) run_boot(now_ns);
  for (const auto& n : nodes_) {
    if (n->rebooting && !booting_) continue_reboot(*n, now_ns);
  }
  // Heartbeat producer, until the servo thread's cycle takes it over (for
  // good: were this thread to take it back, a stopped servo thread would go
  // unnoticed by the devices).
  if (config_.master_heartbeat_ms > 0 && !heartbeat_in_cycle_.load(std::memory_order_acquire) &&
      now_ns >= next_heartbeat_ns_) {
    const uint8_t state = boot_state() == BootState::Succeeded ? 0x05 : 0x7F;
    acyclic_port_->send(can::Frame::make(cob::heartbeat(config_.master_node_id), {state}));
    next_heartbeat_ns_ = now_ns + int64_t{config_.master_heartbeat_ms} * 1'000'000;
  }
  // Heartbeat consumer. A heartbeat lost while nothing at all came from
  // the bus and the interface refused frames is the interface's fault, not
  // the node's: said once, with the count, before the nodes' messages.
  for (const auto& np : nodes_) {
    NodeRt& n = *np;
    const uint16_t timeout = n.cfg.consumer_timeout_ms();
    if (!n.monitor || timeout == 0 || n.hb_lost.load()) continue;
    if (now_ns - n.last_hb_ns > int64_t{timeout} * 1'000'000) {
      const uint32_t refused = send_errors_.load(std::memory_order_relaxed) - send_errors_at_rx_;
      // The interface refuses every frame now (a stopped queue, a link
      // down, no other node to acknowledge), not one refusal in passing.
      const bool silent = consecutive_send_errors_.load(std::memory_order_relaxed) >= 3 && refused > 0;
      if (silent && !silence_reported_) {
        silence_reported_ = true;
        const auto last = static_cast<can::SendStatus>(last_send_error_.load(std::memory_order_relaxed));
        message(true, config_.name,
                "CAN interface " + cyclic_port_->name() + " is down or disconnected: nothing received for " +
                    std::to_string((now_ns - last_rx_ns_) / 1'000'000) + " ms and " + std::to_string(refused) +
                    " frames refused by it (last: " + can::to_string(last) + "); every node's heartbeat is lost");
      }
      n.hb_lost.store(true);
      set_fault(n, "heartbeat lost: nothing heard for " + std::to_string(timeout) +
                       (silence_reported_ ? " ms (the interface is down, see above)"
                                          : " ms (power, cable, termination or bus-off?)"));
    }
  }
}

void Master::set_fault(NodeRt& n, const std::string& why) {
  n.fault.store(true);
  const bool mandatory = n.cfg.mandatory;
  message(mandatory, n.source, n.cfg.label() + ": " + why);
}

void Master::handle_frame(const can::Frame& f, int64_t now_ns) {
  if (f.is_error()) return;
  last_rx_ns_ = f.timestamp_ns > 0 && f.timestamp_ns <= now_ns ? f.timestamp_ns : now_ns;
  send_errors_at_rx_ = send_errors_.load(std::memory_order_relaxed);
  if (silence_reported_) {
    silence_reported_ = false;
    message(false, config_.name, "CAN interface " + cyclic_port_->name() + ": frames received again");
  }
  if (f.is_extended()) return;
  const uint32_t id = f.id;
  if (id > cob::kHeartbeatBase && id <= cob::kHeartbeatBase + kMaxNodeId) {
    if (f.is_remote() || f.len < 1) return;
    // Heard when it was received (a late poll must not make it older).
    const int64_t heard = f.timestamp_ns > 0 && f.timestamp_ns <= now_ns ? f.timestamp_ns : now_ns;
    if (NodeRt* n = find(static_cast<uint8_t>(id - cob::kHeartbeatBase))) handle_heartbeat(*n, f.data[0] & 0x7F, heard);
    return;
  }
  if (id > cob::kSdoTxBase && id <= cob::kSdoTxBase + kMaxNodeId) {
    if (NodeRt* n = find(static_cast<uint8_t>(id - cob::kSdoTxBase))) n->sdo->on_frame(f, now_ns);
    return;
  }
  if (id > cob::kEmcyBase && id <= cob::kEmcyBase + kMaxNodeId) handle_emcy(static_cast<uint8_t>(id - cob::kEmcyBase), f);
}

void Master::handle_heartbeat(NodeRt& n, uint8_t state, int64_t now_ns) {
  const NmtState s = nmt_state_from_byte(state);
  n.state.store(state);
  n.last_hb_ns = now_ns;
  if (n.hb_lost.exchange(false)) message(false, n.source, n.cfg.label() + ": heartbeat back (" + to_string(s) + ")");
  if (s == NmtState::Initialising) {
    n.boot_up_seen = true;
    if (n.in_cycle.load()) {
      n.in_cycle.store(false);
      n.booted.store(false);
      n.monitor = false;
      set_fault(n, "restarted (boot-up message) while in operation: its configuration is lost; reboot the node");
    }
    return;
  }
  if (n.phase == NodeRt::Phase::Done && s != NmtState::Operational && !n.fault.load()) {
    set_fault(n, std::string("left operational: it reports ") + to_string(s));
  }
}

void Master::handle_emcy(uint8_t node, const can::Frame& f) {
  Emcy e;
  if (!decode_emcy(f, e)) return;
  char text[200];
  format_emcy(e, text, sizeof text);
  NodeRt* n = find(node);
  if (!n) {
    message(true, config_.name, "node " + std::to_string(node) + " (not configured): " + text);
    return;
  }
  n->emcy_code.store(e.code);
  n->error_register.store(e.error_register);
  n->emcy_count.fetch_add(1);
  message(!e.is_reset(), n->source, n->cfg.label() + ": " + text);
}

// ------------------------------------------------------------ status

NodeStatus Master::node_status_at(std::size_t i) const noexcept {
  NodeStatus s;
  if (i >= nodes_.size()) return s;
  const NodeRt& n = *nodes_[i];
  s.id = n.cfg.id;
  s.state = nmt_state_from_byte(n.state.load(std::memory_order_relaxed));
  if (n.state.load(std::memory_order_relaxed) == static_cast<uint8_t>(NmtState::Unknown)) s.state = NmtState::Unknown;
  s.booted = n.booted.load(std::memory_order_relaxed);
  s.operational = s.booted && s.state == NmtState::Operational;
  s.fault = n.fault.load(std::memory_order_relaxed);
  s.heartbeat_lost = n.hb_lost.load(std::memory_order_relaxed);
  s.emcy_code = n.emcy_code.load(std::memory_order_relaxed);
  s.error_register = n.error_register.load(std::memory_order_relaxed);
  s.emcy_count = n.emcy_count.load(std::memory_order_relaxed);
  s.pdo_missed = n.pdo_missed.load(std::memory_order_relaxed);
  return s;
}

NodeStatus Master::node_status(uint8_t node) const noexcept {
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    if (nodes_[i]->cfg.id == node) return node_status_at(i);
  }
  return {};
}

bool Master::is_ready() const noexcept {
  if (boot_state() != BootState::Succeeded) return false;
  if (interface_down_.load(std::memory_order_relaxed)) return false;
  if (sync_stalled_.load(std::memory_order_relaxed)) return false;
  if (bus_state_.load(std::memory_order_relaxed) == static_cast<int>(can::BusState::BusOff)) return false;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    if (!nodes_[i]->cfg.mandatory) continue;
    const NodeStatus s = node_status_at(i);
    if (!s.operational || s.fault) return false;
  }
  return true;
}

bool Master::has_fault() const noexcept {
  if (boot_state() == BootState::Failed) return true;
  if (interface_down_.load(std::memory_order_relaxed)) return true;
  if (bus_state_.load(std::memory_order_relaxed) == static_cast<int>(can::BusState::BusOff)) return true;
  for (const auto& n : nodes_) {
    if (n->cfg.mandatory && n->fault.load(std::memory_order_relaxed)) return true;
  }
  return false;
}

}  // namespace cnc::canopen
