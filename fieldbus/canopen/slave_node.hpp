// A CANopen device (slave side, CiA 301) on top of an object dictionary:
// NMT slave with boot-up, SDO server, RPDO/TPDO with synchronous and
// event-driven transmission, SYNC consumer with counter, heartbeat producer
// and consumer, EMCY producer with error register and history, node-guarding
// answers. Simulated devices (the CiA-402 drive simulator, test nodes) are
// built on it. After construction nothing allocates: on_frame() and poll()
// may run in the servo thread of an in-process simulation.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>

#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/emcy.hpp"
#include "fieldbus/canopen/lss.hpp"
#include "fieldbus/canopen/object_dictionary.hpp"
#include "fieldbus/canopen/pdo.hpp"
#include "fieldbus/canopen/sdo_server.hpp"

namespace cnc::canopen {

struct SlaveIdentity {
  uint32_t device_type = 0;
  uint32_t vendor_id = 0;
  uint32_t product_code = 0;
  uint32_t revision = 0;
  uint32_t serial = 0;
  std::string device_name = "cnc simulated device";
};

struct SlaveOptions {
  // 1-127, or lss::kUnconfigured (0xFF, only with `lss`): the device then
  // stays silent until an LSS master gives it a node-ID.
  uint8_t node_id = 1;
  // The device answers LSS (CiA 305) on 0x7E5/0x7E4, addressed by its
  // identity (vendor, product, revision, serial).
  bool lss = false;
  uint8_t rpdo_count = 4;
  uint8_t tpdo_count = 4;
  SlaveIdentity identity;
  uint16_t heartbeat_ms = 0;   // default of 0x1017
  // Time from a SYNC's reception until the synchronous TPDOs sampled at
  // it are queued (a device's processing time; 0: at once).
  int64_t sync_response_ns = 0;
  // PDO mappings (0x1600-0x17FF, 0x1A00-0x1BFF) take SDO writes only in
  // Pre-operational, as many drives do (CiA 301 leaves it to the device):
  // abort 0x08000022 in any other state.
  bool pdo_mapping_needs_preop = false;
};

class SlaveNode {
 public:
  static constexpr std::size_t kMaxPdos = 16;
  static constexpr std::size_t kMaxMapEntries = 8;
  static constexpr std::size_t kMaxHeartbeatConsumers = 8;

  // Adds the communication objects (0x1000-0x1A0F) that `od` does not have
  // yet; objects already defined (by the application or an EDS) are kept.
  static void add_communication_objects(ObjectDictionary& od, const SlaveOptions& options);

  SlaveNode(ObjectDictionary& od, can::Transport& transport, SlaveOptions options);
  SlaveNode(const SlaveNode&) = delete;
  SlaveNode& operator=(const SlaveNode&) = delete;

  // Power-on: initialisation, boot-up message, pre-operational.
  void start(int64_t now_ns) noexcept;
  void on_frame(const can::Frame& f, int64_t now_ns) noexcept;
  // Timers: heartbeat production and consumption, event timers, RPDO
  // deadlines, EMCY inhibit, paced SDO block uploads.
  void poll(int64_t now_ns) noexcept;
  // Receives everything waiting on the transport, then polls.
  void process(int64_t now_ns) noexcept;

  uint8_t node_id() const noexcept { return options_.node_id; }
  // The LSS side of the device (nullptr when it does not support LSS).
  const lss::Slave* lss() const noexcept { return options_.lss ? &lss_ : nullptr; }
  NmtState state() const noexcept { return state_; }
  ObjectDictionary& od() noexcept { return od_; }
  SdoServer& sdo_server() noexcept { return sdo_; }

  // EMCY producer: sets the error register bits, records the code in the
  // history (0x1003) and sends it (respecting the inhibit time 0x1015).
  void emcy(uint16_t code, uint8_t error_register_bits, const uint8_t* vendor5 = nullptr) noexcept;
  // Error reset: clears the register bits and sends EMCY 0x0000.
  void clear_emcy(uint8_t error_register_bits = 0xFF) noexcept;
  // Requests an event-driven TPDO now (subject to its inhibit time).
  void trigger_tpdo(unsigned number) noexcept;
  // Fault injection: a muted node sends nothing (a dead or unplugged device).
  void set_muted(bool muted) noexcept { muted_ = muted; }
  bool is_muted() const noexcept { return muted_; }

  // Application hooks (set before start(); called from on_frame/poll).
  // At each SYNC in Operational: TPDO values are sampled, RPDOs received
  // since the previous SYNC are applied, then on_sync runs, then the sampled
  // TPDOs go out: inputs are those at the SYNC, outputs take effect at it.
  std::function<void(uint8_t counter, int64_t now_ns)> on_sync;
  std::function<void(NmtState)> on_state_change;
  std::function<void(unsigned rpdo_number)> on_rpdo;          // event-driven RPDO applied
  std::function<void(unsigned rpdo_number)> on_rpdo_timeout;  // deadline 0x1400:5 missed
  std::function<void(uint8_t node)> on_heartbeat_lost;        // 0x1016 consumer
  std::function<void()> on_reset_application;

