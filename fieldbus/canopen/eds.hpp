// CANopen device description files (CiA 306): EDS and DCF, INI-style text
// with one section per object and sub-index. The parser checks what it
// reads and reports errors as "file:line: what was expected"
// (cnc::ConfigError). A description can build a slave's object dictionary
// (simulated devices) and gives the master the values a DCF configures
// (ParameterValue) and the types to check PDO mappings against.
// Non-realtime.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fieldbus/canopen/object_dictionary.hpp"
#include "fieldbus/canopen/types.hpp"

namespace cnc::canopen {

struct EdsEntry {
  ObjectAddress addr;
  uint8_t object_type = 0x7;        // of the enclosing object: 0x7 VAR, 0x8 ARRAY, 0x9 RECORD
  std::string name;
  DataType type = DataType::Unsigned8;
  Access access = Access::ReadOnly;
  bool pdo_mapping = false;
  std::string default_value;        // as written, may contain $NODEID
  std::string parameter_value;      // DCF only
  std::string low_limit, high_limit;
  int line = 0;                     // of the section
  int value_line = 0;               // of ParameterValue (DCF), else of the section
};

struct DeviceDescription {
  std::string file;
  bool is_dcf = false;
  // [DeviceInfo]
  std::string vendor_name, product_name;
  std::optional<uint32_t> vendor_number, product_number, revision_number;
  std::vector<uint32_t> baud_rates_kbit;   // BaudRate_<n>=1
  // [DeviceComissioning] (DCF)
  std::optional<uint8_t> node_id;
  std::string node_name;
  std::optional<uint32_t> baudrate_kbit;
  // Every VAR and sub-index, sorted by address.
  std::vector<EdsEntry> entries;

  const EdsEntry* find(ObjectAddress a) const noexcept;
  bool has_index(uint16_t index) const noexcept;

  // The value of an entry for node `node_id` as little-endian bytes:
  // ParameterValue when present and `configured`, else DefaultValue.
  // Throws ConfigError (file:line) if the text does not fit the type.
  std::vector<uint8_t> value_bytes(const EdsEntry& e, uint8_t node_id, bool configured) const;
  // Adds every entry to `od` with its default value (the dictionary of a
  // simulated device described by this file).
  void build_dictionary(ObjectDictionary& od, uint8_t node_id) const;
};

DeviceDescription parse_eds(std::string_view text, const std::string& filename);
DeviceDescription load_eds(const std::filesystem::path& path);

// "$NODEID+0x180", "0x200", "-5", "012" (octal): a number in C syntax with
// $NODEID replaced. Empty result when the text is not such a number.
std::optional<int64_t> eval_eds_number(std::string_view text, uint8_t node_id) noexcept;

}  // namespace cnc::canopen
