#include "fieldbus/canopen/slave_node.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include "fieldbus/canopen/sdo_abort.hpp"

namespace cnc::canopen {
namespace {

void add_if_missing(ObjectDictionary& od, ObjectAddress a, DataType t, Access acc, uint64_t v, const char* name,
                    bool mappable = false) {
  if (!od.find(a)) od.add(a, t, acc, v, mappable, name);
}

uint32_t get_u32(const uint8_t* d) noexcept { return get_le<uint32_t>(d); }

}  // namespace

void SlaveNode::add_communication_objects(ObjectDictionary& od, const SlaveOptions& o) {
  using D = DataType;
  using A = Access;
  const unsigned id = o.node_id;
  add_if_missing(od, {0x1000, 0}, D::Unsigned32, A::ReadOnly, o.identity.device_type, "Device type");
  add_if_missing(od, {0x1001, 0}, D::Unsigned8, A::ReadOnly, 0, "Error register", true);
  add_if_missing(od, {0x1003, 0}, D::Unsigned8, A::ReadWrite, 0, "Number of errors");
  for (uint8_t s = 1; s <= 8; ++s) add_if_missing(od, {0x1003, s}, D::Unsigned32, A::ReadOnly, 0, "Standard error field");
  add_if_missing(od, {0x1005, 0}, D::Unsigned32, A::ReadWrite, cob::kSync, "COB-ID SYNC");
  add_if_missing(od, {0x1006, 0}, D::Unsigned32, A::ReadWrite, 0, "Communication cycle period");
  add_if_missing(od, {0x1007, 0}, D::Unsigned32, A::ReadWrite, 0, "Synchronous window length");
  if (!od.find({0x1008, 0})) od.add_string({0x1008, 0}, A::Const, o.identity.device_name, 0, "Manufacturer device name");
  if (!od.find({0x100A, 0})) od.add_string({0x100A, 0}, A::Const, "cnc-canopen 0.1", 0, "Manufacturer software version");
  add_if_missing(od, {0x100C, 0}, D::Unsigned16, A::ReadWrite, 0, "Guard time");
  add_if_missing(od, {0x100D, 0}, D::Unsigned8, A::ReadWrite, 0, "Life time factor");
  add_if_missing(od, {0x1014, 0}, D::Unsigned32, A::ReadWrite, cob::emcy(id), "COB-ID EMCY");
  add_if_missing(od, {0x1015, 0}, D::Unsigned16, A::ReadWrite, 0, "Inhibit time EMCY");
  add_if_missing(od, {0x1016, 0}, D::Unsigned8, A::ReadOnly, 4, "Consumer heartbeat time");
  for (uint8_t s = 1; s <= 4; ++s) add_if_missing(od, {0x1016, s}, D::Unsigned32, A::ReadWrite, 0, "Consumer heartbeat time");
  add_if_missing(od, {0x1017, 0}, D::Unsigned16, A::ReadWrite, o.heartbeat_ms, "Producer heartbeat time");
  add_if_missing(od, {0x1018, 0}, D::Unsigned8, A::ReadOnly, 4, "Identity object");
  add_if_missing(od, {0x1018, 1}, D::Unsigned32, A::ReadOnly, o.identity.vendor_id, "Vendor-ID");
  add_if_missing(od, {0x1018, 2}, D::Unsigned32, A::ReadOnly, o.identity.product_code, "Product code");
  add_if_missing(od, {0x1018, 3}, D::Unsigned32, A::ReadOnly, o.identity.revision, "Revision number");
  add_if_missing(od, {0x1018, 4}, D::Unsigned32, A::ReadOnly, o.identity.serial, "Serial number");
  add_if_missing(od, {0x1019, 0}, D::Unsigned8, A::ReadWrite, 0, "Synchronous counter overflow value");
  add_if_missing(od, {0x1200, 0}, D::Unsigned8, A::ReadOnly, 2, "SDO server parameter");
  add_if_missing(od, {0x1200, 1}, D::Unsigned32, A::ReadOnly, cob::sdo_request(id), "COB-ID client to server");
  add_if_missing(od, {0x1200, 2}, D::Unsigned32, A::ReadOnly, cob::sdo_response(id), "COB-ID server to client");
  for (unsigned n = 1; n <= o.rpdo_count && n <= kMaxPdos; ++n) {
    const uint16_t c = rpdo_comm_index(n), m = rpdo_map_index(n);
    const uint32_t cob = default_pdo_cob(false, n, id);
    add_if_missing(od, {c, 0}, D::Unsigned8, A::ReadOnly, 5, "RPDO communication parameter");
    add_if_missing(od, {c, 1}, D::Unsigned32, A::ReadWrite, (cob ? cob : 0) | cob::kPdoInvalid, "COB-ID used by RPDO");
    add_if_missing(od, {c, 2}, D::Unsigned8, A::ReadWrite, 255, "Transmission type");
    add_if_missing(od, {c, 3}, D::Unsigned16, A::ReadWrite, 0, "Inhibit time");
    add_if_missing(od, {c, 5}, D::Unsigned16, A::ReadWrite, 0, "Event timer");
    add_if_missing(od, {m, 0}, D::Unsigned8, A::ReadWrite, 0, "Number of mapped objects");
    for (uint8_t s = 1; s <= kMaxMapEntries; ++s) add_if_missing(od, {m, s}, D::Unsigned32, A::ReadWrite, 0, "Mapped object");
  }
  for (unsigned n = 1; n <= o.tpdo_count && n <= kMaxPdos; ++n) {
    const uint16_t c = tpdo_comm_index(n), m = tpdo_map_index(n);
    const uint32_t cob = default_pdo_cob(true, n, id);
    add_if_missing(od, {c, 0}, D::Unsigned8, A::ReadOnly, 6, "TPDO communication parameter");
    add_if_missing(od, {c, 1}, D::Unsigned32, A::ReadWrite, (cob ? cob : 0) | cob::kPdoInvalid, "COB-ID used by TPDO");
    add_if_missing(od, {c, 2}, D::Unsigned8, A::ReadWrite, 255, "Transmission type");
    add_if_missing(od, {c, 3}, D::Unsigned16, A::ReadWrite, 0, "Inhibit time");
    add_if_missing(od, {c, 5}, D::Unsigned16, A::ReadWrite, 0, "Event timer");
    add_if_missing(od, {c, 6}, D::Unsigned8, A::ReadWrite, 0, "SYNC start value");
    add_if_missing(od, {m, 0}, D::Unsigned8, A::ReadWrite, 0, "Number of mapped objects");
    for (uint8_t s = 1; s <= kMaxMapEntries; ++s) add_if_missing(od, {m, s}, D::Unsigned32, A::ReadWrite, 0, "Mapped object");
  }
}

SlaveNode::SlaveNode(ObjectDictionary& od, can::Transport& transport, SlaveOptions options)
    : od_((add_communication_objects(od, options), od)),
      transport_(transport),
      options_(std::move(options)),
      sdo_(od_, transport_, cob::sdo_request(options_.node_id), cob::sdo_response(options_.node_id)),
      lss_(lss::Address{options_.identity.vendor_id, options_.identity.product_code, options_.identity.revision,
                        options_.identity.serial},
           options_.node_id) {
  if (options_.node_id == lss::kUnconfigured ? !options_.lss : (options_.node_id < 1 || options_.node_id > kMaxNodeId)) {
    throw std::invalid_argument("CANopen device: node-ID " + std::to_string(options_.node_id) +
                                " is not 1-127 (255, unconfigured, only for a device with LSS)");
  }
  install_checks();
  reconfigure();
}

void SlaveNode::send(const can::Frame& f) noexcept {
  if (!muted_) transport_.send(f);
}

// --- validation of writes to the communication objects ---

uint32_t SlaveNode::check_mapping(const OdEntry& e, const uint8_t* d, std::size_t n, bool tpdo) const noexcept {
  const unsigned number = e.addr.index - (tpdo ? 0x1A00u : 0x1600u) + 1;
  const uint16_t comm = tpdo ? tpdo_comm_index(number) : rpdo_comm_index(number);
  if (options_.pdo_mapping_needs_preop && state_ != NmtState::PreOperational) return abort_code::kDeviceState;
  if (!(od_.get<uint32_t>({comm, 1}) & cob::kPdoInvalid)) return abort_code::kUnsupportedAccess;  // PDO in use
  if (e.addr.sub == 0) {
    if (n != 1) return abort_code::kLengthMismatch;
    const uint8_t count = d[0];
    if (count > kMaxMapEntries || !od_.find({e.addr.index, count})) return abort_code::kValueTooHigh;
    uint32_t bits = 0;
    for (uint8_t s = 1; s <= count; ++s) {
      const PdoMapEntry m = PdoMapEntry::decode(od_.get<uint32_t>({e.addr.index, s}));
      if (m.bits == 0) return abort_code::kNotMappable;
      bits += m.bits;
    }
    return bits > 64 ? abort_code::kPdoLength : 0;
  }
  if (od_.get<uint8_t>({e.addr.index, 0}) != 0) return abort_code::kUnsupportedAccess;  // sub 0 must be 0 first
  if (n != 4) return abort_code::kLengthMismatch;
  const PdoMapEntry m = PdoMapEntry::decode(get_u32(d));
  if (m.encode() == 0) return 0;  // clearing an entry
  if (m.is_dummy()) {
    if (tpdo) return abort_code::kNotMappable;
    const std::size_t size = data_type_size(static_cast<DataType>(m.index));
    return m.bits == size * 8 || (m.index == 0x0001 && m.bits == 1) ? 0 : abort_code::kNotMappable;
  }
  const OdEntry* target = od_.find({m.index, m.sub});
  if (!target) return od_.has_index(m.index) ? abort_code::kNoSubIndex : abort_code::kNoObject;
  if (!target->pdo_mappable) return abort_code::kNotMappable;
  if (tpdo ? !is_readable(target->access) : !is_writable(target->access)) return abort_code::kNotMappable;
  const std::size_t size = data_type_size(target->type);
  const bool bit_ok = m.bits == size * 8 || (target->type == DataType::Boolean && m.bits == 1);
  return bit_ok ? 0 : abort_code::kNotMappable;
}

uint32_t SlaveNode::check_comm(const OdEntry& e, const uint8_t* d, std::size_t n, bool tpdo) const noexcept {
  if (e.addr.sub == 1 && n == 4) {
    const uint32_t next = get_u32(d);
    const uint32_t now = od_.get<uint32_t>(e.addr);
    if (next & cob::kPdoExtended) return abort_code::kValueRange;  // 29-bit PDOs are not supported
    if ((next & 0x1FFFFFFF) > 0x7FF) return abort_code::kValueRange;
    // The identifier of a valid PDO may not change (CiA 301 §7.5.2.35).
    if (!(now & cob::kPdoInvalid) && !(next & cob::kPdoInvalid) && (now & 0x7FF) != (next & 0x7FF)) {
      return abort_code::kValueRange;
    }
    if (!(next & cob::kPdoInvalid)) {  // enabling: the mapping must be consistent
      const unsigned number = e.addr.index - (tpdo ? 0x1800u : 0x1400u) + 1;
      const uint16_t map = tpdo ? tpdo_map_index(number) : rpdo_map_index(number);
      if (!od_.find({map, 0})) return abort_code::kParameterIncompatible;
    }
  } else if (e.addr.sub == 2 && n == 1) {
    if (!is_valid_transmission(d[0], tpdo)) return abort_code::kValueRange;
  }
  return 0;
}

void SlaveNode::install_checks() {
  for (unsigned n = 1; n <= kMaxPdos; ++n) {
    for (bool tpdo : {false, true}) {
      const uint16_t comm = tpdo ? tpdo_comm_index(n) : rpdo_comm_index(n);
      const uint16_t map = tpdo ? tpdo_map_index(n) : rpdo_map_index(n);
      if (od_.has_index(comm)) {
        od_.set_write_check(comm, [this, tpdo](const OdEntry& e, const uint8_t* d, std::size_t len) {
          return check_comm(e, d, len, tpdo);
        });
        od_.set_after_write(comm, [this](const OdEntry&) { reconfigure(); });
      }
      if (od_.has_index(map)) {
        od_.set_write_check(map, [this, tpdo](const OdEntry& e, const uint8_t* d, std::size_t len) {
          return check_mapping(e, d, len, tpdo);
        });
        od_.set_after_write(map, [this](const OdEntry&) { reconfigure(); });
      }
    }
  }
  auto reconf = [this](const OdEntry&) { reconfigure(); };
  for (uint16_t idx : {0x1005, 0x1014, 0x1015, 0x1016, 0x1017, 0x1019}) {
    if (od_.has_index(idx)) od_.set_after_write(idx, reconf);
  }
  if (od_.find({0x1019, 0})) {
    od_.set_write_check({0x1019, 0}, [](const OdEntry&, const uint8_t* d, std::size_t) -> uint32_t {
      return d[0] == 1 || d[0] > 240 ? abort_code::kValueRange : 0;
    });
  }
  if (od_.find({0x1005, 0})) {
    od_.set_write_check({0x1005, 0}, [](const OdEntry&, const uint8_t* d, std::size_t) -> uint32_t {
      return get_u32(d) & (cob::kSyncProducer | cob::kPdoExtended) ? abort_code::kValueRange : 0;
    });
  }
  if (od_.find({0x1003, 0})) {  // writing 0 clears the history; nothing else is allowed
    od_.set_write_check({0x1003, 0}, [](const OdEntry&, const uint8_t* d, std::size_t) -> uint32_t {
      return d[0] != 0 ? abort_code::kValueRange : 0;
    });
    od_.set_after_write({0x1003, 0}, [this](const OdEntry&) {
      for (uint8_t s = 1; s <= 8; ++s) od_.set<uint32_t>({0x1003, s}, 0);
    });
  }
  if (od_.has_index(0x1016)) {  // one consumer entry per node (CiA 301: 0x06040043)
    od_.set_write_check(0x1016, [this](const OdEntry& e, const uint8_t* d, std::size_t n) -> uint32_t {
      if (e.addr.sub == 0 || n != 4) return 0;
      const uint32_t v = get_u32(d);
      const uint8_t node = static_cast<uint8_t>(v >> 16);
      if ((v & 0xFFFF) == 0 || node == 0) return 0;
      for (uint8_t s = 1; od_.find({0x1016, s}); ++s) {
        if (s == e.addr.sub) continue;
        const uint32_t other = od_.get<uint32_t>({0x1016, s});
        if ((other & 0xFFFF) != 0 && static_cast<uint8_t>(other >> 16) == node) return abort_code::kParameterIncompatible;
      }
      return 0;
    });
  }
}

void SlaveNode::load_pdo(Pdo& p, uint16_t comm, uint16_t map, bool tpdo) noexcept {
  const Pdo before = p;
  p = Pdo{};
  if (!od_.find({comm, 1})) return;
  const uint32_t cob_entry = od_.get<uint32_t>({comm, 1});
  p.cob = cob_entry & 0x7FF;
  p.rtr_allowed = tpdo && !(cob_entry & cob::kPdoNoRtr);
  p.type = od_.get<uint8_t>({comm, 2});
  p.inhibit_100us = od_.get<uint16_t>({comm, 3});
  p.event_ms = od_.get<uint16_t>({comm, 5});
  p.sync_start = tpdo ? od_.get<uint8_t>({comm, 6}) : 0;
  p.count = std::min<uint8_t>(od_.get<uint8_t>({map, 0}), kMaxMapEntries);
  uint32_t bits = 0;
  const auto& entries = od_.entries();
  for (uint8_t s = 0; s < p.count; ++s) {
    const PdoMapEntry m = PdoMapEntry::decode(od_.get<uint32_t>({map, static_cast<uint8_t>(s + 1)}));
    p.map[s].bits = m.bits;
    if (!m.is_dummy()) {
      const OdEntry* e = od_.find({m.index, m.sub});
      p.map[s].entry = e ? static_cast<int32_t>(e - entries.data()) : -1;
    }
    bits += m.bits;
  }
  p.bytes = static_cast<uint8_t>((bits + 7) / 8);
  p.valid = !(cob_entry & cob::kPdoInvalid) && bits <= 64;
  // Keep timers of a PDO that did not change.
  if (before.valid && p.valid && before.cob == p.cob) {
    p.last_ns = before.last_ns;
    p.sync_seen = before.sync_seen;
    p.sync_started = before.sync_started;
  }
}

void SlaveNode::reconfigure() noexcept {
  for (unsigned n = 1; n <= kMaxPdos; ++n) {
    load_pdo(rpdo_[n - 1], rpdo_comm_index(n), rpdo_map_index(n), false);
    load_pdo(tpdo_[n - 1], tpdo_comm_index(n), tpdo_map_index(n), true);
  }
  sync_cob_ = od_.get<uint32_t>({0x1005, 0}) & 0x7FF;
  sync_overflow_ = od_.get<uint8_t>({0x1019, 0});
  const uint32_t emcy_entry = od_.get<uint32_t>({0x1014, 0});
  emcy_cob_ = (emcy_entry & cob::kPdoInvalid) ? 0 : (emcy_entry & 0x7FF);
  emcy_inhibit_100us_ = od_.get<uint16_t>({0x1015, 0});
  const uint16_t hb = od_.get<uint16_t>({0x1017, 0});
  if (hb != heartbeat_ms_) {
    heartbeat_ms_ = hb;
    next_heartbeat_ns_ = now_ns_ + static_cast<int64_t>(hb) * 1'000'000;
  }
  for (std::size_t i = 0; i < kMaxHeartbeatConsumers; ++i) {
    const ObjectAddress a{0x1016, static_cast<uint8_t>(i + 1)};
    const uint32_t v = od_.find(a) ? od_.get<uint32_t>(a) : 0;
    Consumer next{static_cast<uint8_t>((v >> 16) & 0x7F), static_cast<uint16_t>(v & 0xFFFF), -1, false};
    if (consumers_[i].node == next.node && consumers_[i].time_ms == next.time_ms) continue;
    consumers_[i] = next;
  }
}

// --- NMT ---

void SlaveNode::set_state(NmtState s, int64_t now_ns) noexcept {
  if (s == state_) return;
  const NmtState before = state_;
  state_ = s;
  if (s == NmtState::Operational && before != NmtState::Operational) {
    for (auto& p : tpdo_) {
      p.sync_seen = 0;
      p.sync_started = false;
      p.has_sent = false;
      p.last_ns = -1;
    }
    for (auto& p : rpdo_) {
      p.pending = false;
      p.last_ns = -1;
      p.deadline_missed = false;
    }
  }
  (void)now_ns;
  if (on_state_change) on_state_change(s);
}

void SlaveNode::boot(int64_t now_ns) noexcept {
  state_ = NmtState::Initialising;
  sdo_.reset();
  emcy_queued_ = 0;
  active_emcy_code_ = 0;
  guard_toggle_ = false;
  sync_length_reported_ = false;
  heartbeat_ms_ = 0;  // restart the heartbeat timer
  now_ns_ = now_ns;
  reconfigure();
  for (auto& c : consumers_) {
    c.last_ns = -1;
    c.lost = false;
  }
  send(can::Frame::make(cob::heartbeat(options_.node_id), {0x00}));  // boot-up
  next_heartbeat_ns_ = now_ns + static_cast<int64_t>(heartbeat_ms_) * 1'000'000;
  set_state(NmtState::PreOperational, now_ns);
}

void SlaveNode::start(int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  // A device without node-ID stays silent (Initialising) until LSS gives
  // it one.
  if (options_.node_id != lss::kUnconfigured) boot(now_ns);
}

void SlaveNode::change_node_id(uint8_t id) noexcept {
  const unsigned old = options_.node_id;
  if (id == old) return;
  // An identifier moves only where it still is the one derived from the
  // old node-ID (the application or a DCF may have set its own).
  auto move = [&](ObjectAddress a, uint32_t from, uint32_t to) {
    const OdEntry* e = od_.find(a);
    if (!e) return;
    const uint32_t v = od_.get<uint32_t>(a);
    if ((v & 0x7FF) == (from & 0x7FF)) od_.set<uint32_t>(a, (v & ~0x7FFu) | (to & 0x7FF));
    const uint32_t d = static_cast<uint32_t>(od_.default_bits(*e));
    if ((d & 0x7FF) == (from & 0x7FF)) od_.set_default_bits(a, (d & ~0x7FFu) | (to & 0x7FF));
  };
  move({0x1014, 0}, cob::emcy(old), cob::emcy(id));
  move({0x1200, 1}, cob::sdo_request(old), cob::sdo_request(id));
  move({0x1200, 2}, cob::sdo_response(old), cob::sdo_response(id));
  for (unsigned n = 1; n <= kMaxPdos; ++n) {
    if (const uint32_t from = default_pdo_cob(false, n, old)) move({rpdo_comm_index(n), 1}, from, default_pdo_cob(false, n, id));
    if (const uint32_t from = default_pdo_cob(true, n, old)) move({tpdo_comm_index(n), 1}, from, default_pdo_cob(true, n, id));
  }
  options_.node_id = id;
  sdo_.set_cob_ids(cob::sdo_request(id), cob::sdo_response(id));
}

void SlaveNode::handle_lss(const can::Frame& f, int64_t now_ns) noexcept {
  can::Frame reply;
  if (lss_.on_frame(f, reply)) send(reply);
  uint8_t id = 0;
  if (lss_.take_node_id_change(id)) {
    // Given a node-ID while it had none: reset communication under it.
    change_node_id(id);
    od_.restore_defaults(0x1000, 0x1FFF);
    boot(now_ns);
  }
}

void SlaveNode::handle_nmt(const can::Frame& f, int64_t now_ns) noexcept {
  if (f.len < 2) return;
  const uint8_t target = f.data[1];
  if (target != 0 && target != options_.node_id) return;
  switch (static_cast<NmtCommand>(f.data[0])) {
    case NmtCommand::Start:
      set_state(NmtState::Operational, now_ns);
      break;
    case NmtCommand::Stop:
      set_state(NmtState::Stopped, now_ns);
      break;
    case NmtCommand::EnterPreOperational:
      set_state(NmtState::PreOperational, now_ns);
      break;
    case NmtCommand::ResetNode:
      if (options_.lss) {
        lss_.on_nmt_reset();
        change_node_id(lss_.active_node_id());
      }
      if (on_reset_application) on_reset_application();
      od_.restore_defaults(0x2000, 0xFFFF);
      od_.restore_defaults(0x1000, 0x1FFF);
      boot(now_ns);
      break;
    case NmtCommand::ResetCommunication:
      if (options_.lss) {
        lss_.on_nmt_reset();
        change_node_id(lss_.active_node_id());
      }
      od_.restore_defaults(0x1000, 0x1FFF);
      boot(now_ns);
      break;
  }
}

// --- frames ---

void SlaveNode::on_frame(const can::Frame& f, int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  if (options_.lss && f.id == lss::kMasterCob && !f.is_error() && !f.is_extended()) {
    handle_lss(f, now_ns);
    return;
  }
  if (f.is_error() || f.is_extended() || state_ == NmtState::Initialising) return;
  const uint32_t id = f.id;
  if (id == cob::kNmt) {
    handle_nmt(f, now_ns);
    return;
  }
  if (f.is_remote()) {
    if (id == cob::heartbeat(options_.node_id)) {  // node guarding
      const uint8_t b = static_cast<uint8_t>((guard_toggle_ ? 0x80 : 0) | static_cast<uint8_t>(state_));
      guard_toggle_ = !guard_toggle_;
      send(can::Frame::make(id, {b}));
      return;
    }
    if (state_ != NmtState::Operational) return;
    for (auto& p : tpdo_) {
      if (p.valid && p.rtr_allowed && p.cob == id) {
        if (p.type == kTransmissionRtrEvent || !p.has_sent) pack(p);
        send_tpdo(p, now_ns);
      }
    }
    return;
  }
  if (state_ == NmtState::Stopped) {
    // Stopped: only NMT and error control.
    if (id >= cob::kHeartbeatBase + 1 && id <= cob::kHeartbeatBase + kMaxNodeId) goto heartbeat;
    return;
  }
  if (id == sdo_.request_cob()) {
    sdo_.on_frame(f, now_ns);
    return;
  }
  if (id == sync_cob_) {
    handle_sync(f, now_ns);
    return;
  }
  if (state_ == NmtState::Operational) {
    for (unsigned n = 0; n < kMaxPdos; ++n) {
      if (rpdo_[n].valid && rpdo_[n].cob == id) {
        handle_rpdo(rpdo_[n], n + 1, f, now_ns);
        return;
      }
    }
  }
  if (id >= cob::kHeartbeatBase + 1 && id <= cob::kHeartbeatBase + kMaxNodeId) goto heartbeat;
  return;
heartbeat:
  if (f.len >= 1) {
    const uint8_t node = static_cast<uint8_t>(id - cob::kHeartbeatBase);
    // A heartbeat that comes after the consumer time has run out does not
    // undo the timeout: the consumer trips first (frames a late pass of
    // the device's loop reads carry their reception times).
    check_consumers(now_ns);
    for (auto& c : consumers_) {
      if (c.node == node && c.time_ms != 0) {
        c.last_ns = now_ns;
        c.lost = false;
      }
    }
  }
}

void SlaveNode::handle_rpdo(Pdo& p, unsigned number, const can::Frame& f, int64_t now_ns) noexcept {
  if (f.len < p.bytes) {
    ++counters_.rpdo_length_errors;
    emcy(0x8210, kErrRegCommunication);
    return;
  }
  if (f.len > p.bytes && p.bytes > 0) {
    ++counters_.rpdo_length_errors;
    emcy(0x8220, kErrRegCommunication);
  }
  ++counters_.rpdos;
  std::memcpy(p.buffer.data(), f.data.data(), 8);
  p.last_ns = now_ns;
  p.deadline_missed = false;
  if (is_sync_transmission(p.type)) {
    p.pending = true;  // applied at the next SYNC
    return;
  }
  apply(p);
  if (on_rpdo) on_rpdo(number);
}

void SlaveNode::apply(const Pdo& p) noexcept {
  auto& entries = od_.entries();
  unsigned bit = 0;
  for (uint8_t i = 0; i < p.count; ++i) {
    const MapSlot& s = p.map[i];
    if (s.entry >= 0) {
      const OdEntry& e = entries[static_cast<std::size_t>(s.entry)];
      copy_bits(p.buffer.data(), bit, od_.data(e), 0, s.bits);
    }
    bit += s.bits;
  }
}

void SlaveNode::pack(Pdo& p) noexcept {
  auto& entries = od_.entries();
  p.buffer.fill(0);
  unsigned bit = 0;
  for (uint8_t i = 0; i < p.count; ++i) {
    const MapSlot& s = p.map[i];
    if (s.entry >= 0) {
      const OdEntry& e = entries[static_cast<std::size_t>(s.entry)];
      od_.refresh(e);
      copy_bits(od_.data(e), 0, p.buffer.data(), bit, s.bits);
    }
    bit += s.bits;
  }
}

bool SlaveNode::send_tpdo(Pdo& p, int64_t now_ns) noexcept {
  send(can::Frame::make(p.cob, p.buffer.data(), p.bytes));
  p.last_sent = p.buffer;
  p.has_sent = true;
  p.last_ns = now_ns;
  p.triggered = false;
  ++counters_.tpdos;
  return true;
}

void SlaveNode::handle_sync(const can::Frame& f, int64_t now_ns) noexcept {
  const bool has_counter = f.len >= 1;
  if ((sync_overflow_ > 0) != has_counter || f.len > 1) {
    if (!sync_length_reported_) {
      sync_length_reported_ = true;
      emcy(0x8240, kErrRegCommunication);
    }
  }
  const uint8_t counter = has_counter ? f.data[0] : 0;
  ++counters_.syncs;
  counters_.last_sync_counter = counter;
  if (state_ != NmtState::Operational) return;
  // 1. sample the inputs of the TPDOs due at this SYNC
  for (auto& p : tpdo_) {
    if (!p.valid) continue;
    if (p.type == kTransmissionRtrSync) {
      pack(p);
      continue;
    }
    if (!is_sync_transmission(p.type)) continue;
    if (p.type == kTransmissionSyncAcyclic) {
      pack(p);
      p.pending = !p.has_sent || p.triggered || p.buffer != p.last_sent;
      continue;
    }
    if (!p.sync_started) {
      // SYNC start value: the first transmission waits for that counter.
      if (sync_overflow_ > 0 && p.sync_start > 0 && counter != p.sync_start) continue;
      p.sync_started = true;
      p.sync_seen = static_cast<uint8_t>(p.type - 1);
    }
    if (++p.sync_seen >= p.type) {
      p.sync_seen = 0;
      pack(p);
      p.pending = true;
    }
  }
  // 2. apply the RPDOs received since the previous SYNC
  for (unsigned n = 0; n < kMaxPdos; ++n) {
    Pdo& p = rpdo_[n];
    if (p.valid && p.pending) {
      apply(p);
      p.pending = false;
    }
  }
  // 3. the application's cycle
  if (on_sync) on_sync(counter, now_ns);
  // 4. send the sampled inputs, after the device's processing time
  if (options_.sync_response_ns > 0) {
    sync_send_at_ns_ = now_ns + options_.sync_response_ns;
    return;
  }
  send_sync_tpdos(now_ns);
}

void SlaveNode::send_sync_tpdos(int64_t now_ns) noexcept {
  sync_send_at_ns_ = -1;
  for (auto& p : tpdo_) {
    if (p.valid && p.pending && p.type != kTransmissionRtrSync) {
      p.pending = false;
      send_tpdo(p, now_ns);
    }
  }
}

void SlaveNode::process(int64_t now_ns) noexcept {
  can::Frame f;
  while (transport_.receive(f)) on_frame(f, now_ns);
  poll(now_ns);
}

void SlaveNode::poll(int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  if (state_ == NmtState::Initialising) return;
  sdo_.poll(now_ns);
  // heartbeat producer
  if (heartbeat_ms_ > 0 && now_ns >= next_heartbeat_ns_) {
    send(can::Frame::make(cob::heartbeat(options_.node_id), {static_cast<uint8_t>(state_)}));
    next_heartbeat_ns_ += static_cast<int64_t>(heartbeat_ms_) * 1'000'000;
    if (next_heartbeat_ns_ <= now_ns) next_heartbeat_ns_ = now_ns + static_cast<int64_t>(heartbeat_ms_) * 1'000'000;
  }
  check_consumers(now_ns);
  // pending EMCY after the inhibit time
  if (emcy_queued_ > 0 &&
      (last_emcy_ns_ < 0 || now_ns - last_emcy_ns_ >= static_cast<int64_t>(emcy_inhibit_100us_) * 100'000)) {
    const Emcy e = emcy_queue_[0];
    std::move(emcy_queue_.begin() + 1, emcy_queue_.begin() + static_cast<std::ptrdiff_t>(emcy_queued_), emcy_queue_.begin());
    --emcy_queued_;
    send_emcy_now(e, now_ns);
  }
  if (state_ != NmtState::Operational) return;
  if (sync_send_at_ns_ >= 0 && now_ns >= sync_send_at_ns_) send_sync_tpdos(now_ns);
  // RPDO deadlines and event-driven TPDOs
  for (unsigned n = 0; n < kMaxPdos; ++n) {
    Pdo& p = rpdo_[n];
    if (p.valid && p.event_ms > 0 && p.last_ns >= 0 && !p.deadline_missed &&
        now_ns - p.last_ns > static_cast<int64_t>(p.event_ms) * 1'000'000) {
      p.deadline_missed = true;
      emcy(0x8250, kErrRegCommunication);
      if (on_rpdo_timeout) on_rpdo_timeout(n + 1);
    }
  }
  for (auto& p : tpdo_) {
    if (!p.valid || is_sync_transmission(p.type) || p.type == kTransmissionRtrSync || p.type == kTransmissionRtrEvent) {
      continue;
    }
    const bool inhibited = p.last_ns >= 0 && now_ns - p.last_ns < static_cast<int64_t>(p.inhibit_100us) * 100'000;
    const bool timer = p.event_ms > 0 && (p.last_ns < 0 || now_ns - p.last_ns >= static_cast<int64_t>(p.event_ms) * 1'000'000);
    if ((timer || p.triggered) && !inhibited) {
      pack(p);
      send_tpdo(p, now_ns);
    }
  }
}

// Heartbeat consumer (CiA 301 7.2.8.3.2.2): monitoring starts with the
// first heartbeat received; when none follows within the consumer time,
// EMCY 0x8130 and the application's reaction (on_heartbeat_lost), once,
// until a heartbeat is heard again.
void SlaveNode::check_consumers(int64_t now_ns) noexcept {
  for (auto& c : consumers_) {
    if (c.time_ms == 0 || c.last_ns < 0 || c.lost) continue;
    if (now_ns - c.last_ns > static_cast<int64_t>(c.time_ms) * 1'000'000) {
      c.lost = true;
      ++counters_.heartbeats_lost;
      emcy(0x8130, kErrRegCommunication);
      if (on_heartbeat_lost) on_heartbeat_lost(c.node);
    }
  }
}

void SlaveNode::trigger_tpdo(unsigned number) noexcept {
  if (number >= 1 && number <= kMaxPdos) tpdo_[number - 1].triggered = true;
}

// --- EMCY producer ---

void SlaveNode::send_emcy_now(const Emcy& e, int64_t now_ns) noexcept {
  if (emcy_cob_ == 0) return;
  can::Frame f = encode_emcy(options_.node_id, e);
  f.id = emcy_cob_;
  send(f);
  last_emcy_ns_ = now_ns;
  ++counters_.emcys;
}

void SlaveNode::emcy(uint16_t code, uint8_t error_register_bits, const uint8_t* vendor5) noexcept {
  // One error event, one EMCY (CiA 301 7.2.7.1: sent when an error
  // occurs): the same code again while it is still active (no error reset
  // since) is the same error reported by a second part of the device, e.g.
  // the heartbeat consumer and the application's fault reaction.
  if (code != 0 && code == active_emcy_code_) return;
  active_emcy_code_ = code;
  uint8_t reg = od_.get<uint8_t>({0x1001, 0});
  reg = static_cast<uint8_t>(reg | error_register_bits | (code != 0 ? kErrRegGeneric : 0));
  od_.set<uint8_t>({0x1001, 0}, reg);
  // history: newest in sub 1
  if (od_.find({0x1003, 1})) {
    uint8_t count = od_.get<uint8_t>({0x1003, 0});
    uint8_t last = 1;
    while (od_.find({0x1003, static_cast<uint8_t>(last + 1)})) ++last;
    for (uint8_t s = last; s > 1; --s) od_.set<uint32_t>({0x1003, s}, od_.get<uint32_t>({0x1003, static_cast<uint8_t>(s - 1)}));
    od_.set<uint32_t>({0x1003, 1}, code);
    if (count < last) od_.set<uint8_t>({0x1003, 0}, static_cast<uint8_t>(count + 1));
  }
  Emcy e;
  e.code = code;
  e.error_register = reg;
  if (vendor5) std::memcpy(e.vendor, vendor5, 5);
  if (state_ == NmtState::Stopped || state_ == NmtState::Initialising) return;
  const bool inhibited =
      last_emcy_ns_ >= 0 && now_ns_ - last_emcy_ns_ < static_cast<int64_t>(emcy_inhibit_100us_) * 100'000;
  if (inhibited || emcy_queued_ > 0) {
    if (emcy_queued_ < emcy_queue_.size()) emcy_queue_[emcy_queued_++] = e;
    return;
  }
  send_emcy_now(e, now_ns_);
}

void SlaveNode::clear_emcy(uint8_t error_register_bits) noexcept {
  active_emcy_code_ = 0;
  uint8_t reg = od_.get<uint8_t>({0x1001, 0});
  reg = static_cast<uint8_t>(reg & ~error_register_bits);
  if ((reg & ~kErrRegGeneric) == 0) reg = 0;
  od_.set<uint8_t>({0x1001, 0}, reg);
  Emcy e;
  e.code = 0;
  e.error_register = reg;
  if (state_ == NmtState::Stopped || state_ == NmtState::Initialising) return;
  if (emcy_queued_ > 0) {
    if (emcy_queued_ < emcy_queue_.size()) emcy_queue_[emcy_queued_++] = e;
    return;
  }
  send_emcy_now(e, now_ns_);
}

}  // namespace cnc::canopen
