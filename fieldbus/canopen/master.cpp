#include "fieldbus/canopen/master.hpp"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <future>
#include <stdexcept>

#include "core/util/messages.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/sdo_abort.hpp"

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

namespace {

std::string hexbytes(const std::vector<uint8_t>& v) {
  char buf[16];
  if (v.size() <= 4) {
    uint32_t x = 0;
    for (std::size_t i = 0; i < v.size(); ++i) x |= static_cast<uint32_t>(v[i]) << (8 * i);
    std::snprintf(buf, sizeof buf, "0x%0*X", static_cast<int>(v.size() * 2 > 0 ? v.size() * 2 : 2), x);
    return buf;
  }
  std::string out;
  for (std::size_t i = 0; i < v.size() && i < 16; ++i) {
    std::snprintf(buf, sizeof buf, "%s%02X", i ? " " : "", v[i]);
    out += buf;
  }
  if (v.size() > 16) out += " ... (" + std::to_string(v.size()) + " bytes)";
  return out;
}

std::string addr_text(ObjectAddress a) {
  char buf[16];
  return format(a, buf, sizeof buf);
}

std::vector<uint8_t> u32_bytes(uint32_t v, std::size_t n = 4) {
  std::vector<uint8_t> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<uint8_t>(v >> (8 * i));
  return out;
}

uint32_t as_u32(const std::vector<uint8_t>& v) {
  uint32_t x = 0;
  for (std::size_t i = 0; i < v.size() && i < 4; ++i) x |= static_cast<uint32_t>(v[i]) << (8 * i);
  return x;
}

}  // namespace

// One SDO action of a node's boot.
struct Master::Step {
  enum class Kind : uint8_t { Expect, Write, Verify };
  Kind kind = Kind::Write;
  ObjectAddress addr;
  std::vector<uint8_t> data;       // Write: value; Expect/Verify: expected (empty: only read)
  uint32_t mask = 0xFFFFFFFF;      // comparison mask for values of up to 4 bytes
  bool may_be_missing = false;     // Write: the device may not have the object
  std::string what;                // "vendor-ID", "RPDO1 mapping entry 1", ...
};

struct Master::TpdoRt {
  std::size_t node = 0;
  uint16_t number = 0;
  uint32_t cob = 0;
  uint8_t bytes = 0;
  uint8_t type = 1;
  std::array<uint8_t, 8> image{};
  uint64_t received_serial = 0;
  bool ever = false;
  uint32_t consecutive_missed = 0;
};

struct Master::RpdoRt {
  std::size_t node = 0;
  uint16_t number = 0;
  uint32_t cob = 0;
  uint8_t bytes = 0;
  std::array<uint8_t, 8> image{};
};

struct Master::NodeRt {
  enum class Phase : uint8_t { Idle, WaitBootUp, Steps, Ready, WaitOperational, Done, Failed };
  NodeConfig cfg;
  std::unique_ptr<SdoClient> sdo;
  std::vector<Step> steps;
  Phase phase = Phase::Idle;
  std::size_t step = 0;
  bool step_active = false;
  uint64_t generation = 0;
  int64_t deadline_ns = 0;
  bool boot_up_seen = false;
  int64_t last_hb_ns = -1;
  bool monitor = false;
  std::string error;
  std::string source;  // "canopen.0.node.03"
  bool rebooting = false;
  std::atomic<bool> reboot_request{false};
  // published
  std::atomic<uint8_t> state{static_cast<uint8_t>(NmtState::Unknown)};
  std::atomic<bool> booted{false};
  std::atomic<bool> in_cycle{false};
  std::atomic<bool> fault{false};
  std::atomic<bool> hb_lost{false};
  std::atomic<uint16_t> emcy_code{0};
  std::atomic<uint8_t> error_register{0};
  std::atomic<uint32_t> emcy_count{0};
  std::atomic<uint32_t> pdo_missed{0};
  // servo thread
  uint64_t inputs_serial = 0;
  bool pdo_fault_reported = false;
};

// ------------------------------------------------------------ construction

