#include "fieldbus/ethercat/config.hpp"

#include <set>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"
#include "fieldbus/canopen/config.hpp"

namespace cnc::ethercat {
namespace {

std::optional<uint32_t> hex_key(const ini::IniFile& ini, const std::string& section, const char* key) {
  const ini::Entry* e = ini.find_entry(section, key);
  if (!e) return std::nullopt;
  const int64_t v = ini.get_int(section, key, 0, {0, 4294967295.0});
  return static_cast<uint32_t>(v);
}

std::vector<PdoEntryConfig> pdo_entries(const ini::IniFile& ini, const ini::Entry* e) {
  std::vector<PdoEntryConfig> out;
  for (const auto& word : split_blanks(e->value)) {
    std::string error;
    const auto p = canopen::parse_map_entry(std::string(trim(word)), nullptr, error);
    if (!p) ini.fail(e, "\"" + std::string(word) + "\": " + error);
    out.push_back({p->entry.index, p->entry.sub, p->entry.bits});
  }
  if (out.size() > 8) ini.fail(e, std::to_string(out.size()) + " entries; a PDO of the simulated drive holds at most 8");
  return out;
}

}  // namespace

BusSettings load_bus_settings(const ini::IniFile& ini, const std::string& section, const std::string& name,
                              const std::function<int64_t(const std::string&)>& thread_period) {
  if (!ini.has_section(section)) ini.fail(nullptr, "no [" + section + "] section (the EtherCAT bus for " + name + ")");
  BusSettings b;
  MasterConfig& c = b.master;
  c.name = name;
  c.interface = ini.require_string(section, "INTERFACE");
  if (c.interface.rfind("raw:", 0) != 0 && c.interface.rfind("sim:", 0) != 0) {
    ini.fail(ini.find_entry(section, "INTERFACE"), "\"" + c.interface + "\": expected raw:<interface> or sim:<segment>");
  }
  b.thread = ini.get_string(section, "THREAD", "servo-thread");
  const int64_t thread_ns = thread_period ? thread_period(b.thread) : 0;
  c.cycle_ns = thread_ns > 0 ? thread_ns : 1'000'000;
  if (const ini::Entry* e = ini.find_entry(section, "CYCLE_US")) {
    c.cycle_ns = ini.get_int(section, "CYCLE_US", 1000, {100, 100'000}) * 1000;
    b.cycle_key = e->file + ":" + std::to_string(e->line) + ": [" + section + "]CYCLE_US";
  }
  c.miss_limit = static_cast<unsigned>(ini.get_int(section, "MISS_LIMIT", 3, {0, 100000}));
  c.dc = ini.get_bool(section, "DC", true);
  c.dc_lock = ini.get_bool(section, "DC_LOCK", true);
  const int64_t shift = ini.get_int(section, "SYNC0_SHIFT_US", -1, {-1, 100'000});
  c.sync0_shift_ns = shift < 0 ? -1 : shift * 1000;
  if (c.sync0_shift_ns >= c.cycle_ns) ini.fail(ini.find_entry(section, "SYNC0_SHIFT_US"), "must be shorter than the cycle");
  c.state_timeout_ms = ini.get_int(section, "STATE_TIMEOUT_MS", 3000, {10, 600'000});
  c.mailbox_timeout_ms = ini.get_int(section, "MAILBOX_TIMEOUT_MS", 1000, {10, 600'000});
  // The slaves' process-data watchdog: outputs that stop arriving for this
  // long take a slave to SAFEOP (0x001B) and its drive to its 0x6007
  // reaction. At least two cycles, so that one late frame never trips it.
  auto watchdog_key = [&](const std::string& s, uint32_t fallback) {
    const auto ms = static_cast<uint32_t>(ini.get_int(s, "WATCHDOG_MS", fallback, {0, 6000}));
    if (ms > 0 && int64_t{ms} * 1'000'000 < 2 * c.cycle_ns) {
      ini.fail(ini.find_entry(s, "WATCHDOG_MS"), std::to_string(ms) + " ms is shorter than two cycles (" +
                                                     std::to_string(2 * c.cycle_ns / 1000) + " us); 0 switches it off");
    }
    return ms;
  };
  c.watchdog_ms = watchdog_key(section, 100);

  std::set<unsigned> positions;
  for (const ini::Entry* e : ini.find_all_entries(section, "SLAVE")) {
    for (const auto& word : split_blanks(e->value)) {
      unsigned p = 0;
      try {
        p = static_cast<unsigned>(std::stoul(std::string(trim(word))));
      } catch (const std::exception&) {
        ini.fail(e, "\"" + std::string(word) + "\" is not a slave position (1, 2, ...)");
      }
      if (p < 1 || p > 65535) ini.fail(e, "slave position " + std::to_string(p) + " out of 1..65535");
      if (!positions.insert(p).second) ini.fail(e, "slave " + std::to_string(p) + " listed twice");
    }
  }
  for (unsigned p : positions) {
    const std::string s = section + "_SLAVE_" + std::to_string(p);
    SlaveConfig sc;
    sc.position = p;
    sc.name = ini.get_string(s, "NAME", "");
    sc.vendor_id = hex_key(ini, s, "VENDOR_ID");
    sc.product_code = hex_key(ini, s, "PRODUCT_CODE");
    sc.revision = hex_key(ini, s, "REVISION");
    if (const ini::Entry* e = ini.find_entry(s, "RXPDO")) sc.rx_pdo = pdo_entries(ini, e);
    if (const ini::Entry* e = ini.find_entry(s, "TXPDO")) sc.tx_pdo = pdo_entries(ini, e);
    sc.rx_pdo_index = static_cast<uint16_t>(ini.get_int(s, "RXPDO_INDEX", 0x1600, {0x1600, 0x17FF}));
    sc.tx_pdo_index = static_cast<uint16_t>(ini.get_int(s, "TXPDO_INDEX", 0x1A00, {0x1A00, 0x1BFF}));
    sc.sync0 = ini.get_bool(s, "SYNC0", true);
    sc.complete_access = ini.get_bool(s, "COMPLETE_ACCESS", false);
    sc.watchdog_ms = watchdog_key(s, c.watchdog_ms);
    if (const ini::Entry* e = ini.find_entry(s, "ESI")) sc.esi = ini.resolve_path(e->value).string();
    for (const ini::Entry* e : ini.find_all_entries(s, "SDO")) {
      std::string error;
      const auto w = canopen::parse_sdo_write(e->value, nullptr, error);
      if (!w) ini.fail(e, error);
      sc.sdos.push_back({w->addr.index, w->addr.sub, w->data, e->file + ":" + std::to_string(e->line)});
    }
    c.slaves.push_back(std::move(sc));
  }
  return b;
}

}  // namespace cnc::ethercat
