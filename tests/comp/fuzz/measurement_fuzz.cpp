// libFuzzer entry point: arbitrary bytes as a measurement CSV (ISO 230-2
// points). A file that loads is written out and must load again with the
// same points; with the fitting library built, its ISO 230-2 figures are
// evaluated and must be finite. Anything but ConfigError (reading) and
// std::invalid_argument (evaluation), a crash, a sanitizer report or a
// hang is a bug.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>
#include <string_view>

#include "comp/measurement.hpp"
#include "core/util/error.hpp"
#ifdef CNC_FUZZ_ISO230
#include "comp/iso230.hpp"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::comp;
  Measurement m;
  try {
    m = parse_measurement(std::string_view(reinterpret_cast<const char*>(data), size), "fuzz.csv");
  } catch (const cnc::ConfigError&) {
    return 0;
  }
  (void)m.has_temperature();
  (void)m.has_time();
  try {
    const Measurement back = parse_measurement(format_measurement(m), "written.csv");
    if (back.points.size() != m.points.size()) std::abort();
  } catch (const cnc::ConfigError&) {
    // The writer keeps targets to 1e-6: two targets just over 1e-6 apart
    // (distinct) may be written 1e-6 apart (one target), and their runs
    // then repeat. Refused with a reason, as it should be.
  }
#ifdef CNC_FUZZ_ISO230
  try {
    const Iso230Result r = evaluate_iso230(m);
    if (!std::isfinite(r.A) || !std::isfinite(r.E) || !std::isfinite(r.R) || !std::isfinite(r.M)) std::abort();
  } catch (const std::invalid_argument&) {
  }
#endif
  Measurement numbered = m;
  number_runs(numbered);
  return 0;
}
