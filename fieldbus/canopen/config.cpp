#include "fieldbus/canopen/config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <stdexcept>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::canopen {
namespace {

std::string hex(uint32_t v, int width) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%0*X", width, v);
  return buf;
}

std::string addr_text(ObjectAddress a) {
  char buf[16];
  return format(a, buf, sizeof buf);
}

struct TypeToken {
  const char* name;
  DataType type;
  ValueKind kind;
  uint8_t bits;
};
constexpr TypeToken kTypes[] = {
    {"u8", DataType::Unsigned8, ValueKind::Unsigned, 8},    {"u16", DataType::Unsigned16, ValueKind::Unsigned, 16},
    {"u32", DataType::Unsigned32, ValueKind::Unsigned, 32}, {"u64", DataType::Unsigned64, ValueKind::Unsigned, 64},
    {"s8", DataType::Integer8, ValueKind::Signed, 8},       {"s16", DataType::Integer16, ValueKind::Signed, 16},
    {"s32", DataType::Integer32, ValueKind::Signed, 32},    {"s64", DataType::Integer64, ValueKind::Signed, 64},
    {"f32", DataType::Real32, ValueKind::Real, 32},         {"f64", DataType::Real64, ValueKind::Real, 64},
    {"bool", DataType::Boolean, ValueKind::Bit, 1},
};

const TypeToken* find_type(std::string_view t) {
  for (const auto& k : kTypes) {
    if (iequals(t, k.name)) return &k;
  }
  return nullptr;
}

ValueKind kind_of(DataType t) {
  if (t == DataType::Boolean) return ValueKind::Bit;
  if (t == DataType::Real32 || t == DataType::Real64) return ValueKind::Real;
  return is_signed(t) ? ValueKind::Signed : ValueKind::Unsigned;
}

std::optional<ObjectAddress> parse_address(std::string_view idx, std::string_view sub) {
  const auto i = parse_uint(trim(idx));
  const auto s = parse_uint(trim(sub));
  if (!i || !s || *i > 0xFFFF || *s > 0xFF) return std::nullopt;
  return ObjectAddress{static_cast<uint16_t>(*i), static_cast<uint8_t>(*s)};
}

}  // namespace

std::string NodeConfig::label() const {
  return "node " + std::to_string(id) + (name.empty() ? "" : " (" + name + ")");
}

std::optional<ParsedMapEntry> parse_map_entry(const std::string& text, const DeviceDescription* eds, std::string& error) {
  const std::string t(trim(text));
  ParsedMapEntry out;
  for (const char* pad : {"pad8", "pad16", "pad32"}) {
    if (iequals(t, pad)) {
      const uint8_t bits = static_cast<uint8_t>(std::stoi(std::string(pad + 3)));
      out.entry = PdoMapEntry{static_cast<uint16_t>(bits == 8 ? 0x0005 : bits == 16 ? 0x0006 : 0x0007), 0, bits};
      return out;
    }
  }
  const auto parts = split(t, ':');
  if (parts.size() == 1) {  // raw 0xIIIISSLL
    const auto v = parse_uint(t);
    if (!v || *v > 0xFFFFFFFF || (*v & 0xFF) == 0) {
      error = "\"" + t + "\": expected index:sub:type (0x6040:0:u16), a raw entry (0x60400010) or pad8/pad16/pad32";
      return std::nullopt;
    }
    out.entry = PdoMapEntry::decode(static_cast<uint32_t>(*v));
    if (out.entry.bits > 64) {
      error = "\"" + t + "\": more than 64 bits";
      return std::nullopt;
    }
    const EdsEntry* e = eds ? eds->find({out.entry.index, out.entry.sub}) : nullptr;
    out.kind = e ? kind_of(e->type) : (out.entry.bits == 1 ? ValueKind::Bit : ValueKind::Unsigned);
    return out;
  }
  if (parts.size() != 2 && parts.size() != 3) {
    error = "\"" + t + "\": expected index:sub:type, e.g. 0x6040:0:u16";
    return std::nullopt;
  }
  const auto a = parse_address(parts[0], parts[1]);
  if (!a) {
    error = "\"" + t + "\": index 0..0xFFFF and sub-index 0..0xFF expected";
    return std::nullopt;
  }
  out.entry.index = a->index;
  out.entry.sub = a->sub;
  if (parts.size() == 3) {
    const TypeToken* k = find_type(trim(parts[2]));
    if (!k) {
      error = "\"" + t + "\": type \"" + std::string(trim(parts[2])) + "\" is not one of u8 u16 u32 u64 s8 s16 s32 s64 f32 f64 bool";
      return std::nullopt;
    }
    out.entry.bits = k->bits;
    out.kind = k->kind;
    return out;
  }
  const EdsEntry* e = eds ? eds->find(*a) : nullptr;
  if (!e || !is_fixed_size(e->type)) {
    error = "\"" + t + "\": give the type (index:sub:type); no device description says it";
    return std::nullopt;
  }
  out.entry.bits = static_cast<uint8_t>(data_type_size(e->type) * 8);
  out.kind = kind_of(e->type);
  return out;
}

