// Step 9, writing the configuration: the INI and HAL files of the machine
// generated from the commissioning state (the CANopen bus, the CiA 402
// drives with their scaling and direction, joints and axes, the I/O
// controller), shown as a difference against the files there, then written
// atomically with the old ones kept as <file>.bak, and checked by
// `cncd --check --strict`. A disabled axis (Axis::enabled false) is written
// with its drive DISABLED (the joint follows its command, nothing moves)
// and its node optional (MANDATORY = NO): a machine can be brought up one
// axis at a time. Non-realtime.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "commission/state.hpp"

namespace cnc::commission {

struct GeneratedFile {
  std::filesystem::path path;
  std::string content;
};

// What generate_config writes besides the machine's configuration: the
// additions of the commissioning steps' own configurations. The default is
// the machine's configuration as `write` writes it.
struct WriterOptions {
  // Commissioning a gantry's drives one joint at a time (steps 4, 5 and 7
  // jog each joint of the pair before it is homed): the pair's joints get
  // HOME_SEQUENCE 0 instead of their synchronised group, whose joints
  // motion does not jog unhomed.
  bool gantry_joints_apart = false;
  // Step 7's loop response on this axis (0: none; commission/response.hpp):
  // the target velocity 0x60FF mapped on the axis' drive (CANopen: RPDO2 of
  // its node; EtherCAT: kResponseEthercatRxPdo as its slave's RxPDO), a
  // signal generator in the servo thread on the drive's vel-cmd (siggen
  // "response", mux2 "response-mux": sel 0 sine, 1 square), and a virtual
  // CAN bus shared (",share") so that cnc-commission reaches the drive by
  // SDO while cncd runs.
  char response_axis = 0;
};

// The EtherCAT slave's RxPDO for the loop response: the ESI's default
// (controlword, target position, touch-probe function), which the machine's
// configuration leaves in use, and the target velocity.
inline constexpr const char* kResponseEthercatRxPdo = "0x6040:0:u16 0x607A:0:s32 0x60B8:0:u16 0x60FF:0:s32";
// The CANopen node's RPDO for the loop response: the target velocity.
inline constexpr const char* kResponseCanopenRpdo = "0x60FF:0:s32";

// The files for configuration name `name` in folder `dir`: <name>.ini,
// <name>.hal, the check program check.ngc (commission/check.hpp) and, when
// there is none yet, tool.tbl. Throws
// std::invalid_argument when the state cannot make a configuration (no
// axis, an axis without scaling, a response axis without a drive), naming
// what is missing.
std::vector<GeneratedFile> generate_config(const State& s, const std::filesystem::path& dir, const std::string& name,
                                           const WriterOptions& options = {});

// The servo period the written configuration runs at: 1 ms per two axis
// drives on the one bus (their PDOs at 1 Mbit/s stay inside the bus-load
// budget of the CANopen master's plan).
long servo_period_ns(std::size_t drives) noexcept;

// A line difference of `old_text` and `new_text` ("-" removed, "+" added,
// unchanged lines left out), headed by the file name; "" when equal.
std::string diff_text(const std::string& file, const std::string& old_text, const std::string& new_text);

// Writes each file atomically; an existing file that changes is first kept
// as <file>.bak. Returns the files changed.
std::vector<std::filesystem::path> write_config(const std::vector<GeneratedFile>& files);

// Runs `<cncd> --check --strict <ini>` and returns its exit status; its
// output goes to `output`.
int check_config(const std::filesystem::path& cncd, const std::filesystem::path& ini, std::string& output);

}  // namespace cnc::commission
