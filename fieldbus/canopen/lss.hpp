// Layer Setting Services (CiA 305): giving a device its node-ID (and bit
// rate) over the bus when it has none, or changing it, without touching
// its switches. The master sends on 0x7E5, devices answer on 0x7E4. A
// device is addressed by its LSS address, the four values of its identity
// object 0x1018 (vendor, product, revision, serial): one at a time by
// "switch state selective", or, when the master does not know them, found
// bit by bit by fastscan among the devices that have no node-ID yet
// (node-ID 0xFF, "unconfigured").
//
// LssSlave is the device's side (protocol only, no allocation: it runs
// where the device's frames are handled); LssMaster is the commissioning
// side, blocking with time-outs, non-realtime.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "fieldbus/can/transport.hpp"

namespace cnc::canopen::lss {

inline constexpr uint32_t kMasterCob = 0x7E5;  // master -> devices
inline constexpr uint32_t kSlaveCob = 0x7E4;   // device -> master
inline constexpr uint8_t kUnconfigured = 0xFF;  // a device without node-ID

// Command specifiers (byte 0).
enum Cs : uint8_t {
  kSwitchGlobal = 0x04,
  kConfigureNodeId = 0x11,
  kConfigureBitTiming = 0x13,
  kActivateBitTiming = 0x15,
  kStoreConfiguration = 0x17,
  kSwitchSelectiveVendor = 0x40,
  kSwitchSelectiveProduct = 0x41,
  kSwitchSelectiveRevision = 0x42,
  kSwitchSelectiveSerial = 0x43,
  kSwitchSelectiveResponse = 0x44,
  kIdentifySlave = 0x4F,
  kFastscan = 0x51,
  kInquireVendor = 0x5A,
  kInquireProduct = 0x5B,
  kInquireRevision = 0x5C,
  kInquireSerial = 0x5D,
  kInquireNodeId = 0x5E,
};

// The LSS address: the identity object 0x1018:1-4.
struct Address {
  uint32_t vendor = 0, product = 0, revision = 0, serial = 0;
  uint32_t part(int i) const noexcept { return i == 0 ? vendor : i == 1 ? product : i == 2 ? revision : serial; }
  bool operator==(const Address&) const = default;
};
std::string to_string(const Address& a);  // "vendor 0x... product 0x... revision 0x... serial 0x..."

// Bit rate of a bit-timing index of table 0 (0 when the index is reserved
// or "automatic"), and the index of a bit rate (nullopt when the table has
// none).
uint32_t bitrate_of_index(uint8_t index) noexcept;
std::optional<uint8_t> index_of_bitrate(uint32_t bitrate) noexcept;

// The device's side. Feed it every frame on kMasterCob; it answers through
// `reply` (returns true when there is an answer to send).
class Slave {
 public:
  enum class Mode : uint8_t { Waiting, Configuration };

  Slave() = default;
  Slave(const Address& address, uint8_t node_id) noexcept : address_(address), active_(node_id), pending_(node_id), stored_(node_id) {}

  bool on_frame(const can::Frame& f, can::Frame& reply) noexcept;

  Mode mode() const noexcept { return mode_; }
  uint8_t active_node_id() const noexcept { return active_; }
  uint8_t pending_node_id() const noexcept { return pending_; }
  uint8_t stored_node_id() const noexcept { return stored_; }
  uint8_t pending_bit_timing() const noexcept { return bit_timing_; }
  uint64_t stores() const noexcept { return stores_; }

  // Set when the device must take a new node-ID now: an unconfigured
  // device that was given one and switched back to waiting (it then resets
  // its communication under that ID, CiA 305). Cleared by the call.
  bool take_node_id_change(uint8_t& new_id) noexcept;
  // An NMT reset (communication or node) makes the pending node-ID the
  // active one (a configured device changes its ID only then).
  void on_nmt_reset() noexcept { active_ = pending_; }

 private:
  Address address_;
  Mode mode_ = Mode::Waiting;
  uint8_t active_ = kUnconfigured, pending_ = kUnconfigured, stored_ = kUnconfigured;
  uint8_t bit_timing_ = 0;
  uint8_t selective_ = 0;   // how many of the four selective frames matched in order
  int fastscan_pos_ = 0;    // LSS-sub the device is at in a fastscan
  bool change_ = false;
  uint64_t stores_ = 0;
};

// The commissioning side over one transport (non-realtime, blocking).
// `timeout_ns` bounds each answer, in the transport's clock; a fastscan
// step waits `window_ns` whole (every matching device answers it).
class Master {
 public:
  explicit Master(can::Transport& bus, int64_t timeout_ns = 50'000'000, int64_t window_ns = 10'000'000)
      : bus_(bus), timeout_ns_(timeout_ns), window_ns_(window_ns) {}

  // Every device to waiting / configuration mode (no answer).
  bool switch_global(bool configuration);
  // The one device with this address to configuration mode; false when it
  // does not answer.
  bool switch_selective(const Address& a);
  // Node-ID of the device(s) in configuration mode (1-127, or 0xFF to
  // unconfigure). Throws std::runtime_error when it refuses or is silent.
  void configure_node_id(uint8_t id);
  void configure_bit_timing(uint32_t bitrate);
  // Stores the pending configuration in the device's non-volatile memory.
  void store();
  // Inquiries of the one device in configuration mode (nullopt: silent).
  std::optional<uint32_t> inquire(Cs what);
  std::optional<Address> inquire_address();
  // Whether any unconfigured device answers a fastscan.
  bool any_unconfigured();
  // Fastscan: finds the LSS address of one unconfigured device, which is
  // left in configuration mode; nullopt when none answers. Throws
  // std::runtime_error when a confirmation fails (devices appearing or
  // leaving during the scan, or answers later than the time-out).
  std::optional<Address> fastscan();

  uint64_t frames_sent() const noexcept { return sent_; }

 private:
  void send(std::initializer_list<uint8_t> bytes);
  void send_u32(uint8_t cs, uint32_t v, uint8_t b5 = 0, uint8_t b6 = 0, uint8_t b7 = 0);
  // The first answer with command specifier `cs` within the time-out.
  std::optional<can::Frame> wait_for(uint8_t cs);
  bool fastscan_step(uint32_t id, uint8_t bit_check, uint8_t sub, uint8_t next);
  std::optional<Address> fastscan_once();

  can::Transport& bus_;
  int64_t timeout_ns_, window_ns_;
  uint64_t sent_ = 0;
};

}  // namespace cnc::canopen::lss
