#include "fieldbus/modbus/profile.hpp"

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::modbus {
namespace {

ScaledRegister reg(uint16_t address, double per_unit, Space space = Space::Holding, bool is_signed = false) {
  return ScaledRegister{true, space, address, per_unit, is_signed};
}

// AutomationDirect GS2 (GS2 user manual, chapter 5): P9.26 speed reference
// 0x091A in 0.1 Hz, P9.27 run 0x091B, P9.28 direction 0x091C; status
// monitor 0x2100 (error code, low byte), 0x2103 output frequency (0.1 Hz),
// 0x2104 output current (0.1 A).
VfdProfile gs2() {
  VfdProfile p;
  p.name = "gs2";
  p.description = "AutomationDirect GS2";
  p.run_forward = {{0x091C, 0}, {0x091B, 1}};
  p.run_reverse = {{0x091C, 1}, {0x091B, 1}};
  p.stop = {{0x091B, 0}};
  p.speed_address = 0x091A;
  p.speed_per_hz = 10;
  p.output_frequency = reg(0x2103, 10);
  p.current = reg(0x2104, 10);
  p.fault = reg(0x2100, 1);
  p.fault_mask = 0x00FF;
  p.fault_texts = {{1, "over-current (oc)"},      {2, "over-voltage (ov)"},  {3, "overheat (oH)"},
                   {4, "drive overload (oL)"},    {5, "motor overload (oL1)"}, {6, "external fault (EF)"},
                   {7, "CPU failure 1 (CF1)"},    {8, "CPU failure 2 (CF2)"},
                   {10, "over-current during acceleration (ocA)"},
                   {11, "over-current during deceleration (ocd)"},
                   {12, "over-current at constant speed (ocn)"}, {13, "ground fault (GFF)"}, {14, "low voltage (Lv)"}};
  return p;
}

// Delta VFD-E / MS300 (Appendix A, Modbus protocol): command 0x2000 (bits
// 0-1: 01 stop, 10 run; bits 4-5: 01 forward, 10 reverse), frequency 0x2001
// in 0.01 Hz, 0x2002 bit 1 fault reset; monitor 0x2100 fault code (low
// byte), 0x2103 output frequency (0.01 Hz), 0x2104 output current (0.01 A).
VfdProfile delta() {
  VfdProfile p;
  p.name = "delta";
  p.description = "Delta VFD-E / MS300";
  p.run_forward = {{0x2000, 0x0012}};
  p.run_reverse = {{0x2000, 0x0022}};
  p.stop = {{0x2000, 0x0001}};
  p.fault_reset = {{0x2002, 0x0002}};
  p.speed_address = 0x2001;
  p.speed_per_hz = 100;
  p.output_frequency = reg(0x2103, 100);
  p.current = reg(0x2104, 100);
  p.fault = reg(0x2100, 1);
  p.fault_mask = 0x00FF;
  p.fault_texts = {{1, "over-current during acceleration (ocA)"}, {2, "over-current during deceleration (ocd)"},
                   {3, "over-current at constant speed (ocn)"},   {4, "ground fault (GFF)"},
                   {5, "IGBT short circuit (occ)"},               {6, "over-current at stop (ocS)"},
                   {7, "over-voltage during acceleration (ovA)"}, {8, "over-voltage during deceleration (ovd)"},
                   {9, "over-voltage at constant speed (ovn)"},   {10, "over-voltage at stop (ovS)"},
                   {11, "low voltage during acceleration (LvA)"}, {12, "low voltage during deceleration (Lvd)"},
                   {13, "low voltage at constant speed (Lvn)"},   {14, "low voltage at stop (LvS)"},
                   {15, "input phase loss (orP)"},                {16, "IGBT overheat (oH1)"},
                   {21, "drive overload (oL)"},                   {22, "motor 1 overload (EoL1)"}};
  return p;
}

// Yaskawa V1000 / GA500 (MEMOBUS/Modbus data table): 0x0001 operation
// command (bit 0 forward run, bit 1 reverse run, bit 3 fault reset), 0x0002
// frequency reference (o1-03 = 0: 0.01 Hz); monitors 0x0024 output
// frequency (0.01 Hz), 0x0026 output current (0.1 A on most ratings), 0x0080
// current fault (U2-01, fault trace codes).
VfdProfile yaskawa() {
  VfdProfile p;
  p.name = "yaskawa";
  p.description = "Yaskawa V1000 / GA500";
  p.run_forward = {{0x0001, 0x0001}};
  p.run_reverse = {{0x0001, 0x0002}};
  p.stop = {{0x0001, 0x0000}};
  p.fault_reset = {{0x0001, 0x0008}, {0x0001, 0x0000}};
  p.speed_address = 0x0002;
  p.speed_per_hz = 100;
  p.output_frequency = reg(0x0024, 100);
  p.current = reg(0x0026, 10);
  p.fault = reg(0x0080, 1);
  p.fault_texts = {{0x02, "DC bus undervoltage (Uv1)"}, {0x03, "control power undervoltage (Uv2)"},
                   {0x04, "soft charge circuit fault (Uv3)"}, {0x06, "ground fault (GF)"},
                   {0x07, "overcurrent (oC)"},          {0x08, "overvoltage (ov)"},
                   {0x09, "heatsink overheat (oH)"},    {0x0A, "heatsink overheat (oH1)"},
                   {0x0B, "motor overload (oL1)"},      {0x0C, "drive overload (oL2)"},
                   {0x0D, "overtorque detection 1 (oL3)"}};
  return p;
}

// Schneider Altivar 12 / 320 (communication parameters, DRIVECOM profile):
// CMD 8501 (0x0006 shutdown, 0x000F run, bit 11 reverse, bit 8 halt, bit 7
// fault reset), LFR 8502 frequency reference (0.1 Hz); RFR 3202 output
// frequency (0.1 Hz, signed), LCR 3204 motor current (0.1 A), LFT 7121 last
// fault.
VfdProfile atv() {
  VfdProfile p;
  p.name = "atv";
  p.description = "Schneider Altivar 12 / 320";
  p.on_connect = {{8501, 0x0006}};
  p.run_forward = {{8501, 0x000F}};
  p.run_reverse = {{8501, 0x080F}};
  p.stop = {{8501, 0x010F}};
  p.fault_reset = {{8501, 0x0080}, {8501, 0x0006}};
  p.speed_address = 8502;
  p.speed_per_hz = 10;
  p.output_frequency = reg(3202, 10, Space::Holding, true);
  p.current = reg(3204, 10);
  p.fault = reg(7121, 1);
  p.fault_texts = {{16, "drive overheat (OHF)"},        {17, "motor overload (OLF)"},
                   {18, "DC bus overvoltage (OBF)"},    {19, "supply overvoltage (OSF)"},
                   {20, "output phase loss (OPF1)"},    {21, "input phase loss (PHF)"},
                   {22, "supply undervoltage (USF)"},   {23, "motor short circuit (SCF1)"},
                   {24, "overspeed (SOF)"},             {9, "overcurrent (OCF)"}};
  return p;
}

// Huanyang HY: its own function codes (huanyang.hpp); frequency in 0.01 Hz,
// output frequency monitor 0x01 (0.01 Hz), output current monitor 0x02 (0.1
// A). It reports no fault code through this protocol.
VfdProfile huanyang() {
  VfdProfile p;
  p.name = "huanyang";
  p.description = "Huanyang HY series";
  p.protocol = Protocol::Huanyang;
  p.speed_per_hz = 100;
  p.output_frequency = reg(0x01, 100);
  p.current = reg(0x02, 10);
  return p;
}

const std::vector<VfdProfile>& builtins() {
  static const std::vector<VfdProfile> all = {gs2(), delta(), yaskawa(), atv(), huanyang()};
  return all;
}

std::vector<RegisterWrite> parse_writes(const ini::IniFile& ini, const std::string& section, const std::string& key,
                                        bool required) {
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) {
    if (required) ini.require_string(section, key);  // throws naming the key
    return {};
  }
  std::vector<RegisterWrite> out;
  for (const std::string& item : split_blanks(e->value)) {
    const auto parts = split(item, ':', false);
    const auto a = parts.size() == 2 ? parse_int(parts[0]) : std::nullopt;
    const auto v = parts.size() == 2 ? parse_int(parts[1]) : std::nullopt;
    if (!a || !v || *a < 0 || *a > 0xFFFF || *v < 0 || *v > 0xFFFF) {
      ini.fail(e, "expected REGISTER:VALUE pairs (0..65535 each, e.g. 0x2000:0x12), got '" + item + "'");
    }
    out.push_back({static_cast<uint16_t>(*a), static_cast<uint16_t>(*v)});
  }
  return out;
}

ScaledRegister parse_scaled(const ini::IniFile& ini, const std::string& section, const std::string& key,
                            const std::string& scale_key, double default_scale) {
  ScaledRegister r;
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) return r;
  auto parts = split_blanks(e->value);
  if (parts.empty() || parts.size() > 2) ini.fail(e, "expected ADDRESS [HOLDING|INPUT|SIGNED_HOLDING|SIGNED_INPUT]");
  const auto a = parse_int(parts[0]);
  if (!a || *a < 0 || *a > 0xFFFF) ini.fail(e, "register address 0..65535 expected, got '" + parts[0] + "'");
  r.present = true;
  r.address = static_cast<uint16_t>(*a);
  if (parts.size() == 2) {
    const std::string kind = to_upper(parts[1]);
    if (kind == "HOLDING") r.space = Space::Holding;
    else if (kind == "INPUT") r.space = Space::Input;
    else if (kind == "SIGNED_HOLDING") r.space = Space::Holding, r.is_signed = true;
    else if (kind == "SIGNED_INPUT") r.space = Space::Input, r.is_signed = true;
    else ini.fail(e, "expected HOLDING, INPUT, SIGNED_HOLDING or SIGNED_INPUT, got '" + parts[1] + "'");
  }
  if (!scale_key.empty()) r.per_unit = ini.get_double(section, scale_key, default_scale, {1e-6, 1e6});
  return r;
}

}  // namespace

