// Private to the CANopen master: its run-time records of nodes and PDOs and
// the byte helpers its parts share (master.cpp: construction, the acyclic
// thread and status; master_boot.cpp; master_sdo.cpp; master_cycle.cpp).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "fieldbus/canopen/master.hpp"

namespace cnc::canopen::master_detail {

inline std::string hexbytes(const std::vector<uint8_t>& v) {
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

inline std::string addr_text(ObjectAddress a) {
  char buf[16];
  return format(a, buf, sizeof buf);
}

inline std::vector<uint8_t> u32_bytes(uint32_t v, std::size_t n = 4) {
  std::vector<uint8_t> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<uint8_t>(v >> (8 * i));
  return out;
}

inline uint32_t as_u32(const std::vector<uint8_t>& v) {
  uint32_t x = 0;
  for (std::size_t i = 0; i < v.size() && i < 4; ++i) x |= static_cast<uint32_t>(v[i]) << (8 * i);
  return x;
}

}  // namespace cnc::canopen::master_detail

namespace cnc::canopen {

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
  uint64_t rx_sequence = 0;  // arrival order among the bus's TPDOs (Master::input_sequence)
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

}  // namespace cnc::canopen
