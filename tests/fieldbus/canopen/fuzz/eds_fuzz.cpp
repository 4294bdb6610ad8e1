// libFuzzer entry point: arbitrary bytes as an EDS/DCF file. Parsed, every
// entry's value converted for two node-IDs, and the object dictionary of a
// simulated device built from it. Anything but ConfigError, a crash, a
// sanitizer report or a hang is a bug.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/util/error.hpp"
#include "fieldbus/canopen/eds.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::canopen;
  DeviceDescription d;
  try {
    d = parse_eds(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.eds");
  } catch (const cnc::ConfigError&) {
    return 0;
  }
  for (const EdsEntry& e : d.entries) {
    (void)d.find(e.addr);
    (void)eval_eds_number(e.default_value, 1);
    for (const uint8_t node : {uint8_t{1}, uint8_t{127}}) {
      for (const bool configured : {false, true}) {
        try {
          (void)d.value_bytes(e, node, configured);
        } catch (const cnc::ConfigError&) {
        }
      }
    }
  }
  try {
    ObjectDictionary od;
    d.build_dictionary(od, 5);
  } catch (const cnc::ConfigError&) {
  }
  return 0;
}
