#include "commission/backup.hpp"

#include "commission/steps.hpp"  // machine_joints

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>
#include <memory>
#include <stdexcept>

#include "core/util/atomic_file.hpp"
#include "fieldbus/canopen/eds.hpp"
#include "fieldbus/canopen/sdo_client.hpp"
#include "fieldbus/ethercat/master.hpp"

namespace cnc::commission {

namespace co = cnc::canopen;
using D = co::DataType;

namespace {

constexpr uint32_t kAbortTimeout = 0x05040000;

std::string hex(uint32_t v, int digits) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%0*X", digits, v);
  return b;
}

// "6099sub1", or "6098" for sub-index 0 of a plain variable.
std::string section(const co::ObjectAddress& a, bool plain) {
  char b[16];
  if (plain) std::snprintf(b, sizeof b, "%04X", a.index);
  else std::snprintf(b, sizeof b, "%04Xsub%X", a.index, a.sub);
  return b;
}

std::string access_name(co::Access a) {
  switch (a) {
    case co::Access::ReadOnly: return "ro";
    case co::Access::WriteOnly: return "wo";
    case co::Access::ReadWrite: return "rw";
    case co::Access::Const: return "const";
  }
  return "";
}

struct Channel {
  int node = 0;
  std::unique_ptr<co::SdoClient> sdo;
  bool silent = false;
};

// A loop gain whose value came back in another size than guessed (the
// sub-indices of 0x60F9/0x60FB are the manufacturer's) keeps the size the
// drive gave it, so that the restore writes it back as it was read.
BackupObject sized(BackupObject o, const std::vector<uint8_t>& data) {
  if (o.addr.index != 0x60F9 && o.addr.index != 0x60FB) return o;
  if (data.size() == co::data_type_size(o.type)) return o;
  const bool sign = co::is_signed(o.type);
  switch (data.size()) {
    case 1: o.type = sign ? D::Integer8 : D::Unsigned8; break;
    case 2: o.type = sign ? D::Integer16 : D::Unsigned16; break;
    case 4: o.type = sign ? D::Integer32 : D::Unsigned32; break;
    default: break;
  }
  return o;
}

// The sub-indices of the loops' parameter sets that the drive's sub-index
// 0 (read as one of `values`) says it has, each named as step 7 and the
// simulated drive use it where that is known (their meaning is the
// manufacturer's: CiA 402 leaves it open), else by its number; read as
// UNSIGNED32 or UNSIGNED16 first, then kept in the size the drive gives.
std::vector<BackupObject> gain_entries(const std::vector<BackedUpValue>& values) {
  struct Known {
    co::ObjectAddress addr;
    D type;
    const char* name;
  };
  static const Known known[] = {
      {{0x60F9, 1}, D::Unsigned32, "Velocity loop gain"},
      {{0x60F9, 2}, D::Unsigned16, "Velocity loop integration time"},
      {{0x60FB, 1}, D::Unsigned32, "Position loop gain"},
      {{0x60FB, 2}, D::Unsigned16, "Position loop integration time"},
      {{0x60FB, 3}, D::Unsigned16, "Position loop differentiation time"},
      {{0x60FB, 4}, D::Unsigned16, "Position loop velocity feed-forward"},
      {{0x60FB, 5}, D::Unsigned16, "Position loop acceleration feed-forward"},
  };
  std::vector<BackupObject> more;
  for (const BackedUpValue& v : values) {
    const uint16_t idx = v.object.addr.index;
    if ((idx != 0x60F9 && idx != 0x60FB) || v.object.addr.sub != 0 || v.data.empty()) continue;
    for (unsigned k = 1; k <= v.data[0]; ++k) {
      BackupObject o{{idx, static_cast<uint8_t>(k)}, D::Unsigned32,
                     std::string(idx == 0x60F9 ? "Velocity" : "Position") + " control parameter " + std::to_string(k), ""};
      for (const Known& n : known)
        if (n.addr == o.addr) {
          o.type = n.type;
          o.name = n.name;
        }
      more.push_back(o);
    }
  }
  return more;
}

constexpr uint32_t kAbortNoObject = 0x06020000;
constexpr uint16_t kRpdoComm = 0x1400, kTpdoComm = 0x1800, kPdoOffsetToMapping = 0x200, kMaxPdos = 0x200;

// "RPDO12": PDO number n + 1 of the communication index `comm`.
std::string pdo_name(uint16_t comm) {
  const bool tpdo = comm >= kTpdoComm;
  return std::string(tpdo ? "TPDO" : "RPDO") + std::to_string(comm - (tpdo ? kTpdoComm : kRpdoComm) + 1);
}

// The communication parameters of the PDO at `comm` that its sub-index 0
// (`highest`) says it has (CiA 301 7.5.2.35/37): COB-ID, transmission type,
// a TPDO's inhibit time, the event timer (an RPDO's deadline), a TPDO's
// SYNC start value; and the mapping's sub-index 0.
std::vector<BackupObject> pdo_objects(uint16_t comm, uint8_t highest) {
  const bool tpdo = comm >= kTpdoComm;
  const std::string p = pdo_name(comm);
  std::vector<BackupObject> v;
  const auto add = [&](uint8_t sub, D type, const std::string& what) {
    if (sub <= highest) v.push_back({{comm, sub}, type, p + " " + what});
  };
  add(1, D::Unsigned32, "COB-ID");
  add(2, D::Unsigned8, "transmission type");
  if (tpdo) add(3, D::Unsigned16, "inhibit time");
  add(5, D::Unsigned16, "event timer");
  if (tpdo) add(6, D::Unsigned8, "SYNC start value");
  v.push_back({{static_cast<uint16_t>(comm + kPdoOffsetToMapping), 0}, D::Unsigned8, p + " mapped objects"});
  return v;
}

bool is_pdo_mapping(uint16_t index) { return (index >= 0x1600 && index <= 0x17FF) || (index >= 0x1A00 && index <= 0x1BFF); }

// The entries a mapping's sub-index 0 announced, for every mapping in `values`.
std::vector<BackupObject> mapping_entries(const std::vector<BackedUpValue>& values) {
  std::vector<BackupObject> more;
  for (const BackedUpValue& v : values) {
    const uint16_t idx = v.object.addr.index;
    if (!is_pdo_mapping(idx) || v.object.addr.sub != 0 || v.data.empty()) continue;
    const std::string pdo = v.object.name.substr(0, v.object.name.find(' '));
    for (uint8_t k = 1; k <= std::min<uint8_t>(v.data[0], 64); ++k)
      more.push_back({{idx, k}, D::Unsigned32, pdo + " mapping entry " + std::to_string(k), ""});
  }
  return more;
}

// Which PDOs a CANopen node has: those its EDS lists, else found by
// reading each communication object's sub-index 0 in turn from 0x1400 and
// 0x1800 until the node has answered "object does not exist" (0x06020000)
// for BackupOptions::pdo_search_gap numbers in a row (a drive may number
// its PDOs with gaps: CiA 301 has no object that counts them).
struct PdoSearch {
  std::vector<uint16_t> eds;               // the EDS's communication objects (none: search)
  std::map<uint16_t, uint8_t> found;       // communication index -> its sub-index 0
  uint16_t next[2] = {0, 0};               // RPDO, TPDO: the number to read next
  uint16_t misses[2] = {0, 0};             // numbers that did not exist, in a row
  bool ended[2] = {false, false};
};

// Runs the bus until every client is idle.
void run(can::Transport& bus, std::vector<Channel>& ch) {
  std::map<uint32_t, Channel*> by_cob;
  for (auto& c : ch) by_cob[c.sdo->response_cob()] = &c;
  for (;;) {
    can::Frame f;
    while (bus.receive(f)) {
      auto it = by_cob.find(f.id);
      if (it == by_cob.end() || f.is_error() || f.is_remote()) continue;
      it->second->sdo->on_frame(f, bus.now_ns());
    }
    bool idle = true;
    const int64_t now = bus.now_ns();
    for (auto& c : ch) {
      c.sdo->poll(now);
      if (!c.sdo->idle()) idle = false;
    }
    if (idle) return;
    bus.wait(1'000'000);
  }
}

}  // namespace

