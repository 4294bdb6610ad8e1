#include "sim/cia402/canopen_drive.hpp"

#include "fieldbus/canopen/pdo.hpp"

namespace cnc::cia402::sim {

CanopenDrive::CanopenDrive(const SimNodeConfig& config, can::Transport& transport)
    : config_(config), model_(config.drive, od_) {
  canopen::SlaveOptions o;
  o.node_id = config_.lss_unconfigured ? canopen::lss::kUnconfigured : config_.node_id;
  o.lss = config_.lss || config_.lss_unconfigured;
  o.identity = config_.identity;
  o.heartbeat_ms = config_.heartbeat_ms;
  o.sync_response_ns = config_.sync_response_ns;
  o.rpdo_count = 8;
  o.tpdo_count = 8;
  o.pdo_mapping_needs_preop = config_.pdo_mapping_needs_preop;
  canopen::SlaveNode::add_communication_objects(od_, o);
  node_ = std::make_unique<canopen::SlaveNode>(od_, transport, o);
  node_->on_sync = [this](uint8_t, int64_t now) { model_.on_sync(now); };
  node_->on_heartbeat_lost = [this](uint8_t) { model_.connection_lost(err::kHeartbeat); };
  node_->on_rpdo_timeout = [this](unsigned) { model_.connection_lost(err::kRpdoTimeout); };
  node_->on_state_change = [this](canopen::NmtState s) {
    if (s != canopen::NmtState::Operational && model_.state() == State::OperationEnabled) {
      model_.connection_lost(0x8100);  // stopped or pre-operational while enabled: no more set-points
    }
  };
  node_->on_reset_application = [this] { model_.power_on(now_ns_); };
  model_.on_emcy = [this](uint16_t code, uint8_t reg) {
    if (code == 0) node_->clear_emcy();
    else node_->emcy(code, reg);
  };
}

void CanopenDrive::start(int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  model_.power_on(now_ns);
  node_->start(now_ns);
}

void CanopenDrive::set_dead(bool dead) noexcept {
  dead_ = dead;
  node_->set_muted(dead);
}

void CanopenDrive::on_frame(const can::Frame& f, int64_t now_ns) noexcept {
  if (dead_) return;
  now_ns_ = now_ns;
  if (drop_ > 0 && !f.is_error() && !f.is_extended()) {
    const uint32_t id = f.id;
    const uint8_t n = node_->node_id();
    const bool rpdo = id == canopen::cob::rpdo(1, n) || id == canopen::cob::rpdo(2, n) ||
                      id == canopen::cob::rpdo(3, n) || id == canopen::cob::rpdo(4, n);
    if (id == canopen::cob::kSync || rpdo) {
      --drop_;
      ++dropped_;
      return;
    }
  }
  node_->on_frame(f, now_ns);
}

void CanopenDrive::poll(int64_t now_ns) noexcept {
  if (dead_) return;
  now_ns_ = now_ns;
  model_.advance_to(now_ns);
  trigger_changed_tpdos();
  node_->poll(now_ns);
}

void CanopenDrive::trigger_changed_tpdos() noexcept {
  if (node_->state() != canopen::NmtState::Operational) return;
  for (unsigned n = 0; n < last_event_.size(); ++n) {
    const uint8_t type = od_.get<uint8_t>({static_cast<uint16_t>(0x1800 + n), 2});
    const uint32_t cob = od_.get<uint32_t>({static_cast<uint16_t>(0x1800 + n), 1});
    if (type < 254 || (cob & canopen::cob::kPdoInvalid)) continue;
    std::array<uint8_t, 8> now{};
    const uint8_t count = od_.get<uint8_t>({static_cast<uint16_t>(0x1A00 + n), 0});
    unsigned bit = 0;
    for (uint8_t k = 1; k <= count && k <= 8; ++k) {
      const uint32_t e = od_.get<uint32_t>({static_cast<uint16_t>(0x1A00 + n), k});
      const unsigned bits = e & 0xFF;
      if (const canopen::OdEntry* entry = od_.find({static_cast<uint16_t>(e >> 16), static_cast<uint8_t>(e >> 8)})) {
        if (bit + bits <= 64) canopen::copy_bits(od_.data(*entry), 0, now.data(), bit, bits);
      }
      bit += bits;
    }
    if (now != last_event_[n]) {
      last_event_[n] = now;
      node_->trigger_tpdo(n + 1);
    }
  }
}

}  // namespace cnc::cia402::sim
