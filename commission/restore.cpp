#include "commission/restore.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <map>
#include <stdexcept>

#include "commission/backup.hpp"
#include "fieldbus/canopen/sdo_client.hpp"
#include "fieldbus/ethercat/master.hpp"

namespace cnc::commission {

namespace co = cnc::canopen;
using D = co::DataType;

namespace {

constexpr uint32_t kAbortTimeout = 0x05040000;
constexpr uint32_t kAbortReadOnly = 0x06010002;

std::string trim(std::string s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08X", v);
  return b;
}

// "0x6099:01" for people.
std::string addr_text(const co::ObjectAddress& a) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%04X:%02X", a.index, a.sub);
  return b;
}

bool is_hex(char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; }

// "6099sub1" or "6098": the object of a section name; nullopt for others.
std::optional<co::ObjectAddress> object_section(const std::string& name) {
  const std::string n = lower(name);
  const auto sub = n.find("sub");
  const std::string index = n.substr(0, sub);
  if (index.empty() || index.size() > 4 || !std::all_of(index.begin(), index.end(), is_hex)) return std::nullopt;
  co::ObjectAddress a;
  a.index = static_cast<uint16_t>(std::stoul(index, nullptr, 16));
  if (sub != std::string::npos) {
    const std::string s = n.substr(sub + 3);
    if (s.empty() || s.size() > 2 || !std::all_of(s.begin(), s.end(), is_hex)) return std::nullopt;
    a.sub = static_cast<uint8_t>(std::stoul(s, nullptr, 16));
  }
  return a;
}

// "PRE-OPERATIONAL (0x7F)" for people; a boot-up message says it reset.
std::string nmt_text(uint8_t b) {
  char h[8];
  std::snprintf(h, sizeof h, "0x%02X", b);
  switch (b & 0x7F) {
    case 0x00: return std::string("boot-up (") + h + "): it reset";
    case 0x04: return std::string("STOPPED (") + h + ")";
    case 0x05: return std::string("OPERATIONAL (") + h + ")";
    case 0x7F: return std::string("PRE-OPERATIONAL (") + h + ")";
    default: return std::string("the state byte ") + h + ", not a CiA 301 state";
  }
}

class CanopenChannel final : public DriveChannel {
 public:
  CanopenChannel(can::Transport& bus, int node, int64_t timeout_ns, int64_t nmt_timeout_ns)
      : bus_(bus), node_(static_cast<uint8_t>(node)), nmt_timeout_ns_(nmt_timeout_ns) {
    co::SdoClientOptions o;
    o.timeout_ns = timeout_ns;
    sdo_ = std::make_unique<co::SdoClient>(bus, static_cast<uint8_t>(node), o);
  }
  Result upload(co::ObjectAddress a) override {
    Result r;
    sdo_->upload(a, [&r](const co::SdoResult& s) { take(s, r); });
    run();
    return r;
  }
  Result download(co::ObjectAddress a, const std::vector<uint8_t>& data) override {
    Result r;
    sdo_->download(a, data, [&r](const co::SdoResult& s) { take(s, r); });
    run();
    return r;
  }
  // NMT is unconfirmed (CiA 301): the node's heartbeat or its answer to
  // node guarding says whether it followed.
  Result prepare_for_writes(std::string& done) override {
    Result r;
    const Result hb = upload({0x1017, 0});
    heartbeat_ms_ = hb.ok && hb.data.size() >= 2 ? static_cast<int>(hb.data[0] | (hb.data[1] << 8)) : 0;
    drain();
    const int64_t sent_ns = bus_.now_ns();
    if (!send(can::Frame::make(co::cob::kNmt, {static_cast<uint8_t>(co::NmtCommand::EnterPreOperational), node_}))) {
      r.error = "the NMT command Enter Pre-Operational could not be sent on " + bus_.name();
      return r;
    }
    std::string seen;
    r = expect_pre_operational(seen);
    if (!r.ok) {
      r.error = "NMT Enter Pre-Operational sent, but " + r.error;
      return r;
    }
    char ms[32];
    std::snprintf(ms, sizeof ms, "%.0f ms", (bus_.now_ns() - sent_ns) / 1e6);
    done = "NMT Enter Pre-Operational sent before writing, and the node reported " + seen + " " + ms +
           " later: it is left in PRE-OPERATIONAL (the controller's master starts it; nothing else does)";
    return r;
  }
  Result report_state(std::string& state) override {
    drain();
    return expect_pre_operational(state);
  }