std::string VfdProfile::fault_text(uint16_t code) const {
  for (const FaultText& f : fault_texts) {
    if (f.code == code) return f.text;
  }
  return "fault code " + std::to_string(code);
}

const VfdProfile* builtin_profile(const std::string& name) {
  for (const VfdProfile& p : builtins()) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

std::vector<std::string> builtin_profile_names() {
  std::vector<std::string> out;
  for (const VfdProfile& p : builtins()) out.push_back(p.name);
  return out;
}

VfdProfile load_generic_profile(const ini::IniFile& ini, const std::string& s) {
  VfdProfile p;
  p.name = "generic";
  p.description = "generic (" + s + ")";
  p.on_connect = parse_writes(ini, s, "ON_CONNECT", false);
  p.run_forward = parse_writes(ini, s, "RUN_FORWARD", true);
  p.run_reverse = parse_writes(ini, s, "RUN_REVERSE", false);
  p.stop = parse_writes(ini, s, "STOP", true);
  p.fault_reset = parse_writes(ini, s, "FAULT_RESET", false);
  p.speed_address = static_cast<uint16_t>(ini.require_int(s, "SPEED_REGISTER", {0, 0xFFFF}));
  p.speed_per_hz = ini.get_double(s, "SPEED_PER_HZ", 100, {1e-6, 1e6});
  p.output_frequency = parse_scaled(ini, s, "FREQUENCY_REGISTER", "FREQUENCY_PER_HZ", 100);
  p.current = parse_scaled(ini, s, "CURRENT_REGISTER", "CURRENT_PER_A", 10);
  p.fault = parse_scaled(ini, s, "FAULT_REGISTER", "", 1);
  p.fault_mask = static_cast<uint16_t>(ini.get_int(s, "FAULT_MASK", 0xFFFF, {0, 0xFFFF}));
  for (const ini::Entry* e : ini.find_all_entries(s, "FAULT_TEXT")) {
    const auto colon = e->value.find(':');
    const auto code = colon == std::string::npos ? std::nullopt : parse_int(trim(e->value.substr(0, colon)));
    if (!code || *code < 0 || *code > 0xFFFF) ini.fail(e, "expected CODE:TEXT (e.g. 1:over-current), got '" + e->value + "'");
    p.fault_texts.push_back({static_cast<uint16_t>(*code), std::string(trim(e->value.substr(colon + 1)))});
  }
  return p;
}

}  // namespace cnc::modbus
