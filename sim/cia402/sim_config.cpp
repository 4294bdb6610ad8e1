#include "sim/cia402/sim_config.hpp"

#include <cmath>
#include <set>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::cia402::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.141592653589793;

SimNodeConfig load_node(const ini::IniFile& ini, const std::string& s, int id, double step_s) {
  SimNodeConfig n;
  n.node_id = static_cast<uint8_t>(id);
  DriveSimConfig& d = n.drive;
  PlantConfig& p = d.plant;
  d.name = ini.get_string(s, "NAME", "node " + std::to_string(id));
  n.identity.device_name = "cnc simulated servo drive (" + d.name + ")";
  n.identity.vendor_id = static_cast<uint32_t>(ini.get_int(s, "VENDOR_ID", 0xCC1, {0, 4294967295.0}));
  n.identity.product_code = static_cast<uint32_t>(ini.get_int(s, "PRODUCT_CODE", 0x402, {0, 4294967295.0}));
  n.identity.revision = static_cast<uint32_t>(ini.get_int(s, "REVISION", 0x00010000, {0, 4294967295.0}));
  n.identity.serial = static_cast<uint32_t>(ini.get_int(s, "SERIAL", id, {0, 4294967295.0}));
  n.heartbeat_ms = static_cast<uint16_t>(ini.get_int(s, "HEARTBEAT_MS", 0, {0, 65535}));
  n.lss = ini.get_bool(s, "LSS", true);
  n.lss_unconfigured = ini.get_bool(s, "LSS_UNCONFIGURED", false);
  if (n.lss_unconfigured && !n.lss) ini.fail(ini.find_entry(s, "LSS"), "a drive without LSS cannot start LSS_UNCONFIGURED");
  n.sync_response_ns = ini.get_int(s, "SYNC_RESPONSE_US", 0, {0, 100000}) * 1000;

  // Millimetres (linear) or degrees (rotary) in the file; metres or radians here.
  const bool rotary = ini.get_bool(s, "ROTARY", false);
  const double unit = rotary ? kPi / 180.0 : 1e-3;
  p.encoder_counts = ini.get_double(s, "ENCODER_COUNTS", 131072, {1, 1e12});
  p.gear = ini.get_double(s, "GEAR", 1, {1e-6, 1e6});
  p.lead_m = ini.get_double(s, "SCREW_LEAD", rotary ? 360.0 : 5.0, {1e-6, 1e9}) * unit;
  p.motor_inertia = ini.get_double(s, "MOTOR_INERTIA", 1.5e-4, {1e-9, 100});
  p.load_mass = ini.get_double(s, "LOAD_MASS", rotary ? 0.01 : 200, {0, 1e6});
  p.motor_viscous = ini.get_double(s, "MOTOR_VISCOUS", 2e-4, {0, 1e6});
  p.motor_coulomb = ini.get_double(s, "MOTOR_COULOMB", 0.02, {0, 1e6});
  p.load_viscous = ini.get_double(s, "LOAD_VISCOUS", rotary ? 0 : 150, {0, 1e9});
  p.load_coulomb = ini.get_double(s, "LOAD_COULOMB", rotary ? 0 : 40, {0, 1e9});
  p.backlash_m = ini.get_double(s, "BACKLASH", 0, {0, 1e3}) * unit;
  p.torque_constant = ini.get_double(s, "TORQUE_CONSTANT", 0.8, {1e-6, 1e3});
  p.max_current = ini.get_double(s, "MAX_CURRENT", 12, {1e-6, 1e4});
  p.rated_torque = ini.get_double(s, "RATED_TORQUE", 3.2, {1e-6, 1e5});
  p.current_tau = ini.get_double(s, "CURRENT_TIME_CONSTANT", 2e-4, {1e-7, 1});
  p.neg_limit = ini.get_double(s, "NEG_LIMIT_SWITCH", -kInf) * unit;
  p.pos_limit = ini.get_double(s, "POS_LIMIT_SWITCH", kInf) * unit;
  if (const ini::Entry* e = ini.find_entry(s, "HOME_SWITCH")) {
    const auto w = split_blanks(e->value);
    const auto lo = w.size() >= 1 ? parse_double(w[0]) : std::nullopt;
    const auto hi = w.size() >= 2 ? parse_double(w[1]) : std::optional<double>(kInf);
    if (!lo || !hi || *hi < *lo) ini.fail(e, "expected the switch's range: MIN [MAX] (MAX absent: to the end)");
    p.home_min = *lo * unit;
    p.home_max = *hi * unit;
  }
  p.index_offset = ini.get_double(s, "INDEX_OFFSET", 0) * unit;
  p.start_position = ini.get_double(s, "START_POSITION", 0) * unit;
  if (ini.find_entry(s, "PROBE_POSITION")) p.probe_position = ini.get_double(s, "PROBE_POSITION", 0) * unit;
  p.probe_direction = static_cast<int>(ini.get_int(s, "PROBE_DIRECTION", -1, {-1, 1}));
  if (p.probe_direction == 0) ini.fail(ini.find_entry(s, "PROBE_DIRECTION"), "expected -1 or 1");
  if (const ini::Entry* e = ini.find_entry(s, "PITCH_ERROR")) {
    // "position:error position:error ...", both in millimetres (degrees), increasing positions.
    for (const std::string& w : split_blanks(e->value)) {
      const auto parts = split(w, ':');
      const auto x = parts.size() == 2 ? parse_double(parts[0]) : std::nullopt;
      const auto err = parts.size() == 2 ? parse_double(parts[1]) : std::nullopt;
      if (!x || !err) ini.fail(e, "\"" + w + "\": expected POSITION:ERROR");
      if (p.pitch_points == PlantConfig::kMaxPitchPoints) ini.fail(e, "more than 64 points");
      if (p.pitch_points > 0 && *x * unit <= p.pitch_at[p.pitch_points - 1]) ini.fail(e, "positions must increase");
      p.pitch_at[p.pitch_points] = *x * unit;
      p.pitch_error[p.pitch_points] = *err * unit;
      ++p.pitch_points;
    }
  }
  ServoGains& g = d.gains;
  g.position_gain = ini.get_double(s, "POSITION_GAIN", g.position_gain, {0, 1e5});
  g.velocity_bandwidth_hz = ini.get_double(s, "VELOCITY_BANDWIDTH", g.velocity_bandwidth_hz, {0.1, 1e5});
  g.velocity_gain = ini.get_double(s, "VELOCITY_GAIN", 0, {0, 1e6});
  g.velocity_integral_time = ini.get_double(s, "VELOCITY_INTEGRAL_TIME", g.velocity_integral_time, {0, 100});
  g.velocity_ff = ini.get_double(s, "VELOCITY_FF", g.velocity_ff, {0, 2});
  g.torque_ff = ini.get_double(s, "TORQUE_FF", g.torque_ff, {0, 2});
  d.step_s = ini.get_double(s, "STEP_US", step_s * 1e6, {1, 1000}) * 1e-6;
  d.max_motor_speed_rpm = static_cast<uint32_t>(ini.get_int(s, "MAX_MOTOR_SPEED", d.max_motor_speed_rpm, {1, 4294967295.0}));
  d.ferror_window = static_cast<uint32_t>(ini.get_int(s, "FERROR_WINDOW_COUNTS", 0, {0, 4294967295.0}));
  d.ferror_timeout_ms = static_cast<uint16_t>(ini.get_int(s, "FERROR_TIMEOUT_MS", 10, {0, 65535}));
  d.motor_reversed = ini.get_bool(s, "MOTOR_REVERSED", false);
  d.switches_active_low = ini.get_bool(s, "SWITCHES_ACTIVE_LOW", false);
  d.sync_timeout_ns = ini.get_int(s, "SYNC_TIMEOUT_MS", 200, {1, 600'000}) * 1'000'000;
  d.trip_c = ini.get_double(s, "TRIP_TEMPERATURE", d.trip_c, {0, 1000});
  d.warning_c = ini.get_double(s, "WARNING_TEMPERATURE", d.warning_c, {0, 1000});
  return n;
}

}  // namespace

SimBusConfig load_sim_config(const ini::IniFile& ini, const std::string& section, const std::vector<int>& only) {
  SimBusConfig b;
  b.section = section;
  if (!ini.has_section(section)) ini.fail(nullptr, "no [" + section + "] section (the simulated drives)");
  b.interface = ini.require_string(section, "INTERFACE");
  const double step_s = ini.get_double(section, "STEP_US", 20, {1, 1000}) * 1e-6;
  const std::string order = to_upper(trim(ini.get_string(section, "TX_QUEUE", "PRIORITY")));
  if (order != "PRIORITY" && order != "FIFO") ini.fail(ini.find_entry(section, "TX_QUEUE"), "expected PRIORITY or FIFO");
  b.tx_fifo = order == "FIFO";
  std::set<int> ids;
  for (const ini::Entry* e : ini.find_all_entries(section, "NODE")) {
    for (const std::string& w : split_blanks(e->value)) {
      const auto v = parse_int(w);
      if (!v || *v < 1 || *v > 127) ini.fail(e, "\"" + w + "\": expected node-IDs 1..127");
      if (!ids.insert(static_cast<int>(*v)).second) ini.fail(e, "node " + w + " listed twice");
      if (!only.empty() && std::find(only.begin(), only.end(), static_cast<int>(*v)) == only.end()) continue;
      const std::string ns = section + "_NODE_" + std::to_string(*v);
      if (!ini.has_section(ns)) ini.fail(e, "node " + w + " has no [" + ns + "] section");
      b.nodes.push_back(load_node(ini, ns, static_cast<int>(*v), step_s));
    }
  }
  if (b.nodes.empty()) ini.fail(ini.find_entry(section, "INTERFACE"), "no simulated nodes (NODE = <id> ...)");
  return b;
}

}  // namespace cnc::cia402::sim
