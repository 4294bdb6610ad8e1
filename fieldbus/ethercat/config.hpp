// The EtherCAT bus from INI: [ETHERCAT] for the bus and one
// [ETHERCAT_SLAVE_<position>] per slave that needs more than its SII
// defaults (name, expected identity, PDO mapping, start-up SDOs). Keys and
// syntax follow the CANopen ones where they mean the same (docs/ethercat.md).
// Errors name the file, the line and the key (ConfigError).
#pragma once

#include <string>

#include "fieldbus/ethercat/master.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::ethercat {

struct BusSettings {
  MasterConfig master;
  std::string thread = "servo-thread";  // whose wake-up the DC lock steers
};

BusSettings load_bus_settings(const ini::IniFile& ini, const std::string& section, const std::string& name);

}  // namespace cnc::ethercat
