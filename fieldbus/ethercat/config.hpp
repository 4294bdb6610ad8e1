// The EtherCAT bus from INI: [ETHERCAT] for the bus and one
// [ETHERCAT_SLAVE_<position>] per slave that needs more than its SII
// defaults (name, expected identity, PDO mapping, start-up SDOs). Keys and
// syntax follow the CANopen ones where they mean the same (docs/ethercat.md).
// Errors name the file, the line and the key (ConfigError).
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "fieldbus/ethercat/master.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::ethercat {

struct BusSettings {
  MasterConfig master;
  std::string thread = "servo-thread";  // whose wake-up the DC lock steers
  std::string cycle_key;                // "file:line: [ETHERCAT]CYCLE_US" when the INI gives the cycle
};

// The bus cycle is CYCLE_US when given, else the period `thread_period`
// gives for the bus's THREAD (the thread expected to run its functions;
// the component checks that in on_ready), else 1 ms.
BusSettings load_bus_settings(const ini::IniFile& ini, const std::string& section, const std::string& name,
                              const std::function<int64_t(const std::string&)>& thread_period = nullptr);

}  // namespace cnc::ethercat