std::optional<SdoWrite> parse_sdo_write(const std::string& text, const DeviceDescription* eds, std::string& error) {
  const std::string t(trim(text));
  const auto space = t.find_first_of(" \t");
  if (space == std::string::npos) {
    error = "\"" + t + "\": expected index:sub[:type] value, e.g. 0x6060:0:s8 8";
    return std::nullopt;
  }
  const std::string target = t.substr(0, space);
  const std::string value(trim(std::string_view(t).substr(space)));
  const auto parts = split(target, ':');
  if (parts.size() != 2 && parts.size() != 3) {
    error = "\"" + target + "\": expected index:sub[:type]";
    return std::nullopt;
  }
  const auto a = parse_address(parts[0], parts[1]);
  if (!a) {
    error = "\"" + target + "\": index 0..0xFFFF and sub-index 0..0xFF expected";
    return std::nullopt;
  }
  SdoWrite w;
  w.addr = *a;
  std::string type_name = parts.size() == 3 ? to_lower(trim(parts[2])) : "";
  DataType type = DataType::Unsigned8;
  if (type_name.empty()) {
    const EdsEntry* e = eds ? eds->find(*a) : nullptr;
    if (!e) {
      error = "\"" + target + "\": give the type (index:sub:type); no device description says it";
      return std::nullopt;
    }
    type = e->type;
    if (type == DataType::VisibleString) type_name = "str";
    else if (type == DataType::Domain || type == DataType::OctetString) type_name = "hex";
    if (e->access == Access::WriteOnly) w.verify = false;
  } else if (type_name != "str" && type_name != "hex") {
    const TypeToken* k = find_type(type_name);
    if (!k || k->type == DataType::Boolean) {
      error = "\"" + target + "\": type \"" + type_name + "\" is not one of u8 u16 u32 u64 s8 s16 s32 s64 f32 f64 str hex";
      return std::nullopt;
    }
    type = k->type;
  }
  if (type_name == "str") {
    w.data.assign(value.begin(), value.end());
    return w;
  }
  if (type_name == "hex") {
    for (const auto& b : split_blanks(value)) {
      const auto v = parse_uint("0x" + b);
      if (!v || *v > 0xFF || b.size() > 2) {
        error = "\"" + value + "\": expected hex bytes separated by blanks";
        return std::nullopt;
      }
      w.data.push_back(static_cast<uint8_t>(*v));
    }
    return w;
  }
  const std::size_t size = data_type_size(type);
  w.data.assign(size, 0);
  if (type == DataType::Real32 || type == DataType::Real64) {
    const auto d = parse_double(value);
    if (!d) {
      error = "\"" + value + "\": expected a number";
      return std::nullopt;
    }
    if (type == DataType::Real32) put_le<float>(w.data.data(), static_cast<float>(*d));
    else put_le<double>(w.data.data(), *d);
    return w;
  }
  const auto v = parse_int(value);
  const auto u = parse_uint(value);
  if (!v && !u) {
    error = "\"" + value + "\": expected an integer";
    return std::nullopt;
  }
  if (size < 8) {
    const int64_t lo = is_signed(type) ? -(int64_t{1} << (8 * size - 1)) : 0;
    const int64_t hi = is_signed(type) ? (int64_t{1} << (8 * size - 1)) - 1 : (int64_t{1} << (8 * size)) - 1;
    if (!v || *v < lo || *v > hi) {
      error = "\"" + value + "\": out of range for " + to_string(type);
      return std::nullopt;
    }
  }
  const uint64_t bits = u ? *u : static_cast<uint64_t>(*v);
  for (std::size_t i = 0; i < size; ++i) w.data[i] = static_cast<uint8_t>(bits >> (8 * i));
  return w;
}

