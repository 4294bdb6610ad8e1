// VFD profiles as data: which registers a drive family uses for run, stop,
// direction, speed reference, feedback and faults, with their scaling and
// fault texts. One table per family (profile.cpp) and a generic profile read
// from the INI; the link's code never names a family's register.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cnc::ini {
class IniFile;
}

namespace cnc::modbus {

// Standard: Modbus registers (functions 3, 4, 6). Huanyang: the HY series'
// own function codes (huanyang.hpp).
enum class Protocol : uint8_t { Standard, Huanyang };

enum class Space : uint8_t { Holding, Input };

struct RegisterWrite {
  uint16_t address = 0;
  uint16_t value = 0;
};

// A value the drive reports: raw = physical x per_unit.
struct ScaledRegister {
  bool present = false;
  Space space = Space::Holding;
  uint16_t address = 0;
  double per_unit = 1;
  bool is_signed = false;
};

struct FaultText {
  uint16_t code = 0;
  std::string text;
};

struct VfdProfile {
  std::string name;         // PROFILE = name
  std::string description;  // "AutomationDirect GS2"
  Protocol protocol = Protocol::Standard;
  // Register writes per command, in order (a direction register before a
  // run register, for example).
  std::vector<RegisterWrite> on_connect, run_forward, run_reverse, stop, fault_reset;
  // Speed reference: holding register, raw units per Hz.
  uint16_t speed_address = 0;
  double speed_per_hz = 100;
  ScaledRegister output_frequency;  // raw per Hz
  ScaledRegister current;           // raw per A
  ScaledRegister fault;             // fault code (0: none), masked
  uint16_t fault_mask = 0xFFFF;
  std::vector<FaultText> fault_texts;

  // "over-current during acceleration (ocA)", or "fault code 77" when the
  // table does not list it.
  std::string fault_text(uint16_t code) const;
};

// The built-in families by name (gs2, delta, yaskawa, atv, huanyang); null
// for an unknown name.
const VfdProfile* builtin_profile(const std::string& name);
std::vector<std::string> builtin_profile_names();

// The generic profile, entirely from the keys of `section` (docs/modbus.md,
// "Generic profile"); errors name the file, line and key.
VfdProfile load_generic_profile(const ini::IniFile& ini, const std::string& section);

}  // namespace cnc::modbus
