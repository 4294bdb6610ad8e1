// Private to the EtherCAT master: the formatting and byte helpers its parts
// share (master.cpp: datagrams and status; master_config.cpp: scan, states,
// CoE and process-data configuration, DC, start-up; master_cycle.cpp;
// master_coe.cpp: mailbox and SDO; master_worker.cpp).
#pragma once

#include <time.h>

#include <cinttypes>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "fieldbus/canopen/sdo_abort.hpp"
#include "fieldbus/ethercat/master.hpp"

namespace cnc::ethercat::master_detail {

inline int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}
inline void sleep_ns(int64_t ns) {
  timespec ts{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
  nanosleep(&ts, nullptr);
}
inline std::string fmt(const char* f, ...) __attribute__((format(printf, 1, 2)));
inline std::string fmt(const char* f, ...) {
  char b[512];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(b, sizeof b, f, ap);
  va_end(ap);
  return b;
}
inline std::string object(uint16_t index, uint8_t sub) { return fmt("0x%04X:%02X", index, sub); }
inline std::string value_text(const std::vector<uint8_t>& d) {
  if (d.size() <= 8) {
    uint64_t v = 0;
    for (std::size_t i = 0; i < d.size(); ++i) v |= uint64_t{d[i]} << (8 * i);
    return fmt("0x%0*" PRIX64, static_cast<int>(d.size() * 2), v);
  }
  return fmt("%zu bytes", d.size());
}
inline std::vector<uint8_t> le(uint64_t v, unsigned n) {
  std::vector<uint8_t> d(n);
  for (unsigned i = 0; i < n; ++i) d[i] = static_cast<uint8_t>(v >> (8 * i));
  return d;
}
inline std::string abort_text(uint32_t code) {
  return fmt("aborted by the slave: 0x%08X %s", code, canopen::sdo_abort_text(code));
}

}  // namespace cnc::ethercat::master_detail
