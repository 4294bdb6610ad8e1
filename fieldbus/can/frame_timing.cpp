#include "fieldbus/can/frame_timing.hpp"

namespace cnc::can {
namespace {

// The stuffable part of a classic frame (SOF .. end of the data field), one
// bit per call, most significant first, as the controller sends it.
template <class Sink>
void emit_header_and_data(const Frame& f, Sink&& bit) {
  auto bits = [&](uint32_t value, int count) {
    for (int i = count - 1; i >= 0; --i) bit(((value >> i) & 1u) != 0);
  };
  const bool rtr = f.is_remote();
  const uint32_t data_len = rtr ? 0 : f.len;
  const uint32_t dlc = f.len > 8 ? 8 : f.len;
  bit(false);  // SOF
  if (f.is_extended()) {
    bits(f.id >> 18, 11);   // base identifier
    bit(true);              // SRR
    bit(true);              // IDE
    bits(f.id & 0x3FFFF, 18);
    bit(rtr);
    bit(false);             // r1
    bit(false);             // r0
  } else {
    bits(f.id & kStandardIdMask, 11);
    bit(rtr);
    bit(false);             // IDE
    bit(false);             // r0
  }
  bits(dlc, 4);
  for (uint32_t i = 0; i < data_len && i < 8; ++i) bits(f.data[i], 8);
}

}  // namespace

const char* to_string(Stuffing s) noexcept {
  switch (s) {
    case Stuffing::Nominal: return "nominal";
    case Stuffing::WorstCase: return "worst-case";
    case Stuffing::Exact: return "exact";
  }
  return "?";
}

// CRC-15-CAN: x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1 (0x4599), init 0.
uint16_t frame_crc15(const Frame& f) noexcept {
  uint16_t crc = 0;
  emit_header_and_data(f, [&](bool b) {
    const bool next = b != (((crc >> 14) & 1u) != 0);
    crc = static_cast<uint16_t>((crc << 1) & 0x7FFF);
    if (next) crc ^= 0x4599;
  });
  return crc;
}

uint32_t stuff_bits(const Frame& f) noexcept {
  uint32_t stuffed = 0;
  int run = 0;
  bool last = false;
  auto push = [&](bool b) {
    if (run > 0 && b == last) {
      ++run;
    } else {
      last = b;
      run = 1;
    }
    if (run == 5) {  // a complementary stuff bit, which starts the next run
      ++stuffed;
      last = !last;
      run = 1;
    }
  };
  emit_header_and_data(f, push);
  const uint16_t crc = frame_crc15(f);
  for (int i = 14; i >= 0; --i) push(((crc >> i) & 1u) != 0);
  return stuffed;
}

uint32_t exact_frame_bits(const Frame& f) noexcept {
  const uint32_t data = f.is_remote() ? 0 : (f.len > 8 ? 8 : f.len);
  return nominal_frame_bits(f.is_extended(), data) + stuff_bits(f);
}

uint32_t frame_bits(const Frame& f, Stuffing model) noexcept {
  const uint32_t data = f.is_remote() ? 0 : (f.len > 8 ? 8 : f.len);
  switch (model) {
    case Stuffing::Nominal: return nominal_frame_bits(f.is_extended(), data);
    case Stuffing::WorstCase: return worst_case_frame_bits(f.is_extended(), data);
    case Stuffing::Exact: return exact_frame_bits(f);
  }
  return worst_case_frame_bits(f.is_extended(), data);
}

}  // namespace cnc::can
