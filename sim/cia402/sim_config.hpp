// Simulated drives from an INI file: the bus section (interface, nodes, time
// step) and one section per node with the plant, the servo gains and where
// the switches and the index are. Lengths in the file are millimetres (or
// degrees for ROTARY = YES), converted to SI here. See docs/cia402.md.
// Non-realtime; throws ConfigError naming file, line and key.
#pragma once

#include <string>
#include <vector>

#include "sim/cia402/canopen_drive.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::cia402::sim {

struct SimBusConfig {
  std::string section = "CIA402_SIM";
  std::string interface;           // virtual:sim, socketcan:vcan0
  std::vector<SimNodeConfig> nodes;
  // TX_QUEUE: how each simulated drive's controller offers its frames on
  // the in-process bus: PRIORITY (transmit mailboxes, lowest identifier
  // first; the default) or FIFO (one queue: a TPDO1 answering SYNC waits
  // behind the drive's own event PDOs queued before it).
  bool tx_fifo = false;
};

// Reads [<section>] (INTERFACE, NODE = ids..., STEP_US) and each
// [<section>_NODE_<id>]. `only` limits the nodes (empty: all).
SimBusConfig load_sim_config(const ini::IniFile& ini, const std::string& section, const std::vector<int>& only = {});

}  // namespace cnc::cia402::sim
