// libFuzzer entry point: arbitrary bytes as an ESI XML file (expat), then
// a device looked up by product code and revision. Anything but the
// documented std::runtime_error, a crash, a sanitizer report or a hang is
// a bug.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fieldbus/ethercat/esi.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::ethercat;
  try {
    const EsiFile f = parse_esi(std::string(reinterpret_cast<const char*>(data), size), "fuzz.xml");
    for (const EsiDevice& d : f.devices) (void)f.find(d.product_code, d.revision);
    (void)f.find(0x402, 0);
  } catch (const std::runtime_error&) {
  }
  return 0;
}