std::string backup_value_text(D type, const std::vector<uint8_t>& d) {
  if (type == D::VisibleString) {
    std::string s(d.begin(), d.end());
    while (!s.empty() && (s.back() == '\0')) s.pop_back();
    return s;
  }
  const std::size_t size = co::data_type_size(type);
  if (size == 0 || size > 8 || type == D::OctetString || type == D::Domain) {
    std::string s;
    char b[4];
    for (uint8_t c : d) {
      std::snprintf(b, sizeof b, "%02X", c);
      s += b;
    }
    return s.empty() ? "" : s;
  }
  uint64_t u = 0;
  for (std::size_t i = 0; i < d.size() && i < 8; ++i) u |= static_cast<uint64_t>(d[i]) << (8 * i);
  if (type == D::Real32 && d.size() >= 4) {
    float f;
    const uint32_t bits = static_cast<uint32_t>(u);
    std::memcpy(&f, &bits, 4);
    char b[32];
    std::snprintf(b, sizeof b, "%.9g", f);
    return b;
  }
  if (type == D::Real64 && d.size() >= 8) {
    double f;
    std::memcpy(&f, &u, 8);
    char b[32];
    std::snprintf(b, sizeof b, "%.17g", f);
    return b;
  }
  if (co::is_signed(type)) {
    const unsigned bits = static_cast<unsigned>(8 * std::min(size, d.size()));
    int64_t v = static_cast<int64_t>(u);
    if (bits > 0 && bits < 64 && (u >> (bits - 1)) & 1) v = static_cast<int64_t>(u | (~uint64_t{0} << bits));
    return std::to_string(v);
  }
  char b[32];
  std::snprintf(b, sizeof b, "0x%0*llX", static_cast<int>(2 * size), static_cast<unsigned long long>(u));
  return b;
}