 private:
  static void take(const co::SdoResult& s, Result& r) {
    r.ok = s.ok();
    r.data = s.data;
    r.abort_code = s.aborted_by_client ? 0 : s.abort_code;
    r.silent = s.aborted_by_client && s.abort_code == kAbortTimeout;
    if (!s.ok()) r.error = s.abort_text();
  }
  bool send(const can::Frame& f) {
    can::SendStatus st = bus_.send(f);
    for (int i = 0; i < 100 && st == can::SendStatus::WouldBlock; ++i) {  // a full queue drains in a few ms
      bus_.wait(1'000'000);
      st = bus_.send(f);
    }
    return st == can::SendStatus::Ok;
  }
  void drain() {
    can::Frame f;
    while (bus_.receive(f)) {
    }
  }
  // Waits for the node to report PRE-OPERATIONAL: its heartbeat when it
  // produces one (0x1017 > 0; CiA 301: node guarding is then not used),
  // else node guarding, an RTR every 100 ms. A report of another state is
  // remembered and the wait goes on (a heartbeat sent before the command
  // took effect); at the time-out the last report is the error.
  Result expect_pre_operational(std::string& seen) {
    Result r;
    const uint32_t ec = co::cob::heartbeat(node_);
    const bool by_heartbeat = heartbeat_ms_ > 0;
    const int64_t window = std::max<int64_t>(nmt_timeout_ns_, int64_t{3} * heartbeat_ms_ * 1'000'000);
    const int64_t start = bus_.now_ns(), end = start + window;
    int64_t next_rtr = start;
    std::string last;
    for (int64_t now = start; now < end; now = bus_.now_ns()) {
      if (!by_heartbeat && now >= next_rtr) {
        send(can::Frame::remote(ec, 1));
        next_rtr = now + 100'000'000;
      }
      can::Frame f;
      while (bus_.receive(f)) {
        if (f.id != ec || f.is_error() || f.is_remote() || f.is_extended() || f.len != 1) continue;
        const uint8_t state = by_heartbeat ? f.data[0] : static_cast<uint8_t>(f.data[0] & 0x7F);
        char via[48];
        std::snprintf(via, sizeof via, " (%s 0x%03X)", by_heartbeat ? "heartbeat" : "node guarding answer", ec);
        if (state == 0x7F) {
          seen = "PRE-OPERATIONAL" + std::string(via);
          r.ok = true;
          return r;
        }
        last = nmt_text(state) + via;
      }
      bus_.wait(std::min<int64_t>(end - now, 10'000'000));
    }
    char ms[32];
    std::snprintf(ms, sizeof ms, "%.0f ms", window / 1e6);
    char ec_text[8];
    std::snprintf(ec_text, sizeof ec_text, "0x%03X", ec);
    if (!last.empty())
      r.error = "it reported " + last + ", not PRE-OPERATIONAL, within " + ms;
    else if (by_heartbeat)
      r.error = "no heartbeat (" + std::string(ec_text) + ", every " + std::to_string(heartbeat_ms_) + " ms by its 0x1017) within " + ms;
    else
      r.error = "no heartbeat (its 0x1017 is 0) and no answer to node guarding (RTR on " + std::string(ec_text) + ") within " + ms;
    r.error += ": its NMT state is not confirmed";
    return r;
  }
  void run() {
    while (!sdo_->idle()) {
      can::Frame f;
      while (bus_.receive(f)) {
        if (f.id == sdo_->response_cob() && !f.is_error() && !f.is_remote()) sdo_->on_frame(f, bus_.now_ns());
      }
      sdo_->poll(bus_.now_ns());
      if (sdo_->idle()) break;
      bus_.wait(1'000'000);
    }
  }
  can::Transport& bus_;
  uint8_t node_;
  int64_t nmt_timeout_ns_;
  int heartbeat_ms_ = 0;
  std::unique_ptr<co::SdoClient> sdo_;
};

class EthercatChannel final : public DriveChannel {
 public:
  EthercatChannel(ethercat::Master& m, unsigned position) : m_(m), position_(position) {}
  Result upload(co::ObjectAddress a) override { return take(m_.sdo_upload(position_, a.index, a.sub)); }
  Result download(co::ObjectAddress a, const std::vector<uint8_t>& data) override {
    return take(m_.sdo_download(position_, a.index, a.sub, data));
  }

 private:
  static Result take(const ethercat::SdoResult& s) {
    Result r;
    r.ok = s.ok;
    r.data = s.data;
    r.abort_code = s.abort_code;
    r.silent = !s.ok && s.abort_code == 0;
    r.error = s.error;
    return r;
  }
  ethercat::Master& m_;
  unsigned position_;
};

}  // namespace

std::unique_ptr<DriveChannel> canopen_channel(can::Transport& bus, int node, int64_t timeout_ns, int64_t nmt_timeout_ns) {
  return std::make_unique<CanopenChannel>(bus, node, timeout_ns, nmt_timeout_ns);
}
std::unique_ptr<DriveChannel> ethercat_channel(ethercat::Master& master, unsigned position) {
  return std::make_unique<EthercatChannel>(master, position);
}

const BackupEntry* BackupFile::find(uint16_t index, uint8_t sub) const noexcept {
  for (const BackupEntry& e : entries)
    if (e.addr.index == index && e.addr.sub == sub) return &e;
  return nullptr;
}

std::string BackupFile::label() const {
  std::string s = slave ? "EtherCAT slave " + std::to_string(slave) : "node " + std::to_string(node);
  s += " (";
  if (axis) s += std::string("axis ") + axis + ", ";
  return s + path.filename().string() + ")";
}

