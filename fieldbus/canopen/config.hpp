// What a machine builder configures for one CANopen bus and its nodes: the
// interface, SYNC, heartbeats, timeouts, and per node the expected identity,
// the PDO mapping (INI keys, or the ParameterValues of a DCF / defaults of
// an EDS) and any further SDO writes. Loaded from INI sections (see
// docs/canopen.md); validated before anything is sent, including the bus
// load against its budget. Non-realtime.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fieldbus/can/bus_load.hpp"
#include "fieldbus/canopen/eds.hpp"
#include "fieldbus/canopen/pdo.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::canopen {

// How a mapped value shows as a HAL pin (export_pins).
enum class ValueKind : uint8_t { Unsigned, Signed, Real, Bit };

// One object written at boot, checked by reading it back.
struct SdoWrite {
  ObjectAddress addr;
  std::vector<uint8_t> data;
  std::string origin;          // "file:line" or "DCF file:line" for messages
  bool verify = true;
};

struct NodeConfig {
  uint8_t id = 0;
  std::string name;            // for messages; "node <id>" when empty
  bool mandatory = true;
  std::optional<uint32_t> device_type, vendor_id, product_code, revision, serial;
  uint16_t heartbeat_ms = 100;             // written to 0x1017; 0: no heartbeat
  uint16_t heartbeat_timeout_ms = 0;       // master's consumer time; 0: 2 x heartbeat_ms + 20
  uint16_t master_heartbeat_timeout_ms = 0;  // the node's 0x1016:1 watching the master; 0: not written
  std::vector<PdoConfig> rpdos, tpdos;
  std::vector<std::vector<ValueKind>> rpdo_kinds, tpdo_kinds;  // parallel to the mapping entries
  bool disable_unused_pdos = true;         // PDO 1..4 not configured are switched off
  // TX_QUEUE: the node's controller sends its pending frames by priority
  // (several transmit mailboxes, the default) or in the order queued (one
  // FIFO: the bus-load plan then lets the node's own event PDOs and
  // heartbeat delay its synchronous TPDOs).
  bool tx_fifo = false;
  // SYNC_RESPONSE_US: how long after a SYNC the device queues its
  // synchronous TPDOs (its datasheet's processing time); the plan adds it.
  uint32_t sync_response_us = 0;
  std::vector<SdoWrite> sdo;               // further writes, in order
  std::shared_ptr<const DeviceDescription> eds;
  bool export_pins = false;
  std::string origin;                      // "[CANOPEN_NODE_3]" for messages

  std::string label() const;               // "node 3 (x-axis)"
  uint16_t consumer_timeout_ms() const noexcept {
    return heartbeat_timeout_ms ? heartbeat_timeout_ms : static_cast<uint16_t>(heartbeat_ms ? heartbeat_ms * 2 + 20 : 0);
  }
};

struct BusConfig {
  std::string name = "canopen.0";          // HAL prefix and message source
  std::string interface;                   // socketcan:can0, virtual:sim
  uint32_t bitrate = 1'000'000;
  uint8_t master_node_id = 127;
  uint16_t master_heartbeat_ms = 100;      // 0: the master sends no heartbeat
  uint32_t sync_cob_id = cob::kSync;
  uint8_t sync_overflow = 0;               // 0x1019: 0 = SYNC without counter, 2..240
  // SYNC period: the period of the HAL thread that runs <name>.write (the
  // component checks it once addf placed the function, in on_ready).
  int64_t cycle_ns = 1'000'000;
  std::string cycle_key;                   // "file:line: [CANOPEN]SYNC_PERIOD_US" when the INI gives the period
  int64_t sdo_timeout_ns = 500'000'000;
  int64_t boot_timeout_ns = 5'000'000'000;
  bool reset_nodes = true;                 // NMT reset communication before the boot
  bool start_all = false;                  // one broadcast NMT start instead of one per node
  double max_bus_load = 0.8;               // budget of the average load (worst-case stuffing)
  double max_cycle_load = 0.9;             // budget of the busiest cycle slot, share of the SYNC period
  uint32_t plan_emcy_frames = 1;           // EMCY frames the plan allows in any cycle
  uint32_t plan_sdo_frames = 2;            // SDO frames the plan allows in any cycle
  bool load_override = false;              // a plan above a budget only warns (LOAD_OVERRIDE = YES)
  uint32_t pdo_miss_limit = 3;             // consecutive missed TPDOs that fault a node; 0: never
  std::vector<NodeConfig> nodes;
  std::string origin;                      // "[CANOPEN]" of file:line

  // Every frame the configuration lets onto the bus, at its highest rate,
  // for the load calculator (can/bus_load.hpp): SYNC, RPDOs and synchronous
  // TPDOs (in their slot when SYNC_COUNTER_OVERFLOW and SYNC_START fix it),
  // event-driven TPDOs at their inhibit time or declared interval,
  // heartbeats, the EMCY and SDO allowances.
  std::vector<can::ScheduledFrame> schedule() const;
  can::BusLoad load() const;
  // What exceeds a budget ("" when the plan fits): the average load above
  // MAX_BUS_LOAD or the busiest slot above MAX_CYCLE_LOAD, with figures.
  std::string load_problem() const;
  // Throws std::runtime_error naming the node and what is wrong (duplicate
  // IDs, PDO longer than 8 bytes, a mapping the EDS refuses, COB-ID
  // collisions, an event-driven TPDO without a bound on its rate, load
  // above a budget unless load_override, ...).
  void validate() const;
  const NodeConfig* node(uint8_t id) const noexcept;
};

// Reads bus `section` ([CANOPEN] by default) and its node sections
// ([<section>_NODE_<id>]); `name` becomes the HAL prefix. The SYNC period
// is SYNC_PERIOD_US when given, else `thread_period_ns` (the period of the
// thread expected to run the bus). Throws ConfigError (file:line: key).
BusConfig load_bus_config(const ini::IniFile& ini, const std::string& section, const std::string& name,
                          int64_t thread_period_ns = 1'000'000);

// "0x6040:0:u16" / "0x60400010" / "pad8" into a mapping entry and its pin
// kind; the type may be omitted when `eds` knows the object. Empty optional
// with `error` set when the text is not valid.
struct ParsedMapEntry {
  PdoMapEntry entry;
  ValueKind kind = ValueKind::Unsigned;
};
std::optional<ParsedMapEntry> parse_map_entry(const std::string& text, const DeviceDescription* eds, std::string& error);
// "0x6060:0:s8 8" / "0x2000:1:u32 0x10" / "0x1008:0:str text" into a write.
std::optional<SdoWrite> parse_sdo_write(const std::string& text, const DeviceDescription* eds, std::string& error);

}  // namespace cnc::canopen