// ------------------------------------------------------------------ BusConfig

const NodeConfig* BusConfig::node(uint8_t id) const noexcept {
  for (const auto& n : nodes) {
    if (n.id == id) return &n;
  }
  return nullptr;
}

namespace {

bool is_event_transmission(uint8_t t) noexcept { return t >= 253; }

// The bus-load plan's interval of an event-driven TPDO: the longer of its
// inhibit time and the declared interval; 0 when nothing bounds it.
int64_t event_interval_ns(const PdoConfig& p) noexcept {
  return std::max<int64_t>(int64_t{p.inhibit_100us} * 100'000, int64_t{p.plan_interval_us} * 1000);
}

}  // namespace

std::vector<can::ScheduledFrame> BusConfig::schedule() const {
  std::vector<can::ScheduledFrame> out;
  auto sync_frame = [](std::string label, uint32_t bytes, uint32_t cob) {
    can::ScheduledFrame f;
    f.label = std::move(label);
    f.data_bytes = bytes;
    f.cob_id = cob;
    return f;
  };
  auto sporadic = [](std::string label, uint32_t bytes, uint32_t cob, int64_t interval_ns) {
    can::ScheduledFrame f;
    f.label = std::move(label);
    f.data_bytes = bytes;
    f.cob_id = cob;
    f.period_ns = interval_ns;
    return f;
  };
  out.push_back(sync_frame("SYNC", sync_overflow ? 1u : 0u, sync_cob_id & 0x7FF));
  uint8_t lowest_id = 127;
  for (const auto& n : nodes) {
    lowest_id = std::min(lowest_id, n.id);
    // The master sends every RPDO every cycle.
    for (const auto& p : n.rpdos) {
      const uint32_t cob = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(false, p.number, n.id);
      out.push_back(sync_frame(n.label() + " RPDO" + std::to_string(p.number), p.bytes(), cob));
    }
    const int32_t group = n.tx_fifo ? n.id : -1;  // the node's own frames share one queue
    for (const auto& p : n.tpdos) {
      const uint32_t cob = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(true, p.number, n.id);
      const std::string label = n.label() + " TPDO" + std::to_string(p.number);
      if (is_event_transmission(p.transmission)) {
        // Unbounded ones are refused by validate(); plan them every cycle.
        const int64_t interval = event_interval_ns(p);
        out.push_back(sporadic(label, p.bytes(), cob, interval > 0 ? interval : cycle_ns));
        out.back().fifo_group = group;
        continue;
      }
      can::ScheduledFrame f = sync_frame(label, p.bytes(), cob);
      f.fifo_group = group;
      f.release_ns = int64_t{n.sync_response_us} * 1000;
      if (p.transmission >= 1) f.every_n_cycles = p.transmission;
      // The SYNC counter fixes the phase when its overflow is a multiple of
      // the divider: sent at counter == SYNC_START, then every n-th.
      if (f.every_n_cycles > 1 && sync_overflow > 0 && p.sync_start > 0 && sync_overflow % f.every_n_cycles == 0) {
        f.slot = static_cast<int32_t>((p.sync_start - 1u) % f.every_n_cycles);
      }
      out.push_back(f);
    }
    if (n.heartbeat_ms > 0) {
      out.push_back(sporadic(n.label() + " heartbeat", 1, cob::heartbeat(n.id), int64_t{n.heartbeat_ms} * 1'000'000));
      out.back().fifo_group = group;
    }
  }
  if (master_heartbeat_ms > 0) {
    out.push_back(sporadic("master heartbeat", 1, cob::heartbeat(master_node_id), int64_t{master_heartbeat_ms} * 1'000'000));
  }
  // Allowances: EMCY (8 bytes, at the highest EMCY priority of the bus) and
  // SDO (8 bytes, below every PDO).
  if (plan_emcy_frames > 0 && !nodes.empty()) {
    can::ScheduledFrame f = sync_frame("EMCY allowance", 8, cob::emcy(lowest_id));
    f.per_cycle = plan_emcy_frames;
    out.push_back(f);
  }
  if (plan_sdo_frames > 0 && !nodes.empty()) {
    can::ScheduledFrame f = sync_frame("SDO allowance", 8, cob::sdo_response(lowest_id));
    f.per_cycle = plan_sdo_frames;
    out.push_back(f);
  }
  return out;
}

can::BusLoad BusConfig::load() const { return can::compute_bus_load(schedule(), cycle_ns, bitrate); }

std::string BusConfig::load_problem() const {
  const can::BusLoad l = load();
  std::string out;
  char buf[600];
  if (l.worst_case() > max_bus_load) {
    std::snprintf(buf, sizeof buf,
                  "average load %.1f %% in the worst case (%.1f %% nominal) exceeds the budget of %.0f %% (MAX_BUS_LOAD)",
                  l.worst_case() * 100, l.nominal() * 100, max_bus_load * 100);
    out = buf;
  }
  if (l.worst_cycle() > max_cycle_load) {
    const can::SlotLoad& s = l.slots[l.worst_slot];
    std::string response;
    if (s.response_bits > 0) {
      char r[96];
      std::snprintf(r, sizeof r, " + %.0f waiting for the slowest device's SYNC response (SYNC_RESPONSE_US)", s.response_bits);
      response = r;
    }
    std::snprintf(buf, sizeof buf,
                  "%scycle slot %u of %zu needs %.0f bit times (%.0f synchronous + %.0f higher-priority events and "
                  "allowances + %.0f blocking%s), %.1f %% of the SYNC period, above the budget of %.0f %% (MAX_CYCLE_LOAD)",
                  out.empty() ? "" : "; ", s.slot, l.slots.size(), s.total(), s.synchronous_bits, s.interference_bits,
                  s.blocking_bits, response.c_str(), l.worst_cycle() * 100, max_cycle_load * 100);
    out += buf;
  }
  if (out.empty()) return out;
  std::snprintf(buf, sizeof buf,
                " (SYNC period %lld us, %u kbit/s): use fewer or shorter PDOs, inhibit times on event PDOs, "
                "SYNC_START phases, a longer period or a second bus",
                static_cast<long long>(cycle_ns / 1000), bitrate / 1000);
  return out + buf;
}

void BusConfig::validate() const {
  auto fail = [&](const std::string& what) { throw std::runtime_error(name + ": " + what); };
  if (interface.empty()) fail("no INTERFACE (socketcan:<if> or virtual:<bus>)");
  if (cycle_ns <= 0) fail("the SYNC period must be positive");
  if (bitrate == 0 || bitrate > 1'000'000) fail("BITRATE must be 1..1000000");
  if (!is_valid_node_id(master_node_id)) fail("MASTER_NODE_ID must be 1..127");
  if (sync_overflow == 1 || sync_overflow > 240) fail("SYNC_COUNTER_OVERFLOW must be 0 or 2..240");
  std::set<uint8_t> ids;
  std::map<uint32_t, std::string> cobs;
  auto claim = [&](uint32_t id, const std::string& who) {
    const auto [it, fresh] = cobs.emplace(id, who);
    if (!fresh) fail("COB-ID " + hex(id, 3) + " used by both " + it->second + " and " + who);
  };
  claim(sync_cob_id & 0x7FF, "SYNC");
  claim(cob::heartbeat(master_node_id), "the master heartbeat");
  for (const auto& n : nodes) {
    if (!is_valid_node_id(n.id)) fail(n.origin + ": node-ID " + std::to_string(n.id) + " is not 1..127");
    if (!ids.insert(n.id).second) fail(n.label() + " configured twice");
    if (n.id == master_node_id) fail(n.label() + " has the master's node-ID " + std::to_string(master_node_id));
    claim(cob::emcy(n.id), n.label() + " EMCY");
    claim(cob::sdo_response(n.id), n.label() + " SDO");
    claim(cob::sdo_request(n.id), n.label() + " SDO");
    claim(cob::heartbeat(n.id), n.label() + " heartbeat");
    for (bool tpdo : {false, true}) {
      const auto& list = tpdo ? n.tpdos : n.rpdos;
      std::set<uint16_t> numbers;
      for (const auto& p : list) {
        const std::string what = n.label() + (tpdo ? " TPDO" : " RPDO") + std::to_string(p.number);
        if (p.number < 1 || p.number > 512) fail(what + ": PDO number must be 1..512");
        if (!numbers.insert(p.number).second) fail(what + " configured twice");
        if (p.map.size() > 64) fail(what + ": more than 64 mapped objects");
        if (p.total_bits() > 64) fail(what + ": " + std::to_string(p.total_bits()) + " bits mapped, a classic CAN PDO holds 64");
        if (!is_valid_transmission(p.transmission, tpdo)) fail(what + ": transmission type " + std::to_string(p.transmission) + " is reserved or not allowed");
        if (tpdo && is_event_transmission(p.transmission) && event_interval_ns(p) == 0) {
          const std::string k = "TPDO" + std::to_string(p.number);
          fail(what + ": event-driven (transmission " + std::to_string(p.transmission) +
               ") with nothing bounding its rate, the bus load cannot be planned: give " + k +
               "_INHIBIT_100US (the device enforces it) or " + k + "_MIN_INTERVAL_US (what the application guarantees)");
        }
        const uint32_t id = p.cob_id ? (p.cob_id & 0x7FF) : default_pdo_cob(tpdo, p.number, n.id);
        if (id == 0) fail(what + ": PDOs above 4 need a COB_ID");
        claim(id, what);
        if (!n.eds) continue;
        for (const auto& e : p.map) {
          if (e.is_dummy()) continue;
          const EdsEntry* d = n.eds->find({e.index, e.sub});
          std::string obj = addr_text({e.index, e.sub});
          if (!d) fail(what + ": " + obj + " is not in " + n.eds->file);
          if (!d->name.empty()) obj += " (" + d->name + ")";
          if (!d->pdo_mapping) fail(what + ": " + obj + " is not PDO-mappable according to " + n.eds->file);
          const std::size_t size = data_type_size(d->type) * 8;
          if (e.bits != size && !(d->type == DataType::Boolean && e.bits == 1)) {
            fail(what + ": " + obj + " is " + to_string(d->type) + " (" + std::to_string(size) + " bits), mapped with " + std::to_string(e.bits));
          }
          if (tpdo ? !is_readable(d->access) : !is_writable(d->access)) {
            fail(what + ": " + obj + " cannot be " + (tpdo ? "read" : "written") + " according to " + n.eds->file);
          }
        }
      }
    }
  }
  if (const std::string problem = load_problem(); !problem.empty() && !load_override) {
    fail("bus load: " + problem + "; LOAD_OVERRIDE = YES runs it anyway, with a warning");
  }
}

// ------------------------------------------------------------------ INI

namespace {

// PDO `number` from the description's communication and mapping objects,
// when they are there and enable it (ParameterValue of a DCF, else the
// EDS default).
std::optional<PdoConfig> pdo_from_description(const DeviceDescription& d, bool tpdo, unsigned number, uint8_t node_id,
                                              std::vector<ValueKind>& kinds) {
  const uint16_t comm = tpdo ? tpdo_comm_index(number) : rpdo_comm_index(number);
  const uint16_t map = tpdo ? tpdo_map_index(number) : rpdo_map_index(number);
  const EdsEntry* cob_entry = d.find({comm, 1});
  const EdsEntry* count_entry = d.find({map, 0});
  if (!cob_entry || !count_entry) return std::nullopt;
  auto u32 = [&](const EdsEntry& e) {
    const auto b = d.value_bytes(e, node_id, true);
    uint32_t v = 0;
    for (std::size_t i = 0; i < b.size() && i < 4; ++i) v |= static_cast<uint32_t>(b[i]) << (8 * i);
    return v;
  };
  const uint32_t cob = u32(*cob_entry);
  if (cob & cob::kPdoInvalid) return std::nullopt;
  PdoConfig p;
  p.number = static_cast<uint16_t>(number);
  p.cob_id = cob & 0x7FF;
  if (const EdsEntry* t = d.find({comm, 2})) p.transmission = static_cast<uint8_t>(u32(*t));
  if (const EdsEntry* t = d.find({comm, 3}); t && tpdo) p.inhibit_100us = static_cast<uint16_t>(u32(*t));
  if (const EdsEntry* t = d.find({comm, 5})) p.event_ms = static_cast<uint16_t>(u32(*t));
  if (const EdsEntry* t = d.find({comm, 6}); t && tpdo) p.sync_start = static_cast<uint8_t>(u32(*t));
  const uint32_t count = u32(*count_entry);
  for (uint32_t s = 1; s <= count; ++s) {
    const EdsEntry* e = d.find({map, static_cast<uint8_t>(s)});
    if (!e) throw ConfigError(d.file, count_entry->line, "[" + addr_text({map, 0}) + "] maps " + std::to_string(count) + " objects but sub-index " + std::to_string(s) + " is missing");
    const PdoMapEntry m = PdoMapEntry::decode(u32(*e));
    p.map.push_back(m);
    const EdsEntry* obj = d.find({m.index, m.sub});
    kinds.push_back(obj ? kind_of(obj->type) : ValueKind::Unsigned);
  }
  return p;
}

bool is_pdo_object(uint16_t index) { return index >= 0x1400 && index <= 0x1BFF; }

}  // namespace

BusConfig load_bus_config(const ini::IniFile& ini, const std::string& section, const std::string& name,
                          int64_t thread_period_ns) {
  BusConfig c;
  c.name = name;
  c.origin = "[" + section + "]";
  if (!ini.has_section(section)) ini.fail(nullptr, "no [" + section + "] section for the CANopen bus " + name);
  c.interface = ini.require_string(section, "INTERFACE");
  c.bitrate = static_cast<uint32_t>(ini.get_int(section, "BITRATE", 1'000'000, {10'000, 1'000'000}));
  c.master_node_id = static_cast<uint8_t>(ini.get_int(section, "MASTER_NODE_ID", 127, {1, 127}));
  c.master_heartbeat_ms = static_cast<uint16_t>(ini.get_int(section, "MASTER_HEARTBEAT_MS", 100, {0, 65535}));
  c.sync_cob_id = static_cast<uint32_t>(ini.get_int(section, "SYNC_COB_ID", 0x80, {1, 0x7FF}));
  const int64_t overflow = ini.get_int(section, "SYNC_COUNTER_OVERFLOW", 0, {0, 240});
  if (overflow == 1) ini.fail(ini.find_entry(section, "SYNC_COUNTER_OVERFLOW"), "expected 0 (no counter) or 2..240");
  c.sync_overflow = static_cast<uint8_t>(overflow);
  c.cycle_ns = thread_period_ns;
  if (const ini::Entry* e = ini.find_entry(section, "SYNC_PERIOD_US")) {
    c.cycle_ns = ini.get_int(section, "SYNC_PERIOD_US", 1000, {100, 1e6}) * 1000;
    c.cycle_key = e->file + ":" + std::to_string(e->line) + ": [" + section + "]SYNC_PERIOD_US";
  }
  c.sdo_timeout_ns = ini.get_int(section, "SDO_TIMEOUT_MS", 500, {10, 60'000}) * 1'000'000;
  c.boot_timeout_ns = ini.get_int(section, "BOOT_TIMEOUT_MS", 5000, {10, 600'000}) * 1'000'000;
  c.reset_nodes = ini.get_bool(section, "RESET_NODES", true);
  c.start_all = ini.get_bool(section, "START_ALL_NODES", false);
  c.max_bus_load = ini.get_double(section, "MAX_BUS_LOAD", 80, {1, 100}) / 100.0;
  c.max_cycle_load = ini.get_double(section, "MAX_CYCLE_LOAD", 90, {1, 100}) / 100.0;
  c.plan_emcy_frames = static_cast<uint32_t>(ini.get_int(section, "EMCY_FRAMES_PER_CYCLE", 1, {0, 127}));
  c.plan_sdo_frames = static_cast<uint32_t>(ini.get_int(section, "SDO_FRAMES_PER_CYCLE", 2, {0, 100}));
  c.load_override = ini.get_bool(section, "LOAD_OVERRIDE", false);
  c.pdo_miss_limit = static_cast<uint32_t>(ini.get_int(section, "PDO_MISS_LIMIT", 3, {0, 1000}));

  std::vector<std::pair<uint8_t, const ini::Entry*>> ids;
  for (const ini::Entry* e : ini.find_all_entries(section, "NODE")) {
    for (const auto& w : split_blanks(e->value)) {
      const auto v = parse_uint(w);
      if (!v || !is_valid_node_id(static_cast<unsigned>(*v)) || *v > 127) ini.fail(e, "\"" + w + "\": expected node-IDs 1..127");
      ids.emplace_back(static_cast<uint8_t>(*v), e);
    }
  }
  if (ids.empty()) ini.fail(ini.find_entry(section, "INTERFACE"), "no NODE = <id> lines in [" + section + "]");

  for (const auto& [id, where] : ids) {
    NodeConfig n;
    n.id = id;
    const std::string ns = section + "_NODE_" + std::to_string(id);
    n.origin = "[" + ns + "]";
    if (!ini.has_section(ns)) ini.fail(where, "node " + std::to_string(id) + " has no [" + ns + "] section");
    n.name = ini.get_string(ns, "NAME", "");
    n.mandatory = ini.get_bool(ns, "MANDATORY", true);
    const ini::Entry* dcf = ini.find_entry(ns, "DCF");
    const ini::Entry* eds = ini.find_entry(ns, "EDS");
    if (dcf && eds) ini.fail(eds, "give DCF or EDS, not both (a DCF is an EDS with values)");
    if (dcf || eds) {
      const ini::Entry* file = dcf ? dcf : eds;
      auto d = std::make_shared<DeviceDescription>(load_eds(ini.resolve_path(file->value)));
      if (d->node_id && *d->node_id != id) {
        ini.fail(file, d->file + " is for node-ID " + std::to_string(*d->node_id) + " ([DeviceComissioning] NodeID)");
      }
      n.eds = d;
      if (d->vendor_number) n.vendor_id = d->vendor_number;
      if (d->product_number) n.product_code = d->product_number;
    }
    auto opt_u32 = [&](const char* key, std::optional<uint32_t>& out) {
      if (const ini::Entry* e = ini.find_entry(ns, key)) {
        const auto v = parse_uint(e->value);
        if (!v || *v > 0xFFFFFFFF) ini.fail(e, "expected an unsigned 32-bit number");
        out = static_cast<uint32_t>(*v);
      }
    };
    opt_u32("DEVICE_TYPE", n.device_type);
    opt_u32("VENDOR_ID", n.vendor_id);
    opt_u32("PRODUCT_CODE", n.product_code);
    opt_u32("REVISION", n.revision);
    opt_u32("SERIAL", n.serial);
    n.heartbeat_ms = static_cast<uint16_t>(ini.get_int(ns, "HEARTBEAT_MS", 100, {0, 65535}));
    n.heartbeat_timeout_ms = static_cast<uint16_t>(ini.get_int(ns, "HEARTBEAT_TIMEOUT_MS", 0, {0, 65535}));
    n.master_heartbeat_timeout_ms = static_cast<uint16_t>(ini.get_int(ns, "MASTER_HEARTBEAT_TIMEOUT_MS", 0, {0, 65535}));
    n.disable_unused_pdos = ini.get_bool(ns, "DISABLE_UNUSED_PDOS", true);
    {
      const std::string order = to_upper(trim(ini.get_string(ns, "TX_QUEUE", "PRIORITY")));
      if (order != "PRIORITY" && order != "FIFO") ini.fail(ini.find_entry(ns, "TX_QUEUE"), "expected PRIORITY or FIFO");
      n.tx_fifo = order == "FIFO";
    }
    n.sync_response_us = static_cast<uint32_t>(ini.get_int(ns, "SYNC_RESPONSE_US", 0, {0, 100000}));
    n.export_pins = ini.get_bool(ns, "EXPORT_PINS", false);

    for (bool tpdo : {false, true}) {
      for (unsigned number = 1; number <= 8; ++number) {
        const std::string key = std::string(tpdo ? "TPDO" : "RPDO") + std::to_string(number);
        const ini::Entry* m = ini.find_entry(ns, key);
        std::vector<ValueKind> kinds;
        std::optional<PdoConfig> p;
        if (m) {
          p = PdoConfig{};
          p->number = static_cast<uint16_t>(number);
          for (const auto& w : split_blanks(m->value)) {
            std::string err;
            const auto e = parse_map_entry(w, n.eds.get(), err);
            if (!e) ini.fail(m, err);
            p->map.push_back(e->entry);
            kinds.push_back(e->kind);
          }
          if (p->map.empty()) ini.fail(m, "no objects mapped");
        } else if (n.eds) {
          p = pdo_from_description(*n.eds, tpdo, number, id, kinds);
        }
        auto key_int = [&](const std::string& suffix, int64_t def, int64_t lo, int64_t hi) {
          const std::string k = key + "_" + suffix;
          const ini::Entry* e = ini.find_entry(ns, k);
          if (e && !p) ini.fail(e, key + " is not configured");
          return ini.get_int(ns, k, def, {static_cast<double>(lo), static_cast<double>(hi)});
        };
        const int64_t transmission = key_int("TRANSMISSION", p ? p->transmission : 1, 0, 255);
        const int64_t cob = key_int("COB_ID", p ? p->cob_id : 0, 0, 0x7FF);
        const int64_t event = key_int("EVENT_MS", p ? p->event_ms : 0, 0, 65535);
        const int64_t inhibit = tpdo ? key_int("INHIBIT_100US", p ? p->inhibit_100us : 0, 0, 65535) : 0;
        const int64_t start = tpdo ? key_int("SYNC_START", p ? p->sync_start : 0, 0, 240) : 0;
        const int64_t plan_interval = tpdo ? key_int("MIN_INTERVAL_US", 0, 0, 60'000'000) : 0;
        if (!p) continue;
        p->transmission = static_cast<uint8_t>(transmission);
        p->cob_id = static_cast<uint32_t>(cob);
        p->event_ms = static_cast<uint16_t>(event);
        p->inhibit_100us = static_cast<uint16_t>(inhibit);
        p->sync_start = static_cast<uint8_t>(start);
        p->plan_interval_us = static_cast<uint32_t>(plan_interval);
        (tpdo ? n.tpdos : n.rpdos).push_back(*p);
        (tpdo ? n.tpdo_kinds : n.rpdo_kinds).push_back(kinds);
      }
    }

    // A DCF's configured values, except what the keys above configure.
    if (n.eds && n.eds->is_dcf) {
      for (const EdsEntry& e : n.eds->entries) {
        if (e.parameter_value.empty() || !is_writable(e.access)) continue;
        if (is_pdo_object(e.addr.index) || e.addr.index == 0x1017 || e.addr.index == 0x1016) continue;
        SdoWrite w;
        w.addr = e.addr;
        w.data = n.eds->value_bytes(e, id, true);
        w.origin = n.eds->file + ":" + std::to_string(e.value_line);
        w.verify = e.access != Access::WriteOnly;
        n.sdo.push_back(std::move(w));
      }
      if (const EdsEntry* hb = n.eds->find({0x1017, 0}); hb && !hb->parameter_value.empty() && !ini.find_entry(ns, "HEARTBEAT_MS")) {
        const auto b = n.eds->value_bytes(*hb, id, true);
        n.heartbeat_ms = static_cast<uint16_t>(b[0] | (b.size() > 1 ? b[1] << 8 : 0));
      }
    }
    for (const ini::Entry* e : ini.find_all_entries(ns, "SDO")) {
      std::string err;
      auto w = parse_sdo_write(e->value, n.eds.get(), err);
      if (!w) ini.fail(e, err);
      w->origin = e->file + ":" + std::to_string(e->line);
      n.sdo.push_back(std::move(*w));
    }
    c.nodes.push_back(std::move(n));
  }
  try {
    c.validate();
  } catch (const std::runtime_error& e) {
    ini.fail(ini.find_entry(section, "INTERFACE"), e.what());
  }
  return c;
}

}  // namespace cnc::canopen
