// EtherCAT slave information (ESI) XML files (ETG.2000), read offline when
// the INI names one: the vendor, and per device its identity, its default
// PDOs (those assigned to a sync manager) and the DC AssignActivate word.
// The master then takes PDO defaults and SYNC activation from the file
// instead of the SII. Non-realtime; errors name the file and line.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "fieldbus/ethercat/sii.hpp"

namespace cnc::ethercat {

struct EsiDevice {
  std::string type;  // <Type> text, e.g. "SIM402"
  std::string name;  // first <Name>
  uint32_t product_code = 0, revision = 0;
  std::vector<SiiPdo> rx_pdos, tx_pdos;  // PDOs with an Sm attribute (assigned by default)
  bool has_dc = false;
  uint16_t assign_activate = 0;          // of the first DC operation mode (0x0300: SYNC0)
  int line = 0;                          // where the device starts in the file
};

struct EsiFile {
  std::string path;
  uint32_t vendor_id = 0;
  std::string vendor_name;
  std::vector<EsiDevice> devices;
  // The device with this product code and revision, else the one with this
  // product code and the highest revision; null when none.
  const EsiDevice* find(uint32_t product_code, uint32_t revision) const noexcept;
};

// Throws std::runtime_error "<file>:<line>: <reason>".
EsiFile load_esi(const std::filesystem::path& path);
EsiFile parse_esi(const std::string& xml, const std::string& filename);
// ESI numbers: "#x1A00" hexadecimal or decimal.
bool parse_esi_number(const std::string& text, uint64_t& out) noexcept;

}  // namespace cnc::ethercat
