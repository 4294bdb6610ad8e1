// Step 1, the bus: a CANopen node scan over SDO. Every node-ID of the range
// is asked for its device type (0x1000) at once, each through its own SDO
// channel, so that a scan of 1-127 takes one SDO time-out rather than 127.
// The nodes that answer are then read: identity (0x1018), name (0x1008),
// firmware (0x100A), and for CiA 402 drives the supported modes (0x6502),
// statusword and error code (0x6041, 0x603F) and the factor group
// (0x608F, 0x6091, 0x6092) where the drive has them. Each node is matched
// with a description file (EDS/DCF) of a library folder by vendor and
// product code. Works on any can::Transport: SocketCAN ("socketcan:can0")
// or the simulators' in-process bus. Non-realtime.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "commission/state.hpp"
#include "fieldbus/can/transport.hpp"

namespace cnc::commission {

struct ScanOptions {
  int first = 1, last = 127;
  int64_t timeout_ns = 200'000'000;   // per SDO transfer
  int64_t settle_ns = 50'000'000;     // time left for second answers (two nodes on one ID)
  std::vector<int> expected;          // node-IDs that must answer (else a problem is reported)
  std::filesystem::path eds_dir;      // "" : no matching
  // After the SDO scan, one LSS fastscan request (lss_assign.hpp): devices
  // without node-ID are reported (0: not asked).
  int64_t lss_window_ns = 10'000'000;
};

struct ScanResult {
  std::vector<ScannedNode> nodes;     // those that answered, by node-ID
  std::vector<std::string> problems;  // bus-wide: expected nodes silent, unreadable description files
  bool ok() const noexcept;           // no problem anywhere
};

// A description file of the library: what identifies it.
struct EdsInfo {
  std::filesystem::path file;
  uint32_t vendor = 0, product = 0;
  std::optional<uint32_t> revision;
  std::string product_name;
};
// Reads every *.eds / *.dcf of `dir`; files that do not parse are named
// in `problems` ("file:line: what").
std::vector<EdsInfo> load_eds_library(const std::filesystem::path& dir, std::vector<std::string>& problems);
// The best match: vendor and product, the same revision preferred.
const EdsInfo* match_eds(const std::vector<EdsInfo>& lib, uint32_t vendor, uint32_t product, uint32_t revision);

ScanResult scan_canopen(can::Transport& bus, const ScanOptions& options);

// The EtherCAT segment on `interface` ("raw:eth0"; the simulators'
// "sim:<segment>"): every slave's SII identity, name, CoE and DC, matched
// with an ESI file of `esi_dir` by vendor and product code ("" : no
// matching). A segment that does not answer is a bus-wide problem.
struct EthercatScanResult {
  std::vector<ScannedSlave> slaves;
  std::vector<std::string> problems;
  bool ok() const noexcept;
};
EthercatScanResult scan_ethercat(const std::string& interface, const std::filesystem::path& esi_dir);
std::string describe(const ScannedSlave& s);

// One line per node and problem, for people ("node 1: cnc simulated servo
// drive, vendor 0x00000CC1 product 0x00000402 ... CiA 402 (CSP CSV CST HM), EDS servo.eds").
std::string describe(const ScannedNode& n);

}  // namespace cnc::commission