std::optional<std::vector<uint8_t>> parse_backup_value(D type, const std::string& text) {
  std::vector<uint8_t> out;
  if (type == D::VisibleString) return std::vector<uint8_t>(text.begin(), text.end());
  const std::size_t size = co::data_type_size(type);
  if (size == 0 || size > 8 || type == D::OctetString || type == D::Domain) {
    if (text.size() % 2) return std::nullopt;
    for (std::size_t i = 0; i < text.size(); i += 2) {
      if (!std::isxdigit(static_cast<unsigned char>(text[i])) || !std::isxdigit(static_cast<unsigned char>(text[i + 1])))
        return std::nullopt;
      out.push_back(static_cast<uint8_t>(std::stoul(text.substr(i, 2), nullptr, 16)));
    }
    return out;
  }
  if (text.empty()) return std::nullopt;
  uint64_t u = 0;
  try {
    std::size_t used = 0;
    if (type == D::Real32) {
      const float f = std::stof(text, &used);
      uint32_t bits;
      std::memcpy(&bits, &f, 4);
      u = bits;
    } else if (type == D::Real64) {
      const double f = std::stod(text, &used);
      std::memcpy(&u, &f, 8);
    } else if (co::is_signed(type)) {
      const long long v = std::stoll(text, &used, 0);
      const unsigned bits = static_cast<unsigned>(8 * size);
      if (bits < 64 && (v < -(1LL << (bits - 1)) || v >= (1LL << (bits - 1)))) return std::nullopt;
      u = static_cast<uint64_t>(v);
    } else {
      if (text[0] == '-') return std::nullopt;
      u = std::stoull(text, &used, 0);
      if (size < 8 && (u >> (8 * size)) != 0) return std::nullopt;
    }
    if (used != text.size()) return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
  for (std::size_t i = 0; i < size; ++i) out.push_back(static_cast<uint8_t>(u >> (8 * i)));
  return out;
}

const std::vector<BackupObject>& backup_objects() {
  static const std::vector<BackupObject> list = [] {
    std::vector<BackupObject> v = {
        {{0x1000, 0}, D::Unsigned32, "Device type"},
        {{0x1008, 0}, D::VisibleString, "Manufacturer device name"},
        {{0x1009, 0}, D::VisibleString, "Manufacturer hardware version"},
        {{0x100A, 0}, D::VisibleString, "Manufacturer software version"},
        {{0x1017, 0}, D::Unsigned16, "Producer heartbeat time"},
        {{0x1018, 1}, D::Unsigned32, "Vendor-ID"},
        {{0x1018, 2}, D::Unsigned32, "Product code"},
        {{0x1018, 3}, D::Unsigned32, "Revision number"},
        {{0x1018, 4}, D::Unsigned32, "Serial number"},
    };
    const std::vector<BackupObject> drive = {
        {{0x6007, 0}, D::Integer16, "Abort connection option code"},
        {{0x605A, 0}, D::Integer16, "Quick stop option code"},
        {{0x605B, 0}, D::Integer16, "Shutdown option code"},
        {{0x605C, 0}, D::Integer16, "Disable operation option code"},
        {{0x605D, 0}, D::Integer16, "Halt option code"},
        {{0x605E, 0}, D::Integer16, "Fault reaction option code"},
        {{0x6060, 0}, D::Integer8, "Modes of operation"},
        {{0x6065, 0}, D::Unsigned32, "Following error window"},
        {{0x6066, 0}, D::Unsigned16, "Following error time out"},
        {{0x6067, 0}, D::Unsigned32, "Position window"},
        {{0x6068, 0}, D::Unsigned16, "Position window time"},
        {{0x6072, 0}, D::Unsigned16, "Max torque"},
        {{0x607C, 0}, D::Integer32, "Home offset"},
        {{0x607D, 1}, D::Integer32, "Min position limit"},
        {{0x607D, 2}, D::Integer32, "Max position limit"},
        {{0x607E, 0}, D::Unsigned8, "Polarity"},
        {{0x6080, 0}, D::Unsigned32, "Max motor speed"},
        {{0x6085, 0}, D::Unsigned32, "Quick stop deceleration"},
        {{0x608F, 1}, D::Unsigned32, "Encoder increments"},
        {{0x608F, 2}, D::Unsigned32, "Motor revolutions"},
        {{0x6091, 1}, D::Unsigned32, "Gear ratio: motor shaft revolutions"},
        {{0x6091, 2}, D::Unsigned32, "Gear ratio: driving shaft revolutions"},
        {{0x6092, 1}, D::Unsigned32, "Feed constant: feed"},
        {{0x6092, 2}, D::Unsigned32, "Feed constant: shaft revolutions"},
        {{0x6098, 0}, D::Integer8, "Homing method"},
        {{0x6099, 1}, D::Unsigned32, "Homing speed during search for switch"},
        {{0x6099, 2}, D::Unsigned32, "Homing speed during search for zero"},
        {{0x609A, 0}, D::Unsigned32, "Homing acceleration"},
        {{0x60C2, 1}, D::Unsigned8, "Interpolation time period value"},
        {{0x60C2, 2}, D::Integer8, "Interpolation time index"},
        {{0x6502, 0}, D::Unsigned32, "Supported drive modes"},
        // The loops' parameter sets (CiA 402 records with manufacturer-
        // specific sub-indices): their sub-index 0, the highest sub-index
        // the drive has, then (gain_entries) each sub-index up to it; the
        // EDS's entries replace them.
        {{0x60F9, 0}, D::Unsigned8, "Velocity control parameter set: highest sub-index", "ro"},
        {{0x60FB, 0}, D::Unsigned8, "Position control parameter set: highest sub-index", "ro"},
    };
    v.insert(v.end(), drive.begin(), drive.end());
    return v;
  }();
  return list;
}

BackupResult backup_drives(can::Transport& bus, const State& s, const BackupOptions& o) {
  BackupResult r;
  co::SdoClientOptions so;
  so.timeout_ns = o.timeout_ns;
  std::vector<Channel> ch;
  std::vector<NodeBackup> nodes;
  std::vector<std::vector<BackupObject>> lists;
  std::vector<PdoSearch> searches;
  for (const MachineJoint& mj : machine_joints(s)) {  // a gantry pair: both its drives
    const Axis& a = mj.axis;
    if (a.slave != 0) continue;  // an EtherCAT drive: backup_ethercat_drives
    if (!a.enabled) {
      r.skipped.push_back(std::string("axis ") + a.letter + " (node " + std::to_string(a.node) +
                          ") is disabled: its drive is not backed up");
      continue;
    }
    NodeBackup b;
    b.node = a.node;
    b.axis = a.letter;
    std::vector<BackupObject> list = backup_objects();
    PdoSearch search;
    if (const ScannedNode* n = s.node(a.node); n && !n->eds.empty() && !s.eds_dir.empty()) {
      b.eds = n->eds;
      const std::filesystem::path eds = std::filesystem::path(s.eds_dir) / n->eds;
      try {
        const co::DeviceDescription d = co::load_eds(eds);
        for (const co::EdsEntry& e : d.entries)
          if (e.addr.index >= 0x2000 && e.addr.index <= 0x5FFF && co::is_readable(e.access))
            list.push_back({e.addr, e.type, e.name, access_name(e.access)});
        for (const co::EdsEntry& e : d.entries) {
          const uint16_t i = e.addr.index;
          const bool comm = (i >= kRpdoComm && i < kRpdoComm + kMaxPdos) || (i >= kTpdoComm && i < kTpdoComm + kMaxPdos);
          if (comm && e.addr.sub == 0) search.eds.push_back(i);
        }
        // The loop gains as the EDS describes them (names, types, access), in
        // place of the sub-indices read from the drive.
        for (uint16_t gains : {uint16_t{0x60F9}, uint16_t{0x60FB}}) {
          if (std::none_of(d.entries.begin(), d.entries.end(), [gains](const co::EdsEntry& e) { return e.addr.index == gains; }))
            continue;
          std::erase_if(list, [gains](const BackupObject& o) { return o.addr.index == gains; });
          for (const co::EdsEntry& e : d.entries)
            if (e.addr.index == gains && e.addr.sub != 0 && co::is_readable(e.access))
              list.push_back({e.addr, e.type, e.name, access_name(e.access)});
        }
      } catch (const std::exception& e) {
        r.problems.push_back("node " + std::to_string(a.node) + " (axis " + std::string(1, a.letter) +
                             "): its EDS cannot be read: " + e.what());
      }
    }
    char f[32];
    std::snprintf(f, sizeof f, "node-%02d-%c.dcf", a.node, static_cast<char>(std::tolower(a.letter)));
    b.file = f;
    nodes.push_back(b);
    lists.push_back(list);
    searches.push_back(search);
    Channel c;
    c.node = a.node;
    c.sdo = std::make_unique<co::SdoClient>(bus, static_cast<uint8_t>(a.node), so);
    ch.push_back(std::move(c));
  }
  if (!r.ok()) return r;

  // Phase 1: does each node answer (its device type)?
  for (auto& c : ch) {
    Channel* cp = &c;
    c.sdo->upload({0x1000, 0}, [cp](const co::SdoResult& res) {
      if (!res.ok() && res.aborted_by_client && res.abort_code == kAbortTimeout) cp->silent = true;
    });
  }
  run(bus, ch);
  for (std::size_t i = 0; i < ch.size(); ++i) {
    if (ch[i].silent)
      r.problems.push_back("node " + std::to_string(ch[i].node) + " (axis " + std::string(1, nodes[i].axis) +
                           ") does not answer on " + bus.name() +
                           ": check its power, the cable and termination, its bit rate and node-ID; nothing was written");
  }
  if (!r.ok()) return r;

  // Phase 2: the list, then (phase 3) the PDO mapping entries their
  // sub-index 0 announced.
  auto post = [&](std::size_t i, const BackupObject& obj) {
    NodeBackup* b = &nodes[i];
    Channel* cp = &ch[i];
    cp->sdo->upload(obj.addr, [b, cp, obj](const co::SdoResult& res) {
      if (res.ok()) {
        b->values.push_back({sized(obj, res.data), res.data});
      } else if (res.aborted_by_client && res.abort_code == kAbortTimeout) {
        cp->silent = true;
      } else {
        b->missing.push_back(section(obj.addr, false) + " " + obj.name + ": " + res.abort_text());
      }
    });
  };
  for (std::size_t i = 0; i < ch.size(); ++i)
    for (const BackupObject& obj : lists[i]) post(i, obj);
  run(bus, ch);
  // The PDOs: each communication object's sub-index 0 (the EDS's at once,
  // else one PDO number per round until pdo_search_gap in a row do not exist),
  // then the parameters it announces and the mapping's sub-index 0, then
  // (phase 3) the mapping entries.
  auto probe = [&](std::size_t i, uint16_t comm, int kind) {
    PdoSearch* ps = &searches[i];
    NodeBackup* b = &nodes[i];
    Channel* cp = &ch[i];
    const unsigned gap = std::max(1u, o.pdo_search_gap);
    cp->sdo->upload({comm, 0}, [ps, b, cp, comm, kind, gap](const co::SdoResult& res) {
      if (res.ok() && !res.data.empty()) {
        ps->found[comm] = res.data[0];
        if (kind >= 0) ps->misses[kind] = 0;
        if (kind >= 0 && ++ps->next[kind] >= kMaxPdos) ps->ended[kind] = true;
        return;
      }
      if (kind >= 0) {
        const bool absent = res.abort_code == kAbortNoObject && !res.aborted_by_client;
        ps->ended[kind] = !absent || ++ps->misses[kind] >= gap || ++ps->next[kind] >= kMaxPdos;
      }
      if (res.aborted_by_client && res.abort_code == kAbortTimeout) cp->silent = true;
      else if (kind < 0 || res.abort_code != kAbortNoObject)  // a number the drive has not got is no loss
        b->missing.push_back(section({comm, 0}, false) + " " + pdo_name(comm) + " communication parameter: " +
                             res.abort_text());
    });
  };
  for (std::size_t i = 0; i < ch.size(); ++i) {
    if (searches[i].eds.empty()) continue;
    for (uint16_t comm : searches[i].eds) probe(i, comm, -1);
    searches[i].ended[0] = searches[i].ended[1] = true;
  }
  for (;;) {
    bool any = false;
    for (std::size_t i = 0; i < ch.size(); ++i) {
      if (ch[i].silent) continue;
      for (int kind : {0, 1}) {
        if (searches[i].ended[kind]) continue;
        probe(i, static_cast<uint16_t>((kind ? kTpdoComm : kRpdoComm) + searches[i].next[kind]), kind);
        any = true;
      }
    }
    run(bus, ch);
    if (!any) break;
  }
  for (std::size_t i = 0; i < ch.size(); ++i)
    for (const auto& [comm, highest] : searches[i].found)
      for (const BackupObject& obj : pdo_objects(comm, highest)) post(i, obj);
  run(bus, ch);
  for (std::size_t i = 0; i < ch.size(); ++i) {
    for (const BackupObject& obj : mapping_entries(nodes[i].values)) post(i, obj);
    for (const BackupObject& obj : gain_entries(nodes[i].values)) post(i, obj);
  }
  run(bus, ch);
  for (std::size_t i = 0; i < ch.size(); ++i) {
    if (ch[i].silent)
      r.problems.push_back("node " + std::to_string(ch[i].node) + " (axis " + std::string(1, nodes[i].axis) +
                           ") stopped answering during the backup on " + bus.name() +
                           ": check its power and the cable; nothing was written");
    std::sort(nodes[i].values.begin(), nodes[i].values.end(),
              [](const BackedUpValue& a, const BackedUpValue& b) { return a.object.addr < b.object.addr; });
    std::sort(nodes[i].missing.begin(), nodes[i].missing.end());
  }
  r.nodes = std::move(nodes);
  return r;
}

bool has_canopen_axes(const State& s) {
  return std::any_of(s.axes.begin(), s.axes.end(), [](const Axis& a) { return a.enabled && a.slave == 0; });
}
bool has_ethercat_axes(const State& s) {
  return std::any_of(s.axes.begin(), s.axes.end(), [](const Axis& a) { return a.enabled && a.slave != 0; });
}

namespace {

// CoE SDO information access bits (ETG.1000.6): 0-2 readable in PREOP,
// SAFEOP, OP; 3-5 writable in them.
std::string coe_access(uint16_t bits) {
  const bool r = bits & 0x07, w = bits & 0x38;
  return r && w ? "rw" : r ? "ro" : w ? "wo" : "";
}

// The fixed list as it applies to an EtherCAT drive: no CANopen PDO
// communication objects or heartbeat (the EtherCAT master owns the
// exchange), the sync managers' PDO assignment instead.
std::vector<BackupObject> ethercat_objects() {
  std::vector<BackupObject> v;
  for (const BackupObject& o : backup_objects()) {
    const uint16_t i = o.addr.index;
    if (i == 0x1017) continue;
    v.push_back(o);
  }
  for (uint16_t sm : {uint16_t{0x1C12}, uint16_t{0x1C13}})
    v.push_back({{sm, 0}, D::Unsigned8, std::string(sm == 0x1C12 ? "RxPDO" : "TxPDO") + " assign: number of PDOs", ""});
  return v;
}

// The PDO mappings of an EtherCAT drive: those its SDO information lists
// (`indices`), else found by reading each mapping's sub-index 0 from
// 0x1600 and 0x1A00 on until `gap` in a row do not exist; a
// mapping is read as its sub-index 0 ("RPDO1 mapped objects", 0x1600).
template <class Read>
void read_ethercat_mappings(const std::vector<uint16_t>& indices, bool listed, unsigned gap, Read&& read) {
  for (uint16_t base : {uint16_t{0x1600}, uint16_t{0x1A00}}) {
    unsigned misses = 0;
    for (uint16_t n = 0; n < kMaxPdos; ++n) {
      const uint16_t map = static_cast<uint16_t>(base + n);
      if (listed && std::find(indices.begin(), indices.end(), map) == indices.end()) continue;
      const BackupObject obj{{map, 0}, D::Unsigned8, pdo_name(static_cast<uint16_t>(map - kPdoOffsetToMapping)) + " mapped objects", ""};
      if (read(obj, !listed)) misses = 0;
      else if (!listed && ++misses >= std::max(1u, gap)) break;
    }
  }
}

bool is_timeout(const ethercat::SdoResult& r) { return !r.ok && r.abort_code == 0; }

}  // namespace

BackupResult backup_ethercat_drives(ethercat::Master& m, const State& s) {
  BackupResult r;
  for (const MachineJoint& mj : machine_joints(s)) {  // a gantry pair: both its drives
    const Axis& a = mj.axis;
    if (a.slave == 0) continue;  // a CANopen drive: backup_drives
    const std::string who =
        "EtherCAT slave " + std::to_string(a.slave) + " (axis " + std::string(1, a.letter) + ")";
    if (!a.enabled) {
      r.skipped.push_back(std::string("axis ") + a.letter + " (EtherCAT slave " + std::to_string(a.slave) +
                          ") is disabled: its drive is not backed up");
      continue;
    }
    const auto& slaves = m.slaves();
    const auto it = std::find_if(slaves.begin(), slaves.end(),
                                 [&](const ethercat::SlaveInfo& x) { return x.position == static_cast<unsigned>(a.slave); });
    if (it == slaves.end()) {
      r.problems.push_back(who + " is not on " + m.config().interface + " (" + std::to_string(slaves.size()) +
                           " slave(s) answer): check its power and the cable before it; nothing was written");
      continue;
    }
    if (!it->sii.has_coe()) {
      r.problems.push_back(who + " (" + it->sii.name + ") has no CoE mailbox: its parameters cannot be read");
      continue;
    }
    NodeBackup b;
    b.slave = static_cast<unsigned>(a.slave);
    b.axis = a.letter;
    char f[32];
    std::snprintf(f, sizeof f, "slave-%02d-%c.dcf", a.slave, static_cast<char>(std::tolower(a.letter)));
    b.file = f;
    std::vector<BackupObject> list = ethercat_objects();
    // The manufacturer objects from the drive's SDO information, with each
    // entry's type and access.
    std::string err;
    const std::vector<uint16_t> indices = m.sdo_info_list(b.slave, err);
    const bool listed = err.empty() && std::any_of(indices.begin(), indices.end(), is_pdo_mapping);
    if (!err.empty()) {
      b.missing.push_back("SDO information: " + err + " (manufacturer objects 0x2000-0x5FFF not read)");
    }
    for (uint16_t index : indices) {
      if (index < 0x2000 || index > 0x5FFF) continue;
      const auto obj = m.sdo_info_object(b.slave, index, err);
      if (!obj) continue;
      const uint8_t first = obj->object_code == 7 ? 0 : 1;
      const uint8_t last = obj->object_code == 7 ? 0 : obj->max_sub;
      for (unsigned sub = first; sub <= last; ++sub) {
        const auto e = m.sdo_info_entry(b.slave, index, static_cast<uint8_t>(sub), err);
        if (!e || !(e->access & 0x07) || !co::is_known_data_type(e->data_type)) continue;
        list.push_back({{index, static_cast<uint8_t>(sub)}, static_cast<D>(e->data_type),
                        e->name.empty() ? obj->name : e->name, coe_access(e->access)});
      }
    }
    bool silent = false;
    // Reads one object; false when the drive has not got it. With
    // `searching`, "object does not exist" ends a search and is no loss.
    auto read = [&](const BackupObject& obj, bool searching = false) {
      if (silent) return false;
      const ethercat::SdoResult res = m.sdo_upload(b.slave, obj.addr.index, obj.addr.sub);
      if (res.ok) b.values.push_back({sized(obj, res.data), res.data});
      else if (is_timeout(res)) silent = true;
      else if (!searching || res.abort_code != kAbortNoObject)
        b.missing.push_back(section(obj.addr, false) + " " + obj.name + ": " + res.error);
      return res.ok;
    };
    for (const BackupObject& obj : list) read(obj);
    for (const BackupObject& obj : gain_entries(b.values)) read(obj);
    read_ethercat_mappings(indices, listed, BackupOptions{}.pdo_search_gap, read);
    // The PDO mapping entries their sub-index 0 announced, and the PDOs
    // each sync manager's assignment counts.
    for (const BackupObject& obj : mapping_entries(b.values)) read(obj);
    std::vector<BackupObject> assigned;
    for (const BackedUpValue& v : b.values) {
      const uint16_t sm = v.object.addr.index;
      if ((sm != 0x1C12 && sm != 0x1C13) || v.object.addr.sub != 0 || v.data.empty()) continue;
      for (uint8_t k = 1; k <= v.data[0]; ++k)
        assigned.push_back({{sm, k}, D::Unsigned16, std::string(sm == 0x1C12 ? "RxPDO" : "TxPDO") + " assign: PDO " + std::to_string(k), ""});
    }
    for (const BackupObject& obj : assigned) read(obj);
    if (silent) {
      r.problems.push_back(who + " does not answer its mailbox on " + m.config().interface +
                           ": check its power and the cable; nothing was written");
      continue;
    }
    std::sort(b.values.begin(), b.values.end(),
              [](const BackedUpValue& x, const BackedUpValue& y) { return x.object.addr < y.object.addr; });
    std::sort(b.missing.begin(), b.missing.end());
    r.nodes.push_back(std::move(b));
  }
  return r;
}

BackupResult backup_ethercat_drives(const std::string& interface, const State& s) {
  BackupResult r;
  ethercat::MasterConfig cfg;
  cfg.interface = interface;
  try {
    ethercat::Master m(cfg, nullptr);
    m.to_preop();
    r = backup_ethercat_drives(m, s);
    m.release();
  } catch (const std::exception& e) {
    r.problems.push_back(interface + ": " + e.what() + "; nothing was written");
  }
  return r;
}

std::string format_backup(const NodeBackup& b, const State& s, const std::string& time) {
  std::string o;
  const std::string name = std::string(1, static_cast<char>(std::tolower(b.axis))) + "-axis";
  if (b.slave != 0) {
    o += "; Drive-parameter backup of EtherCAT slave " + std::to_string(b.slave) + " (axis " + std::string(1, b.axis) +
         "), CoE SDO upload by cnc-commission backup, " + time + "\n";
    o += "; Segment " + s.ethercat_interface +
         ". Sections [index] and [indexsubN] as in a DCF (CiA 306); ParameterValue as read.\n";
    o += "; cnc-commission restore checks the identity (1018sub1-3) and writes the changed parameters of\n"
         "; 0x2000-0x9FFF back with CoE SDO downloads (not those with AccessType ro or const).\n";
    o += "\n[DeviceComissioning]\nEtherCATSlave=" + std::to_string(b.slave) + "\nNodeName=" + name + "\n";
  } else {
    o += "; Drive-parameter backup of node " + std::to_string(b.node) + " (axis " + std::string(1, b.axis) +
         "), SDO upload by cnc-commission backup, " + time + "\n";
    o += "; Bus " + s.interface + ". Sections [index] and [indexsubN] as in a DCF (CiA 306); ParameterValue as read.\n";
    o += "; cnc-commission restore checks the identity (1018sub1-3), writes the changed parameters of\n"
         "; 0x2000-0x9FFF back with SDO downloads and stores them in the drive (0x1010:1, \"save\").\n";
    o += "\n[DeviceComissioning]\nNodeID=" + std::to_string(b.node) + "\nNodeName=" + name +
         "\nBaudrate=" + std::to_string(s.bitrate / 1000) + "\n";
  }
  if (!b.eds.empty()) o += "; described by " + b.eds + "\n";
  for (const BackedUpValue& v : b.values) {
    const bool plain = v.object.addr.sub == 0 && std::none_of(b.values.begin(), b.values.end(), [&](const BackedUpValue& w) {
                         return w.object.addr.index == v.object.addr.index && w.object.addr.sub != 0;
                       });
    o += "\n[" + section(v.object.addr, plain) + "]\nParameterName=" + v.object.name + "\nDataType=" +
         hex(static_cast<uint32_t>(v.object.type), 4) + "\nParameterValue=" + backup_value_text(v.object.type, v.data) + "\n";
    if (!v.object.access.empty()) o += "AccessType=" + v.object.access + "\n";
  }
  o += "\n[Missing]\n; objects the drive does not have, or would not give (SDO abort)\n";
  for (std::size_t i = 0; i < b.missing.size(); ++i) o += std::to_string(i + 1) + "=" + b.missing[i] + "\n";
  return o;
}

std::vector<std::filesystem::path> write_backup(State& s, BackupResult& r, const std::filesystem::path& dir) {
  if (!r.ok()) {
    std::string m = "drive-parameter backup not written:";
    for (const auto& p : r.problems) m += "\n  " + p;
    throw std::runtime_error(m);
  }
  std::filesystem::create_directories(dir);
  const std::string time = utc_now();
  DriveBackup rec;
  rec.dir = std::filesystem::absolute(dir).string();
  rec.time = time;
  std::vector<std::filesystem::path> out;
  for (const NodeBackup& b : r.nodes) {
    write_file_atomically(dir / b.file, format_backup(b, s, time));
    out.push_back(dir / b.file);
    rec.files.push_back(b.file);
  }
  s.backup = rec;
  return out;
}

std::vector<GeneratedFile> backup_files(const State& s, const std::filesystem::path& dir) {
  std::vector<GeneratedFile> out;
  if (!s.backup) return out;
  for (const std::string& f : s.backup->files) {
    const std::filesystem::path from = std::filesystem::path(s.backup->dir) / f;
    std::string text;
    try {
      text = read_file(from);
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string(e.what()) + ": the drive-parameter backup of " + s.backup->time +
                               " is gone: take it again (cnc-commission backup --dir DIR)");
    }
    out.push_back({dir / "drive-backup" / f, text});
  }
  return out;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return b;
}

}  // namespace cnc::commission
