// A simulated CiA 402 drive as an EtherCAT CoE slave: the transport-
// independent drive model (cia402/sim DriveModel) on its object dictionary,
// plus the CoE communication objects (0x1000, 0x1018, 0x1C00, 0x1C12/13,
// 0x1600.., 0x1A00.., 0x1C32/33), an SDO server over the mailbox (expedited,
// normal and segmented, aborts), emergencies, PDO mapping checked at
// PREOP -> SAFEOP, and the SII image that describes it. Outputs applied in
// OP run the drive's cycle (SM-synchronous); the process-data watchdog is a
// lost connection for the drive.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sim/cia402/drive_model.hpp"
#include "fieldbus/canopen/object_dictionary.hpp"
#include "sim/ethercat/esc.hpp"

namespace cnc::ethercat::sim {

struct CoeDriveConfig {
  std::string name = "drive";
  uint32_t vendor_id = 0x00000CC1, product_code = 0x00000402, revision = 0x00010000, serial = 1;
  cia402::sim::DriveSimConfig drive;
  double drift_ppm = 0;
  int64_t clock_at_power_on_ns = 0;
  uint8_t sm2_control = 0x64;  // SII SyncManager category, outputs (0x24: a description without the watchdog bit)
  uint8_t pdo_mappings = 4;    // RxPDO mappings 0x1600-, TxPDO mappings 0x1A00- (each; at most 32)
};

class CoeDrive final : public SlaveApplication {
 public:
  CoeDrive(const CoeDriveConfig& config, int64_t now_ns);
  CoeDrive(const CoeDrive&) = delete;
  CoeDrive& operator=(const CoeDrive&) = delete;

  // The ESC configuration (SII image, mailbox layout, clock) for this drive.
  EscConfig esc_config() const;

  cia402::sim::DriveModel& model() noexcept { return model_; }
  canopen::ObjectDictionary& od() noexcept { return od_; }
  AlState state() const noexcept { return state_; }
  const CoeDriveConfig& config() const noexcept { return cfg_; }

  // Fault injection: every SDO access to `index` is aborted with `code`
  // (0 clears).
  void abort_sdo(uint16_t index, uint32_t code) noexcept { abort_index_ = index, abort_code_ = code; }
  uint64_t sdo_requests() const noexcept { return sdo_requests_; }

  // SlaveApplication
  // The CoE service of the last SDO reply posted (tests: aborts are
  // service 2, SDO request, as IEC 61158-6-12 defines them).
  CoeService last_reply_service() const noexcept { return last_reply_service_; }
  void on_mailbox(const uint8_t* data, std::size_t size, Esc& esc, int64_t now_ns) override;
  uint16_t check_transition(AlState from, AlState to, const Esc& esc) override;
  void on_state(AlState from, AlState to, int64_t now_ns) override;
  void on_outputs(const uint8_t* data, std::size_t size, int64_t now_ns) noexcept override;
  void fill_inputs(uint8_t* data, std::size_t size) noexcept override;
  void on_watchdog(int64_t now_ns) noexcept override;
  void poll(int64_t now_ns) noexcept override;
  void on_sync0(int64_t t_ns) noexcept override;

  // DC-synchronous operation (0x1C32:01 = 2): SYNC0 pulses that found no
  // new outputs (the drive held its set-point: 0x1C32:0B), and outputs
  // overwritten before a pulse used them.
  uint64_t sync_events_missed() const noexcept { return sync_missed_; }
  uint64_t outputs_overwritten() const noexcept { return outputs_overwritten_; }

 private:
  struct MapItem {
    uint32_t od_offset = 0;
    uint16_t bit = 0;
    uint8_t bits = 0;
    bool dummy = false;
  };
  struct Comm {
    explicit Comm(canopen::ObjectDictionary& od, const CoeDriveConfig& c);
  };

  void sdo(const uint8_t* coe, std::size_t n, Esc& esc);
  void sdo_info(const uint8_t* d, std::size_t n, Esc& esc);
  // Complete access: every sub-index of `index` from `sub` (0 or 1) on,
  // sub-index 0 as 16 bits; abort code or 0.
  uint32_t pack_complete(uint16_t index, uint8_t sub, std::vector<uint8_t>& out);
  uint32_t unpack_complete(uint16_t index, uint8_t sub, const std::vector<uint8_t>& in);
  uint32_t finish_download(const uint8_t* data, std::size_t n);
  void info_reply(Esc& esc, uint8_t opcode, const std::vector<uint8_t>& payload);
  void reply(Esc& esc, const uint8_t* sdo, std::size_t n, CoeService service = CoeService::SdoResponse);
  CoeService last_reply_service_ = CoeService::SdoResponse;
  void abort(Esc& esc, uint16_t index, uint8_t sub, uint32_t code);
  uint32_t build_map(uint16_t assign, std::vector<MapItem>& out, unsigned& bits) const;
  uint32_t check_mapping_write(const canopen::OdEntry& e, const uint8_t* d, std::size_t n) const;
  void emergency(uint16_t code, uint8_t reg);

  CoeDriveConfig cfg_;
  canopen::ObjectDictionary od_;
  Comm comm_;
  cia402::sim::DriveModel model_;
  AlState state_ = AlState::Init;
  Esc* esc_ = nullptr;
  std::vector<MapItem> rx_map_, tx_map_;
  unsigned rx_bits_ = 0, tx_bits_ = 0;
  // SDO transfer in progress
  enum class Transfer : uint8_t { None, Upload, Download } transfer_ = Transfer::None;
  uint16_t t_index_ = 0;
  uint8_t t_sub_ = 0, toggle_ = 0;
  bool t_complete_ = false;
  std::vector<uint8_t> buffer_;
  std::size_t t_size_ = 0, t_pos_ = 0;
  uint16_t abort_index_ = 0;
  uint32_t abort_code_ = 0;
  uint64_t sdo_requests_ = 0;
  uint8_t counter_ = 0;
  int64_t now_ns_ = 0;
  bool fresh_outputs_ = false;
  uint64_t sync_missed_ = 0, outputs_overwritten_ = 0;
};

// The default PDO layout of the simulated drive (also its SII defaults).
std::vector<std::pair<uint32_t, const char*>> default_rx_mapping();
std::vector<std::pair<uint32_t, const char*>> default_tx_mapping();

}  // namespace cnc::ethercat::sim