BackupFile load_backup_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot be read (no such file?)");
  BackupFile f;
  f.path = file;
  auto fail = [&](int line, const std::string& what) {
    throw std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + what);
  };
  enum class In { Nothing, Device, Missing, Object } where = In::Nothing;
  BackupEntry cur;
  std::optional<uint16_t> type_code;
  bool has_value = false;
  std::map<co::ObjectAddress, int> seen;
  auto finish = [&] {
    if (where != In::Object) return;
    if (!type_code) fail(cur.line, "section [" + addr_text(cur.addr) + "] has no DataType");
    if (!co::is_known_data_type(*type_code))
      fail(cur.line, "DataType " + hex32(*type_code) + " of " + addr_text(cur.addr) + " is not a CiA 301 data type");
    if (!has_value) fail(cur.line, "section of " + addr_text(cur.addr) + " has no ParameterValue");
    cur.type = static_cast<D>(*type_code);
    if (cur.type != D::VisibleString) cur.value = trim(cur.value);  // only a string keeps its spaces
    const auto data = parse_backup_value(cur.type, cur.value);
    if (!data)
      fail(cur.line, "ParameterValue \"" + cur.value + "\" of " + addr_text(cur.addr) + " is not a value of type " +
                         co::to_string(cur.type));
    cur.data = *data;
    f.entries.push_back(cur);
  };
  std::string raw;
  int line = 0;
  bool has_id = false;
  while (std::getline(in, raw)) {
    ++line;
    const std::string t = trim(raw);
    if (t.empty() || t[0] == ';' || t[0] == '#') continue;
    if (t[0] == '[') {
      finish();
      if (t.back() != ']') fail(line, "\"" + t + "\": a section header without its ']'");
      const std::string name = t.substr(1, t.size() - 2);
      if (lower(name) == "devicecomissioning" || lower(name) == "devicecommissioning") {
        where = In::Device;
      } else if (lower(name) == "missing") {
        where = In::Missing;
      } else if (const auto a = object_section(name)) {
        if (seen.count(*a)) fail(line, "object " + addr_text(*a) + " twice (first at line " + std::to_string(seen[*a]) + ")");
        seen[*a] = line;
        where = In::Object;
        cur = BackupEntry{};
        cur.addr = *a;
        cur.line = line;
        type_code.reset();
        has_value = false;
      } else {
        fail(line, "section [" + name + "]: expected [DeviceComissioning], [Missing] or an object ([6065], [6099sub1])");
      }
      continue;
    }
    const auto eq = t.find('=');
    if (eq == std::string::npos) fail(line, "\"" + t + "\": expected KEY=VALUE or a [section]");
    if (where == In::Nothing) fail(line, "\"" + t + "\" before any [section]");
    const std::string key = lower(trim(t.substr(0, eq)));
    // The value keeps its spaces (a string parameter), only the line end is cut.
    std::string value = raw.substr(raw.find('=') + 1);
    while (!value.empty() && (value.back() == '\r' || value.back() == '\n')) value.pop_back();
    if (where == In::Device) {
      const std::string v = trim(value);
      try {
        std::size_t used = 0;
        if (key == "nodeid") {
          const unsigned long n = std::stoul(v, &used, 0);
          if (used != v.size() || n < 1 || n > 127) throw std::invalid_argument(v);
          f.node = static_cast<int>(n);
          has_id = true;
        } else if (key == "ethercatslave") {
          const unsigned long n = std::stoul(v, &used, 0);
          if (used != v.size() || n < 1 || n > 65535) throw std::invalid_argument(v);
          f.slave = static_cast<unsigned>(n);
          has_id = true;
        }
      } catch (const std::exception&) {
        fail(line, key + " \"" + v + "\": expected a node-ID 1-127 (NodeID) or a slave position (EtherCATSlave)");
      }
      if (key == "nodename" && v.size() >= 6 && lower(v.substr(1)) == "-axis")
        f.axis = static_cast<char>(std::toupper(static_cast<unsigned char>(v[0])));
    } else if (where == In::Object) {
      if (key == "parametervalue") {
        cur.value = value;
        if (cur.value.find_first_not_of(' ') == std::string::npos) cur.value.clear();
        has_value = true;
      } else if (key == "datatype") {
        const std::string v = trim(value);
        try {
          std::size_t used = 0;
          const unsigned long c = std::stoul(v, &used, 0);
          if (used != v.size() || c > 0xFFFF) throw std::invalid_argument(v);
          type_code = static_cast<uint16_t>(c);
        } catch (const std::exception&) {
          fail(line, "DataType \"" + v + "\": expected a number (0x0007)");
        }
      } else if (key == "parametername") {
        cur.name = trim(value);
      } else if (key == "accesstype") {
        cur.access = lower(trim(value));
      }
    }
  }
  finish();
  if (!has_id) fail(line, "no [DeviceComissioning] NodeID= or EtherCATSlave=: whose backup is it?");
  if (f.node && f.slave) fail(line, "both NodeID and EtherCATSlave: one drive per file");
  for (uint8_t sub = 1; sub <= 3; ++sub)
    if (!f.find(0x1018, sub))
      fail(line, "no identity " + addr_text({0x1018, sub}) +
                     " ([1018sub" + std::to_string(sub) + "]): the drive cannot be checked against it");
  return f;
}

