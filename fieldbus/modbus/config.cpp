#include "fieldbus/modbus/config.hpp"

#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::modbus {
namespace {

// [MODBUS] + VFD + 3 -> [MODBUS_VFD_3]; [MODBUS_1] -> [MODBUS_1_VFD_3].
std::string device_section(const std::string& link, const char* kind, int slave) {
  return link + "_" + kind + "_" + std::to_string(slave);
}

std::vector<int> slave_list(const ini::IniFile& ini, const std::string& section, const char* key) {
  std::vector<int> out;
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) return out;
  for (const std::string& w : split_blanks(e->value)) {
    const auto v = parse_int(w);
    if (!v || *v < 1 || *v > 247) ini.fail(e, "slave addresses 1..247 expected, got '" + w + "'");
    out.push_back(static_cast<int>(*v));
  }
  return out;
}

int64_t ms_key(const ini::IniFile& ini, const std::string& s, const char* key, double def, double min, double max) {
  return static_cast<int64_t>(std::llround(ini.get_double(s, key, def, {min, max}) * 1e6));
}

VfdConfig load_vfd(const ini::IniFile& ini, const std::string& s, int slave) {
  if (!ini.has_section(s)) throw ConfigError(ini.path().string(), 0, "[" + s + "] is missing (slave " + std::to_string(slave) + " is listed as a VFD)");
  VfdConfig v;
  v.slave = static_cast<uint8_t>(slave);
  v.section = s;
  v.name = ini.get_string(s, "NAME", "vfd-" + std::to_string(slave));
  const ini::Entry* pe = ini.find_entry(s, "PROFILE");
  const std::string profile = to_lower(ini.require_string(s, "PROFILE"));
  if (profile == "generic") {
    v.profile = load_generic_profile(ini, s);
  } else if (const VfdProfile* p = builtin_profile(profile)) {
    v.profile = *p;
  } else {
    std::string known = "generic";
    for (const std::string& n : builtin_profile_names()) known += ", " + n;
    ini.fail(pe, "unknown VFD profile '" + profile + "' (known: " + known + ")");
  }
  v.rpm_per_hz = ini.get_double(s, "RPM_PER_HZ", 60, {0.01, 1e5});
  v.at_speed_tolerance = ini.get_double(s, "AT_SPEED_TOLERANCE", 0.02, {0.0, 1.0});
  v.poll_ns = ms_key(ini, s, "POLL_MS", 20, 0, 10'000);
  v.stale_ns = ms_key(ini, s, "STALE_MS", 500, 1, 60'000);
  const std::string action = to_upper(ini.get_string(s, "ON_COMM_LOSS", "FAULT"));
  if (action == "FAULT") v.on_comm_loss = CommLossAction::Fault;
  else if (action == "WARN") v.on_comm_loss = CommLossAction::Warn;
  else ini.fail(ini.find_entry(s, "ON_COMM_LOSS"), "expected FAULT or WARN, got '" + action + "'");
  return v;
}

IoMap parse_map(const ini::IniFile& ini, const ini::Entry* e, IoKind kind, int64_t default_poll_ns) {
  IoMap m;
  m.kind = kind;
  m.poll_ns = default_poll_ns;
  m.type = (kind == IoKind::Coil || kind == IoKind::DiscreteInput) ? IoType::Bit : IoType::Float;
  const auto w = split_blanks(e->value);
  const auto start = w.size() >= 2 ? parse_int(w[0]) : std::nullopt;
  const auto count = w.size() >= 2 ? parse_int(w[1]) : std::nullopt;
  if (!start || !count || *start < 0 || *start > 0xFFFF || *count < 1 || *count > 125 || *start + *count > 0x10000) {
    ini.fail(e, "expected START COUNT [bit|float|s32] [signed] [scale=X] [offset=X] [poll_ms=X] (COUNT 1..125)");
  }
  m.start = static_cast<uint16_t>(*start);
  m.count = static_cast<uint16_t>(*count);
  for (std::size_t i = 2; i < w.size(); ++i) {
    const std::string word = to_lower(w[i]);
    const auto eq = word.find('=');
    const std::string key = word.substr(0, eq);
    const std::string val = eq == std::string::npos ? std::string() : word.substr(eq + 1);
    const double num_value = eq == std::string::npos ? NAN : parse_double(val).value_or(NAN);
    const double* num = std::isnan(num_value) ? nullptr : &num_value;
    if (word == "bit" || word == "float" || word == "s32") {
      const bool bits = kind == IoKind::Coil || kind == IoKind::DiscreteInput;
      if (bits != (word == "bit")) ini.fail(e, "'" + word + "' does not fit " + to_string(kind) + "s");
      m.type = word == "bit" ? IoType::Bit : word == "float" ? IoType::Float : IoType::S32;
    } else if (word == "signed") {
      m.is_signed = true;
    } else if (key == "scale" && num && *num != 0 && std::isfinite(*num)) {
      m.scale = *num;
    } else if (key == "offset" && num && std::isfinite(*num)) {
      m.offset = *num;
    } else if (key == "poll_ms" && num && *num >= 0 && *num <= 60'000) {
      m.poll_ns = static_cast<int64_t>(std::llround(*num * 1e6));
    } else {
      ini.fail(e, "unknown or invalid option '" + w[i] + "' (bit, float, s32, signed, scale=X, offset=X, poll_ms=X)");
    }
  }
  return m;
}

IoConfig load_io(const ini::IniFile& ini, const std::string& s, int slave) {
  if (!ini.has_section(s)) throw ConfigError(ini.path().string(), 0, "[" + s + "] is missing (slave " + std::to_string(slave) + " is listed as I/O)");
  IoConfig c;
  c.slave = static_cast<uint8_t>(slave);
  c.section = s;
  c.name = ini.get_string(s, "NAME", "io-" + std::to_string(slave));
  const int64_t poll = ms_key(ini, s, "POLL_MS", 50, 0, 60'000);
  c.stale_ns = ms_key(ini, s, "STALE_MS", 500, 1, 60'000);
  const std::pair<const char*, IoKind> keys[] = {{"COIL", IoKind::Coil},
                                                 {"DISCRETE_INPUT", IoKind::DiscreteInput},
                                                 {"INPUT_REGISTER", IoKind::InputRegister},
                                                 {"HOLDING_REGISTER", IoKind::HoldingRegister}};
  for (const auto& [key, kind] : keys) {
    for (const ini::Entry* e : ini.find_all_entries(s, key)) {
      IoMap m = parse_map(ini, e, kind, poll);
      m.first_value = c.values;
      c.values += m.count;
      if (c.values > kMaxIoValues) ini.fail(e, "more than " + std::to_string(kMaxIoValues) + " values in one I/O module");
      if (c.maps.size() >= kMaxIoMaps) ini.fail(e, "more than " + std::to_string(kMaxIoMaps) + " map lines in one I/O module");
      c.maps.push_back(m);
    }
  }
  if (c.maps.empty()) {
    throw ConfigError(ini.path().string(), 0, "[" + s + "] maps nothing: add COIL, DISCRETE_INPUT, INPUT_REGISTER or HOLDING_REGISTER lines");
  }
  return c;
}

}  // namespace

const char* to_string(IoKind k) noexcept {
  switch (k) {
    case IoKind::Coil: return "coil";
    case IoKind::DiscreteInput: return "discrete input";
    case IoKind::InputRegister: return "input register";
    case IoKind::HoldingRegister: return "holding register";
  }
  return "?";
}

std::string LinkConfig::describe() const {
  if (transport == Transport::Tcp) return "tcp " + host + ":" + std::to_string(port);
  return "rtu " + device + " " + std::to_string(baud) + " " + std::to_string(data_bits) + parity + std::to_string(stop_bits);
}

LinkConfig load_link_config(const ini::IniFile& ini, const std::string& s, const std::string& name) {
  if (!ini.has_section(s)) throw ConfigError(ini.path().string(), 0, "modbus: the INI file has no [" + s + "] section");
  LinkConfig c;
  c.section = s;
  c.name = name;
  const std::string t = to_upper(ini.require_string(s, "TRANSPORT"));
  if (t == "RTU") {
    c.transport = Transport::Rtu;
    c.device = ini.require_string(s, "DEVICE");
    c.baud = static_cast<int>(ini.get_int(s, "BAUD", 19200, {1200, 921600}));
    const std::string parity = to_upper(ini.get_string(s, "PARITY", "N"));
    if (parity != "N" && parity != "E" && parity != "O") {
      ini.fail(ini.find_entry(s, "PARITY"), "expected N, E or O, got '" + parity + "'");
    }
    c.parity = parity[0];
    c.data_bits = static_cast<int>(ini.get_int(s, "DATA_BITS", 8, {7, 8}));
    c.stop_bits = static_cast<int>(ini.get_int(s, "STOP_BITS", 1, {1, 2}));
  } else if (t == "TCP") {
    c.transport = Transport::Tcp;
    c.host = ini.require_string(s, "HOST");
    c.port = static_cast<int>(ini.get_int(s, "PORT", 502, {1, 65535}));
  } else {
    ini.fail(ini.find_entry(s, "TRANSPORT"), "expected RTU or TCP, got '" + t + "'");
  }
  c.timeout_ns = ms_key(ini, s, "TIMEOUT_MS", 100, 1, 10'000);
  c.retry_min_ns = ms_key(ini, s, "RETRY_MIN_MS", 100, 1, 60'000);
  c.retry_max_ns = ms_key(ini, s, "RETRY_MAX_MS", 2000, 1, 600'000);
  if (c.retry_max_ns < c.retry_min_ns) {
    ini.fail(ini.find_entry(s, "RETRY_MAX_MS"), "RETRY_MAX_MS is below RETRY_MIN_MS");
  }
  for (int slave : slave_list(ini, s, "VFD")) c.vfds.push_back(load_vfd(ini, device_section(s, "VFD", slave), slave));
  for (int slave : slave_list(ini, s, "IO")) c.ios.push_back(load_io(ini, device_section(s, "IO", slave), slave));
  if (c.vfds.empty() && c.ios.empty()) throw ConfigError(ini.path().string(), 0, "[" + s + "] lists no device: add VFD = <slave> or IO = <slave>");
  for (const VfdConfig& v : c.vfds) {
    if (v.profile.protocol == Protocol::Huanyang && c.transport != Transport::Rtu) {
      throw ConfigError(ini.path().string(), 0, "[" + v.section + "] PROFILE = huanyang needs an RTU link ([" + s + "] TRANSPORT = RTU)");
    }
  }
  return c;
}

}  // namespace cnc::modbus
