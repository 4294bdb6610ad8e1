// Test helpers: a simulator and a link configured to talk to it.
#pragma once

#include <chrono>
#include <functional>
#include <string>
#include <thread>

#include "core/ini/ini_file.hpp"
#include "core/util/time.hpp"
#include "fieldbus/modbus/config.hpp"
#include "sim/modbus/server.hpp"

namespace cnc::modbus::testing {

// Waits for `pred` for at most `timeout_s` (generous: the tests assert
// outcomes, never times).
inline bool eventually(const std::function<bool()>& pred, double timeout_s = 10.0) {
  const int64_t deadline = monotonic_ns() + static_cast<int64_t>(timeout_s * 1e9);
  while (monotonic_ns() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return pred();
}

inline modbus_sim::ServerConfig sim_config(modbus_sim::Family family, bool tcp) {
  modbus_sim::ServerConfig s;
  s.family = family;
  s.tcp = tcp;
  s.motor.ramp_hz_s = 4000;  // quick ramps: tests wait for outcomes
  s.motor.trip_a = 1e9;      // trips only when injected
  return s;
}

// The generic profile set up for a Delta-like drive (the simulator's delta
// family), as docs/modbus.md shows it.
inline const char* kGenericDeltaKeys =
    "PROFILE = generic\nRUN_FORWARD = 0x2000:0x12\nRUN_REVERSE = 0x2000:0x22\nSTOP = 0x2000:0x01\n"
    "FAULT_RESET = 0x2002:0x02\nSPEED_REGISTER = 0x2001\nSPEED_PER_HZ = 100\nFREQUENCY_REGISTER = 0x2103\n"
    "FREQUENCY_PER_HZ = 100\nCURRENT_REGISTER = 0x2104\nCURRENT_PER_A = 100\nFAULT_REGISTER = 0x2100\n"
    "FAULT_MASK = 0xFF\nFAULT_TEXT = 1:over-current during acceleration\n";

// INI text for a link to `server` with one VFD of `profile` at slave 1.
inline std::string link_ini(const modbus_sim::Server& server, bool tcp, const std::string& profile,
                            const std::string& extra_vfd_keys = "") {
  std::string s = "[MODBUS]\n";
  if (tcp) s += "TRANSPORT = TCP\nHOST = 127.0.0.1\nPORT = " + std::to_string(server.port()) + "\n";
  else s += "TRANSPORT = RTU\nDEVICE = " + server.pty_path() + "\nBAUD = 115200\n";
  s += "TIMEOUT_MS = 200\nRETRY_MIN_MS = 20\nRETRY_MAX_MS = 200\nVFD = 1\n[MODBUS_VFD_1]\nNAME = spindle\n";
  s += profile == "generic" ? std::string(kGenericDeltaKeys) : "PROFILE = " + profile + "\n";
  s += "POLL_MS = 5\nSTALE_MS = 1000\n" + extra_vfd_keys;
  return s;
}

}  // namespace cnc::modbus::testing
