#include "sim/modbus/device.hpp"

#include <cmath>

namespace cnc::modbus_sim {
namespace {

uint16_t u16(double v) { return static_cast<uint16_t>(std::lround(std::fabs(v))); }
uint16_t s16(double v) { return static_cast<uint16_t>(static_cast<int16_t>(std::lround(v))); }

}  // namespace

bool parse_family(const std::string& name, Family& out) {
  const std::pair<const char*, Family> all[] = {{"gs2", Family::Gs2},         {"delta", Family::Delta},
                                                {"yaskawa", Family::Yaskawa}, {"atv", Family::Atv},
                                                {"huanyang", Family::Huanyang}, {"io", Family::Io}};
  for (const auto& [n, f] : all) {
    if (name == n) {
      out = f;
      return true;
    }
  }
  return false;
}

const char* to_string(Family f) {
  switch (f) {
    case Family::Gs2: return "gs2";
    case Family::Delta: return "delta";
    case Family::Yaskawa: return "yaskawa";
    case Family::Atv: return "atv";
    case Family::Huanyang: return "huanyang";
    case Family::Io: return "io";
  }
  return "?";
}

uint16_t overcurrent_code(Family f) {
  switch (f) {
    case Family::Gs2: return 1;      // oc
    case Family::Delta: return 1;    // ocA
    case Family::Yaskawa: return 7;  // oC
    case Family::Atv: return 9;      // OCF
    default: return 1;
  }
}

Device::Device(Family family, MotorParams motor) : family_(family), model_([&] {
  motor.overcurrent_code = overcurrent_code(family);
  return motor;
}()) {}

bool Device::read_vfd(uint16_t a, uint16_t& out) const {
  const VfdModel& m = model_;
  switch (family_) {
    case Family::Gs2:
      if (a == 0x091A) return out = u16(m.reference_hz() * 10), true;
      if (a == 0x091B) return out = gs2_run_, true;
      if (a == 0x091C) return out = gs2_direction_, true;
      if (a == 0x2100) return out = m.fault_code(), true;
      if (a == 0x2103) return out = u16(m.output_hz() * 10), true;
      if (a == 0x2104) return out = u16(m.current_a() * 10), true;
      return false;
    case Family::Delta:
      if (a == 0x2000) return out = last_cmd_, true;
      if (a == 0x2001) return out = u16(m.reference_hz() * 100), true;
      if (a == 0x2100) return out = m.fault_code(), true;  // low byte: fault, high byte: warning
      if (a == 0x2101) return out = static_cast<uint16_t>((m.run() ? 3 : 0) | (m.reverse() ? 0x18 : 0)), true;
      if (a == 0x2103) return out = u16(m.output_hz() * 100), true;
      if (a == 0x2104) return out = u16(m.current_a() * 100), true;
      return false;
    case Family::Yaskawa:
      if (a == 0x0001) return out = last_cmd_, true;
      if (a == 0x0002) return out = u16(m.reference_hz() * 100), true;
      if (a == 0x0020) return out = static_cast<uint16_t>((m.output_hz() != 0 ? 1 : 0) | (m.reverse() ? 2 : 0) | (m.fault_code() ? 8 : 0)), true;
      if (a == 0x0024) return out = u16(m.output_hz() * 100), true;
      if (a == 0x0026) return out = u16(m.current_a() * 10), true;
      if (a == 0x0080) return out = m.fault_code(), true;
      return false;
    case Family::Atv:
      if (a == 8501) return out = last_cmd_, true;
      if (a == 8502) return out = u16(m.reference_hz() * 10), true;
      if (a == 3201) return out = static_cast<uint16_t>(m.fault_code() ? 0x0008 : (m.run() ? 0x0027 : 0x0021)), true;
      if (a == 3202) return out = s16(m.output_hz() * 10), true;
      if (a == 3204) return out = u16(m.current_a() * 10), true;
      if (a == 7121) return out = m.fault_code(), true;
      return false;
    default: return false;
  }
}

bool Device::read_holding(uint16_t a, uint16_t& out) const {
  if (family_ == Family::Io) {
    if (a >= kIoSize) return false;
    out = holding_regs[a];
    return true;
  }
  return read_vfd(a, out);
}

bool Device::read_input(uint16_t a, uint16_t& out) const {
  if (family_ == Family::Io) {
    if (a >= kIoSize) return false;
    out = input_regs[a];
    return true;
  }
  return read_vfd(a, out);  // drives answer both functions alike
}

bool Device::write_holding(uint16_t a, uint16_t v) {
  VfdModel& m = model_;
  switch (family_) {
    case Family::Io:
      if (a >= kIoSize) return false;
      holding_regs[a] = v;
      return true;
    case Family::Gs2:
      if (a == 0x091A) return m.set_reference_hz(v / 10.0), true;
      if (a == 0x091B) return gs2_run_ = v, m.command(v != 0, gs2_direction_ != 0), true;
      if (a == 0x091C) return gs2_direction_ = v, m.command(gs2_run_ != 0, v != 0), true;
      if (a == 0x091E) return (v ? m.reset_fault() : void()), true;  // reset (the sim's choice)
      return false;
    case Family::Delta:
      if (a == 0x2000) {
        last_cmd_ = v;
        const unsigned run = v & 0x3, dir = (v >> 4) & 0x3;
        if (run == 1) m.command(false, m.reverse());
        if (run == 2) m.command(true, dir == 2 ? true : dir == 1 ? false : m.reverse());
        return true;
      }
      if (a == 0x2001) return m.set_reference_hz(v / 100.0), true;
      if (a == 0x2002) return ((v & 0x2) ? m.reset_fault() : void()), true;
      return false;
    case Family::Yaskawa:
      if (a == 0x0001) {
        last_cmd_ = v;
        if (v & 0x8) m.reset_fault();
        m.command((v & 0x3) != 0, (v & 0x2) != 0);
        return true;
      }
      if (a == 0x0002) return m.set_reference_hz(v / 100.0), true;
      return false;
    case Family::Atv:
      if (a == 8501) {
        last_cmd_ = v;
        if (v & 0x80) m.reset_fault();
        const bool enabled = (v & 0x000F) == 0x000F && !(v & 0x0100);
        m.command(enabled, (v & 0x0800) != 0);
        return true;
      }
      if (a == 8502) return m.set_reference_hz(v / 10.0), true;
      return false;
    default: return false;
  }
}

bool Device::read_coil(uint16_t a, uint8_t& out) const {
  if (family_ != Family::Io || a >= kIoSize) return false;
  out = coils[a];
  return true;
}

bool Device::read_discrete(uint16_t a, uint8_t& out) const {
  if (family_ != Family::Io || a >= kIoSize) return false;
  out = discrete[a];
  return true;
}

bool Device::write_coil(uint16_t a, uint8_t v) {
  if (family_ != Family::Io || a >= kIoSize) return false;
  coils[a] = v ? 1 : 0;
  return true;
}

}  // namespace cnc::modbus_sim
