// libFuzzer entry point: arbitrary bytes as a COMP_FILE, read as type 0
// and type 1. A table that loads is looked up (servo-thread path: finite
// results only), written out and must load again with the same entries.
// Anything but ConfigError, a crash, a sanitizer report or a hang is a bug.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "comp/comp_table.hpp"
#include "core/util/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::comp;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  for (const CompFileType type : {CompFileType::Positions, CompFileType::Trims}) {
    CompTable t;
    try {
      t = parse_comp_table(text, type, "fuzz.comp");
    } catch (const cnc::ConfigError&) {
      continue;
    }
    const double lo = t.nominal.front(), hi = t.nominal.back();
    for (const double x : {lo - 1, lo, (lo + hi) / 2, hi, hi + 1, lo + (hi - lo) / 3}) {
      for (const int d : {-1, 0, 1}) {
        if (!std::isfinite(t.at(x, d))) std::abort();  // a correction the servo thread would add to the motor
      }
    }
    (void)t.max_abs_trim();
    (void)t.max_abs_slope();
    CompTable back;
    try {
      back = parse_comp_table(format_comp_table(t, type, {"note"}), type, "written.comp");
    } catch (const cnc::ConfigError&) {
      std::abort();  // what it writes, it must read
    }
    if (back.size() != t.size()) std::abort();
  }
  return 0;
}