namespace {
// An in-process bus runs at the configured bit rate unless the interface
// names one itself ("virtual:sim,bitrate=500000").
std::string transport_spec(const BusConfig& c) {
  if (c.interface.rfind("virtual:", 0) == 0 && c.interface.find("bitrate=") == std::string::npos) {
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
        write({comm, 1}, u32_bytes(default_pdo_cob(tpdo, number, c.id) | cob::kPdoInvalid),
              std::string(kind) + std::to_string(number) + " off (not configured)", false, 0xFFFFFFFF, true);
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
  // Heartbeat consumer.
  for (const auto& np : nodes_) {
    NodeRt& n = *np;
    const uint16_t timeout = n.cfg.consumer_timeout_ms();
    if (!n.monitor || timeout == 0 || n.hb_lost.load()) continue;
    if (now_ns - n.last_hb_ns > int64_t{timeout} * 1'000'000) {
      n.hb_lost.store(true);
      set_fault(n, "heartbeat lost: nothing heard for " + std::to_string(timeout) +
                       " ms (power, cable, termination or bus-off?)");
    }
  }
}

void Master::set_fault(NodeRt& n, const std::string& why) {
  n.fault.store(true);
  const bool mandatory = n.cfg.mandatory;
  message(mandatory, n.source, n.cfg.label() + ": " + why);
}

void Master::handle_frame(const can::Frame& f, int64_t now_ns) {
  if (f.is_error() || f.is_extended()) return;
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

// ------------------------------------------------------------ boot

void Master::begin_boot() {
  {
    std::lock_guard<std::mutex> lock(boot_mutex_);
    boot_error_.clear();
  }
  boot_state_.store(BootState::Running, std::memory_order_release);
  post([this](int64_t now) {
    booting_ = true;
    start_sent_ = false;
    boot_started_ns_ = now;
    cyclic_enabled_.store(false);
    for (const auto& n : nodes_) {
      n->sdo->cancel_all(abort_code::kGeneral, now);
      ++n->generation;
      n->rebooting = false;
      n->phase = config_.reset_nodes ? NodeRt::Phase::WaitBootUp : NodeRt::Phase::Steps;
      n->step = 0;
      n->step_active = false;
      n->boot_up_seen = false;
      n->deadline_ns = now + config_.boot_timeout_ns;
      n->error.clear();
      n->monitor = false;
      n->in_cycle.store(false);
      n->booted.store(false);
      n->fault.store(false);
      n->hb_lost.store(false);
      if (config_.reset_nodes) send_nmt(NmtCommand::ResetCommunication, n->cfg.id);
    }
  });
}

std::string Master::boot_error() const {
  std::lock_guard<std::mutex> lock(boot_mutex_);
  return boot_error_;
}

void Master::node_failed(NodeRt& n, const std::string& why) {
  n.phase = NodeRt::Phase::Failed;
  n.error = n.cfg.label() + ": " + why;
  n.sdo->cancel_all(abort_code::kGeneral, last_poll_ns_);
  ++n.generation;
  if (!n.cfg.mandatory) {
    n.fault.store(true);
    message(false, n.source, n.error + " (optional node: start-up continues without it)");
  }
}

void Master::boot_node(NodeRt& n, int64_t now_ns) {
  using Phase = NodeRt::Phase;
  switch (n.phase) {
    case Phase::WaitBootUp:
      if (n.boot_up_seen) {
        n.phase = Phase::Steps;
      } else if (now_ns > n.deadline_ns) {
        node_failed(n, "not found: no boot-up message within " + std::to_string(config_.boot_timeout_ns / 1'000'000) +
                           " ms after NMT reset communication (power, wiring, node-ID, bit rate?)");
        return;
      } else {
        return;
      }
      [[fallthrough]];
    case Phase::Steps: {
      if (n.step_active) return;
      if (n.step >= n.steps.size()) {
        n.phase = Phase::Ready;
        return;
      }
      const Step& s = n.steps[n.step];
      n.step_active = true;
      const uint64_t gen = n.generation;
      auto done = [this, &n, gen](const SdoResult& r) {
        if (n.generation != gen) return;
        n.step_active = false;
        const Step& st = n.steps[n.step];
        const std::string obj = addr_text(st.addr);
        if (!r.ok()) {
          if (st.kind == Step::Kind::Write && st.may_be_missing &&
              (r.abort_code == abort_code::kNoObject || r.abort_code == abort_code::kNoSubIndex)) {
            ++n.step;
            return;
          }
          char code[200];
          std::snprintf(code, sizeof code, "0x%08X %s", r.abort_code, sdo_abort_text(r.abort_code));
          if (n.step == 0 && r.abort_code == abort_code::kTimeout && r.aborted_by_client) {
            node_failed(n, "not found: no answer to SDO upload " + obj + " (device type) within " +
                               std::to_string(config_.sdo_timeout_ns / 1'000'000) + " ms");
          } else if (st.kind == Step::Kind::Write) {
            node_failed(n, "writing " + obj + " = " + hexbytes(st.data) + " (" + st.what + ") refused: " + code);
          } else {
            node_failed(n, "reading " + obj + " (" + st.what + ") failed: " + code);
          }
          return;
        }
        if (st.kind != Step::Kind::Write && !st.data.empty()) {
          // Values up to 4 bytes compare as numbers under the mask (the
          // identity as U32, COB-IDs without the RTR bit), longer ones bytewise.
          const bool same = st.data.size() <= 4 && r.data.size() <= 4
                                ? (as_u32(r.data) & st.mask) == (as_u32(st.data) & st.mask)
                                : r.data == st.data;
          if (!same) {
            if (st.kind == Step::Kind::Expect) {
              node_failed(n, (st.addr.index == 0x1018 ? "identity " : "") + obj + " " + st.what + " is " +
                                 hexbytes(r.data) + ", expected " + hexbytes(st.data) + " (wrong device at this node-ID?)");
            } else {
              node_failed(n, "verification of " + obj + " (" + st.what + ") failed: the device has " + hexbytes(r.data) +
                                 " after " + hexbytes(st.data) + " was written");
            }
            return;
          }
        }
        ++n.step;
      };
      if (s.kind == Step::Kind::Write) n.sdo->download(s.addr, s.data, done);
      else n.sdo->upload(s.addr, done);
      return;
    }
    case Phase::WaitOperational:
      if (n.cfg.heartbeat_ms == 0 || nmt_state_from_byte(n.state.load()) == NmtState::Operational) {
        n.phase = Phase::Done;
        n.booted.store(true);
      } else if (now_ns > n.deadline_ns) {
        node_failed(n, std::string("did not enter operational within ") + std::to_string(config_.boot_timeout_ns / 1'000'000) +
                           " ms after NMT start (its heartbeat says " + to_string(nmt_state_from_byte(n.state.load())) + ")");
      }
      return;
    default:
      return;
  }
}

void Master::run_boot(int64_t now_ns) {
  using Phase = NodeRt::Phase;
  for (const auto& n : nodes_) boot_node(*n, now_ns);
  // A mandatory node that failed stops the start-up.
  for (const auto& n : nodes_) {
    if (n->phase == Phase::Failed && n->cfg.mandatory) {
      booting_ = false;
      for (const auto& other : nodes_) {
        other->sdo->cancel_all(abort_code::kGeneral, now_ns);
        ++other->generation;
      }
      const std::string why = "start-up stopped: " + n->error;
      message(true, config_.name, why);
      {
        // Under the lock, so that boot() cannot miss the notification.
        std::lock_guard<std::mutex> lock(boot_mutex_);
        boot_error_ = config_.name + ": " + why;
        boot_state_.store(BootState::Failed, std::memory_order_release);
      }
      boot_cv_.notify_all();
      return;
    }
  }
  auto all = [&](std::initializer_list<Phase> phases) {
    return std::all_of(nodes_.begin(), nodes_.end(), [&](const auto& n) {
      return n->phase == Phase::Failed || std::find(phases.begin(), phases.end(), n->phase) != phases.end();
    });
  };
  if (!start_sent_ && all({Phase::Ready})) {
    start_sent_ = true;
    if (config_.start_all) send_nmt(NmtCommand::Start, 0);
    for (const auto& n : nodes_) {
      if (n->phase != Phase::Ready) continue;
      if (!config_.start_all) send_nmt(NmtCommand::Start, n->cfg.id);
      n->phase = Phase::WaitOperational;
      n->deadline_ns = now_ns + config_.boot_timeout_ns;
      n->in_cycle.store(true);
      n->monitor = n->cfg.heartbeat_ms > 0;
      n->last_hb_ns = now_ns;
    }
    return;
  }
  if (start_sent_ && all({Phase::Done})) {
    booting_ = false;
    std::size_t up = 0;
    for (const auto& n : nodes_) up += n->phase == Phase::Done;
    const can::BusLoad l = config_.load();
    char text[200];
    std::snprintf(text, sizeof text, "%zu of %zu nodes operational in %.0f ms; planned bus load %.1f %% (worst case)", up,
                  nodes_.size(), static_cast<double>(now_ns - boot_started_ns_) / 1e6, l.worst_case() * 100);
    message(false, config_.name, text);
    cyclic_enabled_.store(true, std::memory_order_release);
    {
      std::lock_guard<std::mutex> lock(boot_mutex_);
      boot_state_.store(BootState::Succeeded, std::memory_order_release);
    }
    boot_cv_.notify_all();
  }
}

void Master::boot() {
  if (!thread_running()) start_thread();
  begin_boot();
  std::unique_lock<std::mutex> lock(boot_mutex_);
  boot_cv_.wait(lock, [&] { return boot_state() != BootState::Running; });
  if (boot_state() == BootState::Failed) throw std::runtime_error(boot_error_);
}

void Master::reboot_node(uint8_t node) {
  post([this, node](int64_t now) {
    NodeRt* n = find(node);
    if (!n || booting_) return;
    n->sdo->cancel_all(abort_code::kGeneral, now);
    ++n->generation;
    n->reboot_request.store(false);
    n->in_cycle.store(false);
    n->booted.store(false);
    n->monitor = false;
    n->fault.store(false);
    n->hb_lost.store(false);
    n->pdo_missed.store(0);
    n->step = 0;
    n->step_active = false;
    n->boot_up_seen = false;
    n->deadline_ns = now + config_.boot_timeout_ns;
    n->phase = config_.reset_nodes ? NodeRt::Phase::WaitBootUp : NodeRt::Phase::Steps;
    if (config_.reset_nodes) send_nmt(NmtCommand::ResetCommunication, n->cfg.id);
    message(false, n->source, n->cfg.label() + ": rebooting");
    n->rebooting = true;  // poll() carries it through the phases
  });
}

void Master::continue_reboot(NodeRt& n, int64_t now_ns) {
  boot_node(n, now_ns);
  if (n.phase == NodeRt::Phase::Ready) {
    send_nmt(NmtCommand::Start, n.cfg.id);
    n.phase = NodeRt::Phase::WaitOperational;
    n.deadline_ns = now_ns + config_.boot_timeout_ns;
    n.in_cycle.store(true);
    n.monitor = n.cfg.heartbeat_ms > 0;
    n.last_hb_ns = now_ns;
  }
  if (n.phase == NodeRt::Phase::Done) {
    n.rebooting = false;
    message(false, n.source, n.cfg.label() + ": back in operation");
  } else if (n.phase == NodeRt::Phase::Failed) {
    n.rebooting = false;
    n.fault.store(true);
    message(true, n.source, n.error);
  }
}

// ------------------------------------------------------------ SDO access

void Master::sdo_upload(uint8_t node, ObjectAddress a, SdoClient::Done done, SdoMode mode) {
  post([this, node, a, done = std::move(done), mode](int64_t) mutable {
    NodeRt* n = find(node);
    if (!n) {
      SdoResult r;
      r.addr = a;
      r.upload = true;
      r.abort_code = abort_code::kResourceNotAvailable;
      r.aborted_by_client = true;
      if (done) done(r);
      return;
    }
    n->sdo->upload(a, std::move(done), mode);
  });
}

void Master::sdo_download(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoClient::Done done, SdoMode mode) {
  post([this, node, a, data = std::move(data), done = std::move(done), mode](int64_t) mutable {
    NodeRt* n = find(node);
    if (!n) {
      SdoResult r;
      r.addr = a;
      r.abort_code = abort_code::kResourceNotAvailable;
      r.aborted_by_client = true;
      if (done) done(r);
      return;
    }
    n->sdo->download(a, std::move(data), std::move(done), mode);
  });
}

SdoResult Master::sdo_upload_wait(uint8_t node, ObjectAddress a, SdoMode mode) {
  if (std::this_thread::get_id() == acyclic_thread_id_) throw std::logic_error("sdo_upload_wait from the acyclic thread would deadlock");
  if (!thread_running()) throw std::logic_error("sdo_upload_wait needs the acyclic thread (start_thread)");
  auto p = std::make_shared<std::promise<SdoResult>>();
  auto f = p->get_future();
  sdo_upload(node, a, [p](const SdoResult& r) { p->set_value(r); }, mode);
  return f.get();
}

SdoResult Master::sdo_download_wait(uint8_t node, ObjectAddress a, std::vector<uint8_t> data, SdoMode mode) {
  if (std::this_thread::get_id() == acyclic_thread_id_) throw std::logic_error("sdo_download_wait from the acyclic thread would deadlock");
  if (!thread_running()) throw std::logic_error("sdo_download_wait needs the acyclic thread (start_thread)");
  auto p = std::make_shared<std::promise<SdoResult>>();
  auto f = p->get_future();
  sdo_download(node, a, std::move(data), [p](const SdoResult& r) { p->set_value(r); }, mode);
  return f.get();
}

// Realtime SDO slots: the servo thread claims a free slot and fills it; the
// acyclic thread runs the transfer and marks it done.
int Master::rt_sdo_read(uint8_t node, ObjectAddress a) noexcept {
  for (std::size_t i = 0; i < rt_sdo_.size(); ++i) {
    int expected = 0;
    if (rt_sdo_[i].state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
      RtSdoSlot& s = rt_sdo_[i];
      s.node = node;
      s.addr = a;
      s.write = false;
      s.result = RtSdoResult{};
      s.state.store(2, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

int Master::rt_sdo_write(uint8_t node, ObjectAddress a, uint32_t value, uint8_t size) noexcept {
  if (size < 1 || size > 4) return -1;
  for (std::size_t i = 0; i < rt_sdo_.size(); ++i) {
    int expected = 0;
    if (rt_sdo_[i].state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
      RtSdoSlot& s = rt_sdo_[i];
      s.node = node;
      s.addr = a;
      s.write = true;
      s.value = value;
      s.size = size;
      s.result = RtSdoResult{};
      s.state.store(2, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

bool Master::rt_sdo_poll(int handle, RtSdoResult& out) noexcept {
  if (handle < 0 || static_cast<std::size_t>(handle) >= rt_sdo_.size()) return false;
  RtSdoSlot& s = rt_sdo_[static_cast<std::size_t>(handle)];
  if (s.state.load(std::memory_order_acquire) != 4) return false;
  out = s.result;
  s.state.store(0, std::memory_order_release);
  return true;
}

void Master::service_rt_sdo() {
  for (auto& s : rt_sdo_) {
    if (s.state.load(std::memory_order_acquire) != 2) continue;
    s.state.store(3, std::memory_order_relaxed);
    RtSdoSlot* slot = &s;
    auto done = [slot](const SdoResult& r) {
      slot->result.abort_code = r.abort_code;
      if (r.ok() && r.upload) {
        slot->result.size = static_cast<uint8_t>(std::min<std::size_t>(r.data.size(), 4));
        slot->result.value = as_u32(r.data);
      }
      slot->state.store(4, std::memory_order_release);
    };
    NodeRt* n = find(s.node);
    if (!n) {
      s.result.abort_code = abort_code::kResourceNotAvailable;
      s.state.store(4, std::memory_order_release);
      continue;
    }
    if (s.write) n->sdo->download(s.addr, u32_bytes(s.value, s.size), done, SdoMode::Expedited);
    else n->sdo->upload(s.addr, done);
  }
}

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
    if (missing) {
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
  if (st == can::SendStatus::Ok) return true;
  ++cyclic_.send_errors;
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
