#include "fieldbus/canopen/pdo.hpp"

#include <cstdio>

namespace cnc::canopen {

uint32_t PdoConfig::total_bits() const noexcept {
  uint32_t n = 0;
  for (const auto& e : map) n += e.bits;
  return n;
}

std::string describe_mapping(const std::vector<PdoMapEntry>& map) {
  std::string out;
  char buf[16];
  for (const auto& e : map) {
    std::snprintf(buf, sizeof buf, "0x%08X", e.encode());
    out += (out.empty() ? "" : " ") + std::string(buf);
  }
  return out.empty() ? "(empty)" : out;
}

}  // namespace cnc::canopen