std::vector<BackupFile> load_backup_dir(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw std::runtime_error(dir.string() + ": not a folder (no backup there?)");
  std::vector<std::filesystem::path> paths;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    if (lower(e.path().extension().string()) == ".dcf") paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  if (paths.empty()) throw std::runtime_error(dir.string() + ": no backup files (*.dcf): take one with cnc-commission backup");
  std::vector<BackupFile> out;
  for (const auto& p : paths) out.push_back(load_backup_file(p));
  return out;
}

bool restorable(const BackupEntry& e) noexcept {
  return e.addr.index >= 0x2000 && e.addr.index <= 0x9FFF && e.access != "ro" && e.access != "const";
}

bool pdo_entry(const BackupEntry& e) noexcept {
  const uint16_t i = e.addr.index;
  return ((i >= 0x1400 && i <= 0x1BFF) || i == 0x1C12 || i == 0x1C13) && e.access != "ro" && e.access != "const";
}

namespace {

// The PDO configuration of one drive written back in order (see
// DriveRestore::pdo_changes); each write logged in d.pdo_steps. Returns
// false with a problem in `r` at the first refused write.
bool restore_pdos(DriveRestore& d, DriveChannel& c, RestoreResult& r, std::vector<co::ObjectAddress>& written,
                  bool& silent) {
  const BackupFile& f = d.file;
  const std::string who = f.label();
  const auto write = [&](co::ObjectAddress a, const std::vector<uint8_t>& data, const std::string& why) {
    const DriveChannel::Result w = c.download(a, data);
    std::string v;
    for (std::size_t i = data.size(); i-- > 0;) {
      char b[4];
      std::snprintf(b, sizeof b, "%02X", data[i]);
      v += b;
    }
    const std::string step = addr_text(a) + " = 0x" + v + " (" + why + ")";
    d.pdo_steps.push_back(step + (w.ok ? "" : ": refused, " + w.error));
    if (w.ok) {
      if (std::find(written.begin(), written.end(), a) == written.end()) written.push_back(a);
    } else {
      d.stopped = "writing " + step + ": " + w.error;
      silent = w.silent;
      r.problems.push_back(who + ": restoring the PDO configuration, writing " + addr_text(a) + " (" + why + ") failed: " + w.error);
    }
    return w.ok;
  };
  const auto differs = [&d](uint16_t index) {
    return std::any_of(d.pdo_changes.begin(), d.pdo_changes.end(),
                       [index](const RestoreChange& k) { return k.entry.addr.index == index; });
  };
  // A mapping: sub-index 0 to 0, the backup's entries, sub-index 0.
  const auto mapping = [&](uint16_t map) {
    const BackupEntry* count = f.find(map, 0);
    if (!count || count->data.empty()) return true;
    if (!write({map, 0}, {0}, "mapping off")) return false;
    for (uint8_t k = 1; k <= count->data[0]; ++k) {
      const BackupEntry* e = f.find(map, k);
      if (!e) {
        d.stopped = "the backup's " + addr_text({map, 0}) + " announces " + std::to_string(count->data[0]) +
                    " entries but has no " + addr_text({map, k});
        r.problems.push_back(who + ": " + d.stopped);
        return false;
      }
      if (!write(e->addr, e->data, "mapping entry")) return false;
    }
    return write({map, 0}, count->data, "mapping on");
  };
  if (f.slave) {  // EtherCAT, in PREOP: the assignments emptied first
    bool any = false;
    for (const RestoreChange& k : d.pdo_changes) any = any || k.entry.addr.index >= 0x1600;
    if (!any) return true;
    for (uint16_t sm : {uint16_t{0x1C12}, uint16_t{0x1C13}})
      if (f.find(sm, 0) && !write({sm, 0}, {0}, "assignment off")) return false;
    for (uint16_t map = 0x1600; map <= 0x1BFF; ++map)
      if (differs(map) && !mapping(map)) return false;
    for (uint16_t sm : {uint16_t{0x1C12}, uint16_t{0x1C13}}) {
      const BackupEntry* count = f.find(sm, 0);
      if (!count || count->data.empty()) continue;
      for (uint8_t k = 1; k <= count->data[0]; ++k)
        if (const BackupEntry* e = f.find(sm, k); e && !write(e->addr, e->data, "assigned PDO")) return false;
      if (!write({sm, 0}, count->data, "assignment on")) return false;
    }
    return true;
  }
  // CANopen: each PDO whose communication or mapping differs, disabled
  // while its mapping is written (CiA 301 7.5.2.36), enabled by its COB-ID.
  for (bool tpdo : {false, true}) {
    for (uint16_t n = 0; n < 0x200; ++n) {
      const uint16_t comm = static_cast<uint16_t>((tpdo ? 0x1800 : 0x1400) + n);
      const uint16_t map = static_cast<uint16_t>((tpdo ? 0x1A00 : 0x1600) + n);
      if (!differs(comm) && !differs(map)) continue;
      const BackupEntry* cob = f.find(comm, 1);
      if (!cob || cob->data.size() < 4) {
        d.stopped = "the backup has no COB-ID " + addr_text({comm, 1}) + " for " + addr_text({map, 0}) +
                    ": the PDO cannot be disabled to restore it";
        r.problems.push_back(who + ": " + d.stopped);
        return false;
      }
      const DriveChannel::Result now = c.upload({comm, 1});
      if (!now.ok || now.data.size() < 4) {
        d.stopped = "reading " + addr_text({comm, 1}) + " to disable the PDO: " + now.error;
        silent = now.silent;
        r.problems.push_back(who + ": " + addr_text({comm, 1}) + " cannot be read: " + now.error);
        return false;
      }
      std::vector<uint8_t> off = now.data;
      off[3] |= 0x80;  // bit 31: PDO not valid
      if (!write({comm, 1}, off, "PDO off")) return false;
      if (differs(map) && !mapping(map)) return false;
      for (const RestoreChange& k : d.pdo_changes)
        if (k.entry.addr.index == comm && k.entry.addr.sub != 1 && !write(k.entry.addr, k.entry.data, "communication parameter"))
          return false;
      if (!write({comm, 1}, cob->data, "the backup's COB-ID")) return false;
    }
  }
  return true;
}

// Store parameters (CiA 301 0x1010:1): bit 0 of its value says the drive
// stores on command.
void store(DriveRestore& d, DriveChannel& c, RestoreResult& r) {
  const DriveChannel::Result cap = c.upload({0x1010, 1});
  if (cap.ok && !cap.data.empty() && (cap.data[0] & 1)) {
    const DriveChannel::Result st = c.download({0x1010, 1}, {'s', 'a', 'v', 'e'});
    if (st.ok) d.notes.push_back("stored in the drive (0x1010:01 \"save\")");
    else r.problems.push_back(d.file.label() + ": storing the parameters (0x1010:01 \"save\") failed: " + st.error);
  } else {
    d.notes.push_back("not stored: the drive has no \"store parameters\" (0x1010:01); the values hold until it is "
                      "switched off unless it stores them its own way");
  }
}

// What the backup lacks to rewrite the PDOs whose entries differ (found
// before anything is written, not half-way through a PDO): a CANopen PDO's
// COB-ID (to disable and enable it), a mapping entry its sub-index 0 counts.
std::vector<std::string> pdo_backup_gaps(const DriveRestore& d) {
  std::vector<std::string> gaps;
  const BackupFile& f = d.file;
  std::vector<uint16_t> seen;
  for (const RestoreChange& k : d.pdo_changes) {
    const uint16_t i = k.entry.addr.index;
    if (std::find(seen.begin(), seen.end(), i) != seen.end()) continue;
    seen.push_back(i);
    const bool comm = i >= 0x1400 && i <= 0x15FF ? true : i >= 0x1800 && i <= 0x19FF;
    const bool map = (i >= 0x1600 && i <= 0x17FF) || (i >= 0x1A00 && i <= 0x1BFF);
    if (!f.slave && (comm || map)) {
      const uint16_t c = comm ? i : static_cast<uint16_t>(i - 0x200);
      const BackupEntry* cob = f.find(c, 1);
      if (!cob || cob->data.size() < 4)
        gaps.push_back("the backup has no COB-ID " + addr_text({c, 1}) + " (line of " + addr_text(k.entry.addr) + ": " +
                       std::to_string(k.entry.line) + "): the PDO cannot be disabled to restore it");
    }
    const uint16_t m = map ? i : comm ? static_cast<uint16_t>(i + 0x200) : 0;
    const BackupEntry* count = m ? f.find(m, 0) : nullptr;
    if (count && !count->data.empty())
      for (uint8_t s = 1; s <= count->data[0]; ++s)
        if (!f.find(m, s)) {
          gaps.push_back("the backup's " + addr_text({m, 0}) + " (line " + std::to_string(count->line) + ") counts " +
                         std::to_string(count->data[0]) + " entries but has no " + addr_text({m, s}));
          break;
        }
  }
  return gaps;
}

// The drive's state after the restore stopped on it, as read from it.
std::vector<std::string> state_left(DriveChannel& c, const std::vector<co::ObjectAddress>& written, const BackupFile& f,
                                    bool silent) {
  std::vector<std::string> left;
  if (silent) {
    left.push_back("it stopped answering: its state is not known (the writes listed as done were confirmed by it)");
    return left;
  }
  std::string state;
  const DriveChannel::Result st = c.report_state(state);
  if (!st.ok) left.push_back("NMT state: " + st.error);
  else if (!state.empty()) left.push_back("NMT state: " + state);
  for (const co::ObjectAddress& a : written) {
    const DriveChannel::Result b = c.upload(a);
    std::string v = "?";
    if (b.ok) {
      const BackupEntry* e = f.find(a.index, a.sub);
      v = backup_value_text(e ? e->type : b.data.size() == 1 ? D::Unsigned8 : D::Unsigned32, b.data);
    }
    std::string what = addr_text(a) + " = " + (b.ok ? v : "? (" + b.error + ")");
    const uint16_t i = a.index;
    if (a.sub == 1 && ((i >= 0x1400 && i <= 0x15FF) || (i >= 0x1800 && i <= 0x19FF)) && b.ok && b.data.size() == 4)
      what += (b.data[3] & 0x80) ? " (the PDO is disabled)" : " (the PDO is enabled)";
    if (a.sub == 0 && ((i >= 0x1600 && i <= 0x17FF) || (i >= 0x1A00 && i <= 0x1BFF) || i == 0x1C12 || i == 0x1C13) &&
        b.ok && b.data.size() == 1 && b.data[0] == 0)
      what += i >= 0x1C12 ? " (no PDO assigned)" : " (nothing mapped)";
    left.push_back(what);
  }
  left.push_back("not stored: \"store parameters\" (0x1010:01) was not sent; what was written holds until the drive is "
                 "switched off, then its stored parameters come back");
  return left;
}

}  // namespace

