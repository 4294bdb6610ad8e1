// A simulated CiA 402 drive as a CANopen node: the drive model on the
// slave-side stack (fieldbus/canopen SlaveNode: NMT, SDO server, PDOs,
// SYNC, heartbeat producer and consumer, EMCY). SYNC runs the drive's
// cycle; a lost master heartbeat, an RPDO deadline or leaving Operational
// while enabled reach the drive as a lost connection (0x6007); event-driven
// TPDOs go out when their mapped values change. Frames the drive should
// lose (fault injection) are dropped before the stack sees them.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "sim/cia402/drive_model.hpp"
#include "fieldbus/canopen/slave_node.hpp"

namespace cnc::cia402::sim {

struct SimNodeConfig {
  uint8_t node_id = 1;
  canopen::SlaveIdentity identity{0x00020192, 0x00000CC1, 0x00000402, 0x00010000, 0, "cnc simulated servo drive"};
  uint16_t heartbeat_ms = 0;  // default of 0x1017 (the master configures it)
  int64_t sync_response_ns = 0;  // SYNC_RESPONSE_US: SYNC to the synchronous TPDOs queued
  // LSS (CiA 305): the drive answers it (LSS); with lss_unconfigured it
  // starts without node-ID (silent until an LSS master gives it one),
  // node_id then only names it.
  bool lss = true;
  bool lss_unconfigured = false;
  // As many real drives: PDO mappings are written in Pre-operational only
  // (SDO abort 0x08000022 in Operational or Stopped).
  bool pdo_mapping_needs_preop = true;
  DriveSimConfig drive;
};

class CanopenDrive {
 public:
  CanopenDrive(const SimNodeConfig& config, can::Transport& transport);
  CanopenDrive(const CanopenDrive&) = delete;
  CanopenDrive& operator=(const CanopenDrive&) = delete;

  // The node-ID it has on the bus now (0xFF while LSS-unconfigured).
  uint8_t node_id() const noexcept { return node_->node_id(); }
  const std::string& name() const noexcept { return config_.drive.name; }
  // Power on: the drive initialises, the node sends its boot-up message.
  void start(int64_t now_ns) noexcept;
  void on_frame(const can::Frame& f, int64_t now_ns) noexcept;
  void poll(int64_t now_ns) noexcept;

  DriveModel& model() noexcept { return model_; }
  const DriveModel& model() const noexcept { return model_; }
  canopen::SlaveNode& node() noexcept { return *node_; }
  canopen::ObjectDictionary& od() noexcept { return od_; }

  // Fault injection: the next `n` SYNC and RPDO frames never reach the drive.
  void drop_frames(unsigned n) noexcept { drop_ = n; }
  unsigned frames_dropped() const noexcept { return dropped_; }
  // A dead drive: it neither answers nor sends anything (power cut).
  void set_dead(bool dead) noexcept;

 private:
  void trigger_changed_tpdos() noexcept;

  SimNodeConfig config_;
  canopen::ObjectDictionary od_;
  DriveModel model_;
  std::unique_ptr<canopen::SlaveNode> node_;
  int64_t now_ns_ = 0;
  unsigned drop_ = 0, dropped_ = 0;
  bool dead_ = false;
  std::array<std::array<uint8_t, 8>, 4> last_event_{};
};

}  // namespace cnc::cia402::sim