  struct Counters {
    uint64_t syncs = 0;
    uint64_t rpdos = 0;
    uint64_t tpdos = 0;
    uint64_t emcys = 0;
    uint64_t rpdo_length_errors = 0;
    uint64_t heartbeats_lost = 0;
    uint8_t last_sync_counter = 0;
  };
  const Counters& counters() const noexcept { return counters_; }

 private:
  struct MapSlot {
    int32_t entry = -1;  // index into od.entries(); -1 = dummy (gap)
    uint8_t bits = 0;
  };
  struct Pdo {
    bool valid = false;
    bool rtr_allowed = false;
    uint32_t cob = 0;
    uint8_t type = 255;
    uint16_t inhibit_100us = 0;
    uint16_t event_ms = 0;
    uint8_t sync_start = 0;
    uint8_t count = 0;
    uint8_t bytes = 0;
    std::array<MapSlot, kMaxMapEntries> map{};
    // runtime
    std::array<uint8_t, 8> buffer{};
    std::array<uint8_t, 8> last_sent{};
    bool has_sent = false;
    bool pending = false;        // RPDO: data waiting for SYNC; TPDO: sampled, to send
    bool triggered = false;      // TPDO event requested
    uint8_t sync_seen = 0;       // TPDO: SYNCs since the last transmission
    bool sync_started = false;
    int64_t last_ns = -1;        // RPDO: last reception; TPDO: last transmission
    bool deadline_missed = false;
  };
  struct Consumer {
    uint8_t node = 0;
    uint16_t time_ms = 0;
    int64_t last_ns = -1;
    bool lost = false;
  };

  void send(const can::Frame& f) noexcept;
  void set_state(NmtState s, int64_t now_ns) noexcept;
  void boot(int64_t now_ns) noexcept;
  void reconfigure() noexcept;
  void load_pdo(Pdo& p, uint16_t comm, uint16_t map, bool tpdo) noexcept;
  void install_checks();
  uint32_t check_mapping(const OdEntry& e, const uint8_t* d, std::size_t n, bool tpdo) const noexcept;
  uint32_t check_comm(const OdEntry& e, const uint8_t* d, std::size_t n, bool tpdo) const noexcept;
  void handle_nmt(const can::Frame& f, int64_t now_ns) noexcept;
  void handle_lss(const can::Frame& f, int64_t now_ns) noexcept;
  // Moves every identifier that derives from the node-ID (EMCY, SDO, the
  // predefined PDOs), in value and default, to `id`.
  void change_node_id(uint8_t id) noexcept;
  void handle_sync(const can::Frame& f, int64_t now_ns) noexcept;
  void handle_rpdo(Pdo& p, unsigned number, const can::Frame& f, int64_t now_ns) noexcept;
  void pack(Pdo& p) noexcept;
  void apply(const Pdo& p) noexcept;
  bool send_tpdo(Pdo& p, int64_t now_ns) noexcept;
  void send_sync_tpdos(int64_t now_ns) noexcept;
  void send_emcy_now(const Emcy& e, int64_t now_ns) noexcept;
  void check_consumers(int64_t now_ns) noexcept;

  ObjectDictionary& od_;
  can::Transport& transport_;
  SlaveOptions options_;
  SdoServer sdo_;
  lss::Slave lss_;
  NmtState state_ = NmtState::Initialising;
  bool muted_ = false;
  int64_t now_ns_ = 0;
  int64_t sync_send_at_ns_ = -1;  // the synchronous TPDOs of the last SYNC go then (sync_response_ns)

  std::array<Pdo, kMaxPdos> rpdo_{};
  std::array<Pdo, kMaxPdos> tpdo_{};
  std::array<Consumer, kMaxHeartbeatConsumers> consumers_{};
  uint32_t sync_cob_ = cob::kSync;
  uint8_t sync_overflow_ = 0;
  bool sync_length_reported_ = false;
  uint16_t heartbeat_ms_ = 0;
  int64_t next_heartbeat_ns_ = 0;
  uint32_t emcy_cob_ = 0;
  uint16_t emcy_inhibit_100us_ = 0;
  uint16_t active_emcy_code_ = 0;  // last EMCY code sent, until clear_emcy
  int64_t last_emcy_ns_ = -1;
  std::array<Emcy, 8> emcy_queue_{};
  std::size_t emcy_queued_ = 0;
  bool guard_toggle_ = false;
  Counters counters_;
};

}  // namespace cnc::canopen