RestoreResult restore_drives(const std::vector<BackupFile>& files,
                             const std::function<std::unique_ptr<DriveChannel>(const BackupFile&, std::string&)>& open,
                             bool dry_run) {
  RestoreResult r;
  r.dry_run = dry_run;
  // Two files for one drive would write it twice, in an order nobody chose.
  for (std::size_t i = 0; i < files.size(); ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (files[i].node == files[j].node && files[i].slave == files[j].slave)
        r.problems.push_back(files[i].path.string() + " and " + files[j].path.string() +
                             " are backups of the same drive: restore one of them");
  if (!r.ok()) return r;
  std::vector<std::unique_ptr<DriveChannel>> ch;
  // Phase 1, nothing written: each drive answers, is the backed-up drive,
  // has every parameter; the changes.
  for (const BackupFile& f : files) {
    DriveRestore d;
    d.file = f;
    std::string why;
    std::unique_ptr<DriveChannel> c = open(f, why);
    const std::string who = f.label();
    auto add = [&] {
      r.drives.push_back(std::move(d));
      ch.push_back(std::move(c));
    };
    if (!c) {
      r.problems.push_back(who + ": " + why);
      add();
      continue;
    }
    bool silent = false, other = false;
    for (uint8_t sub = 1; sub <= 4 && !silent; ++sub) {
      const BackupEntry* e = f.find(0x1018, sub);
      if (!e) continue;
      const DriveChannel::Result res = c->upload({0x1018, sub});
      if (res.silent) {
        silent = true;
        r.problems.push_back(who + " does not answer (" + res.error +
                             "): check its power, the cable, its address (node-ID or position); nothing was written");
      } else if (!res.ok) {
        r.problems.push_back(who + ": its identity " + addr_text(e->addr) + " cannot be read: " + res.error +
                             "; nothing was written");
        other = true;
      } else if (backup_value_text(e->type, res.data) != backup_value_text(e->type, e->data)) {
        if (sub == 4) {
          d.notes.push_back("serial number " + backup_value_text(e->type, res.data) + ", the backup's " + e->value +
                            ": a drive of the same type in its place");
          continue;
        }
        other = true;
      }
    }
    if (other && !silent) {
      std::string now, was;
      for (uint8_t sub = 1; sub <= 3; ++sub) {
        const DriveChannel::Result res = c->upload({0x1018, sub});
        const char* what = sub == 1 ? "vendor " : sub == 2 ? " product " : " revision ";
        now += what + (res.ok ? backup_value_text(D::Unsigned32, res.data) : std::string("?"));
        was += what + f.find(0x1018, sub)->value;
      }
      r.problems.push_back(who + " is another drive: " + now + ", the backup's " + was +
                           ": put the backed-up drive there or restore its own backup; nothing was written");
    }
    if (silent || other) {
      add();
      continue;
    }
    for (const BackupEntry& e : f.entries) {
      const bool pdo = pdo_entry(e);
      if (!restorable(e) && !pdo) continue;
      const DriveChannel::Result res = c->upload(e.addr);
      if (res.silent) {
        r.problems.push_back(who + " stopped answering (" + res.error + ") reading " + addr_text(e.addr) +
                             "; nothing was written");
        break;
      }
      if (!res.ok) {
        r.problems.push_back(who + ": " + addr_text(e.addr) + " " + e.name + " (line " + std::to_string(e.line) +
                             ") cannot be read from the drive: " + res.error + "; nothing was written");
        continue;
      }
      const std::string now = backup_value_text(e.type, res.data);
      if (now == backup_value_text(e.type, e.data)) {
        ++d.unchanged;
      } else {
        RestoreChange k;
        k.entry = e;
        k.now = now;
        (pdo ? d.pdo_changes : d.changes).push_back(k);
      }
    }
    for (const std::string& gap : pdo_backup_gaps(d)) r.problems.push_back(who + ": " + gap + "; nothing was written");
    d.checked = true;
    add();
  }
  if (!r.ok() || dry_run) return r;

  // Phase 2: the writes, each read back. A refused write (other than "read
  // only") stops the restore: that drive is not stored, its state is read
  // and said, the drives after it are not written.
  bool stop = false;
  for (std::size_t i = 0; i < r.drives.size(); ++i) {
    DriveRestore& d = r.drives[i];
    DriveChannel& c = *ch[i];
    const std::string who = d.file.label();
    if (d.changes.empty() && d.pdo_changes.empty()) continue;  // left as it is, in its NMT state too
    if (stop) {
      d.not_reached = true;
      continue;
    }
    const std::size_t problems_before = r.problems.size();
    std::string prepared;
    if (const DriveChannel::Result p = c.prepare_for_writes(prepared); !p.ok) {
      r.problems.push_back(who + ": " + p.error + "; nothing was written to it");
      stop = true;
      continue;
    }
    if (!prepared.empty()) d.notes.push_back(prepared);
    std::vector<co::ObjectAddress> written;
    bool silent = false;
    for (RestoreChange& k : d.changes) {
      const DriveChannel::Result w = c.download(k.entry.addr, k.entry.data);
      if (!w.ok && w.abort_code == kAbortReadOnly) {
        k.note = "read-only in this drive: left at " + k.now;
        continue;
      }
      if (!w.ok) {
        d.stopped = "writing " + addr_text(k.entry.addr) + " " + k.entry.name + " = " + k.entry.value + ": " + w.error;
        silent = w.silent;
        r.problems.push_back(who + ": " + d.stopped);
        break;
      }
      k.written = true;
      written.push_back(k.entry.addr);
      const DriveChannel::Result b = c.upload(k.entry.addr);
      if (!b.ok) {
        r.problems.push_back(who + ": " + addr_text(k.entry.addr) + " cannot be read back after writing it: " + b.error);
        continue;
      }
      k.read_back = backup_value_text(k.entry.type, b.data);
      if (k.read_back != backup_value_text(k.entry.type, k.entry.data))
        r.problems.push_back(who + ": " + addr_text(k.entry.addr) + " " + k.entry.name + " reads back as " + k.read_back +
                             " after writing " + k.entry.value);
    }
    if (d.stopped.empty() && !d.pdo_changes.empty()) {
      const bool done = restore_pdos(d, c, r, written, silent);
      for (RestoreChange& k : d.pdo_changes) {
        if (silent) break;
        const DriveChannel::Result b = c.upload(k.entry.addr);
        k.read_back = b.ok ? backup_value_text(k.entry.type, b.data) : "?";
        k.written = done && b.ok && k.read_back == backup_value_text(k.entry.type, k.entry.data);
        if (done && !k.written)
          r.problems.push_back(who + ": " + addr_text(k.entry.addr) + " " + k.entry.name + " reads back as " + k.read_back +
                               " after restoring the PDO configuration, the backup's " + k.entry.value);
      }
    }
    if (!d.stopped.empty()) {
      stop = true;
      d.left = state_left(c, written, d.file, silent);
      std::string after;
      for (std::size_t j = i + 1; j < r.drives.size(); ++j)
        if (!r.drives[j].changes.empty() || !r.drives[j].pdo_changes.empty())
          after += (after.empty() ? "" : ", ") + r.drives[j].file.label();
      r.problems.back() += "; the restore stopped there: " + std::to_string(written.size()) +
                           " object(s) of this drive were written before it, it is not stored" +
                           (after.empty() ? "" : "; not written at all: " + after) + " (what it is left as: its \"left as\" lines)";
      continue;
    }
    if (written.empty() && d.pdo_changes.empty()) continue;
    if (r.problems.size() != problems_before) {
      d.notes.push_back("not stored: a value did not read back as written (above); \"store parameters\" "
                        "(0x1010:01) was not sent");
    } else {
      store(d, c, r);
    }
    // The NMT state it is left in, as it reports it (a drive that reset
    // after the writes or the store says so here).
    std::string state;
    if (const DriveChannel::Result st = c.report_state(state); !st.ok)
      r.problems.push_back(who + ": after the writes " + st.error);
    else if (!state.empty())
      d.notes.push_back("after the writes it reports " + state);
  }
  return r;
}

std::string other_master_traffic(can::Transport& bus, int64_t window_ns) {
  can::Frame f;
  while (bus.receive(f)) {
  }
  std::map<uint32_t, int> seen;  // identifier -> frames
  const int64_t end = bus.now_ns() + window_ns;
  for (int64_t now = bus.now_ns(); now < end; now = bus.now_ns()) {
    while (bus.receive(f)) {
      if (f.is_error() || f.is_extended()) continue;
      const uint32_t id = f.id, node = id & 0x7F, fn = id & 0x780;
      const bool nmt = id == co::cob::kNmt, sync = id == co::cob::kSync;
      const bool rpdo = node != 0 && (fn == 0x200 || fn == 0x300 || fn == 0x400 || fn == 0x500);
      const bool sdo_request = node != 0 && fn == co::cob::kSdoRxBase;
      if (nmt || sync || rpdo || sdo_request) ++seen[id];
    }
    bus.wait(std::min<int64_t>(end - now, 10'000'000));
  }
  std::string o;
  for (const auto& [id, n] : seen) {
    char b[64];
    if (id == co::cob::kNmt) std::snprintf(b, sizeof b, "NMT (0x000)");
    else if (id == co::cob::kSync) std::snprintf(b, sizeof b, "SYNC (0x080)");
    else if ((id & 0x780) == co::cob::kSdoRxBase) std::snprintf(b, sizeof b, "SDO request to node %u (0x%03X)", id & 0x7F, id);
    else std::snprintf(b, sizeof b, "RPDO 0x%03X", id);
    o += (o.empty() ? "" : ", ") + std::string(b) + " x" + std::to_string(n);
  }
  return o;
}

RestoreResult restore_drives(const std::vector<BackupFile>& files, const RestoreBuses& buses, bool dry_run) {
  // Another master on the bus (another instance, another host) would go on
  // with the old values, and its SDO traffic would meet ours.
  const bool on_can = std::any_of(files.begin(), files.end(), [](const BackupFile& f) { return f.slave == 0; });
  if (!dry_run && on_can && buses.can && buses.listen_ns > 0) {
    if (const std::string seen = other_master_traffic(*buses.can, buses.listen_ns); !seen.empty()) {
      RestoreResult r;
      char ms[32];
      std::snprintf(ms, sizeof ms, "%.0f ms", buses.listen_ns / 1e6);
      r.problems.push_back("another CANopen master is active on " + buses.can->name() + ": " + seen + " within " + ms +
                           ": restore does not change drive parameters under it; stop it (another controller, "
                           "instance or host) first; nothing was written");
      return r;
    }
  }
  return restore_drives(
      files,
      [&](const BackupFile& f, std::string& why) -> std::unique_ptr<DriveChannel> {
        if (f.slave) {
          if (!buses.ethercat) {
            why = "an EtherCAT backup, and no EtherCAT segment to reach it (scan-ethercat first, or --ethercat-interface)";
            return nullptr;
          }
          return ethercat_channel(*buses.ethercat, f.slave);
        }
        if (!buses.can) {
          why = "a CANopen backup, and no CAN bus to reach it (scan first, or --interface)";
          return nullptr;
        }
        return canopen_channel(*buses.can, f.node, buses.sdo_timeout_ns, buses.nmt_timeout_ns);
      },
      dry_run);
}

std::string describe(const RestoreResult& r) {
  std::string o;
  for (const DriveRestore& d : r.drives) {
    if (!d.checked) continue;  // its problem says why
    o += d.file.label() + ": ";
    if (d.changes.empty()) o += "every parameter as in the backup (" + std::to_string(d.unchanged) + ")\n";  // PDOs below
    else
      o += std::to_string(d.changes.size()) + " parameter(s) differ from the backup, " + std::to_string(d.unchanged) +
           " as in it\n";
    for (const RestoreChange& k : d.changes) {
      const std::string what = addr_text(k.entry.addr) + " " + k.entry.name;
      if (r.dry_run || (!k.written && k.note.empty()))
        o += "  " + std::string(r.dry_run ? "would write " : "not written: ") + what + ": " + k.now + " -> " +
             k.entry.value + "\n";
      else if (k.written)
        o += "  wrote " + what + " = " + k.entry.value + " (was " + k.now + "), read back " + k.read_back + "\n";
      else if (!k.note.empty())
        o += "  " + what + ": " + k.note + "\n";
    }
    if (!d.pdo_changes.empty()) {
      o += "  " + std::to_string(d.pdo_changes.size()) + " PDO entr" + (d.pdo_changes.size() == 1 ? "y" : "ies") +
           " differ" + (d.pdo_changes.size() == 1 ? "s" : "") + " from the backup" +
           (r.dry_run ? ": the PDOs would be rewritten in order" : "") + "\n";
      for (const RestoreChange& k : d.pdo_changes) {
        const std::string what = addr_text(k.entry.addr) + " " + k.entry.name;
        if (r.dry_run || !k.written)
          o += "  " + std::string(r.dry_run ? "would write " : "not restored: ") + what + ": " + k.now + " -> " + k.entry.value + "\n";
        else
          o += "  restored " + what + " = " + k.entry.value + " (was " + k.now + "), read back " + k.read_back + "\n";
      }
      for (const std::string& s : d.pdo_steps) o += "    pdo write " + s + "\n";
    }
    for (const std::string& n : d.notes) o += "  " + n + "\n";
    if (!d.stopped.empty()) {
      o += "  STOPPED at " + d.stopped + "\n  left as:\n";
      for (const std::string& l : d.left) o += "    " + l + "\n";
    }
    if (d.not_reached) o += "  nothing written: the restore stopped at an earlier drive\n";
  }
  for (const std::string& p : r.problems) o += "problem: " + p + "\n";
  return o;
}

}  // namespace cnc::commission
