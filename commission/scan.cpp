#include "commission/scan.hpp"
#include "commission/lss_assign.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <memory>

#include "fieldbus/canopen/eds.hpp"
#include "fieldbus/ethercat/esi.hpp"
#include "fieldbus/ethercat/master.hpp"
#include "fieldbus/canopen/sdo_client.hpp"

namespace cnc::commission {

namespace co = cnc::canopen;

bool ScanResult::ok() const noexcept {
  if (!problems.empty()) return false;
  for (const auto& n : nodes)
    if (!n.problems.empty()) return false;
  return true;
}

std::vector<EdsInfo> load_eds_library(const std::filesystem::path& dir, std::vector<std::string>& problems) {
  std::vector<EdsInfo> lib;
  std::error_code ec;
  if (dir.empty()) return lib;
  if (!std::filesystem::is_directory(dir, ec)) {
    problems.push_back(dir.string() + ": not a folder of description files (EDS_DIR)");
    return lib;
  }
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".eds" || ext == ".dcf") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    try {
      const co::DeviceDescription d = co::load_eds(f);
      if (!d.vendor_number || !d.product_number) {
        problems.push_back(f.string() + ": [DeviceInfo] has no VendorNumber or ProductNumber; it cannot be matched");
        continue;
      }
      lib.push_back({f, *d.vendor_number, *d.product_number, d.revision_number, d.product_name});
    } catch (const std::exception& e) {
      problems.push_back(e.what());
    }
  }
  return lib;
}

const EdsInfo* match_eds(const std::vector<EdsInfo>& lib, uint32_t vendor, uint32_t product, uint32_t revision) {
  const EdsInfo* best = nullptr;
  for (const auto& e : lib) {
    if (e.vendor != vendor || e.product != product) continue;
    if (e.revision && *e.revision == revision) return &e;
    if (!best) best = &e;
  }
  return best;
}

namespace {

struct Probe {
  int id = 0;
  std::unique_ptr<co::SdoClient> sdo;
  int answers = 0;          // SDO response frames seen
  int requests = 0;         // transfers posted
  bool answered = false;
  bool protocol_error = false;
  ScannedNode node;
};

std::string text_of(const std::vector<uint8_t>& d) {
  std::string s(d.begin(), d.end());
  while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
  return s;
}

// Runs the bus until every client is idle, then `settle_ns` more.
void run(can::Transport& bus, std::vector<Probe>& probes, const ScanOptions& o) {
  std::map<uint32_t, Probe*> by_cob;
  for (auto& p : probes) by_cob[p.sdo->response_cob()] = &p;
  int64_t idle_since = -1;
  for (;;) {
    const int64_t now = bus.now_ns();
    can::Frame f;
    while (bus.receive(f)) {
      auto it = by_cob.find(f.id);
      if (it == by_cob.end() || f.is_error() || f.is_remote()) continue;
      ++it->second->answers;
      it->second->sdo->on_frame(f, bus.now_ns());
    }
    bool all_idle = true;
    for (auto& p : probes) {
      p.sdo->poll(now);
      if (!p.sdo->idle()) all_idle = false;
    }
    if (all_idle) {
      if (idle_since < 0) idle_since = now;
      if (now - idle_since >= o.settle_ns) return;
    } else {
      idle_since = -1;
    }
    bus.wait(1'000'000);
  }
}

const char* mode_name(int bit) {
  switch (bit) {
    case 0: return "PP";
    case 2: return "PV";
    case 3: return "TQ";
    case 5: return "HM";
    case 6: return "IP";
    case 7: return "CSP";
    case 8: return "CSV";
    case 9: return "CST";
    default: return nullptr;
  }
}

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08X", v);
  return b;
}

}  // namespace

ScanResult scan_canopen(can::Transport& bus, const ScanOptions& o) {
  ScanResult r;
  const std::vector<EdsInfo> lib = load_eds_library(o.eds_dir, r.problems);
  co::SdoClientOptions so;
  so.timeout_ns = o.timeout_ns;

  // Phase 1: who is there (0x1000 of every node-ID at once).
  std::vector<Probe> probes;
  for (int id = std::max(1, o.first); id <= std::min(127, o.last); ++id) {
    Probe p;
    p.id = id;
    p.node.node_id = id;
    p.sdo = std::make_unique<co::SdoClient>(bus, static_cast<uint8_t>(id), so);
    probes.push_back(std::move(p));
  }
  for (auto& p : probes) {
    Probe* pp = &p;
    ++p.requests;
    p.sdo->upload({0x1000, 0}, [pp](const co::SdoResult& res) {
      if (res.ok()) {
        pp->answered = true;
        pp->node.device_type = res.as<uint32_t>();
      } else if (!res.aborted_by_client) {
        pp->answered = true;  // it answered, with an abort: still a node
        pp->node.problems.push_back("does not give its device type (0x1000): " + res.abort_text());
      }
    });
  }
  run(bus, probes, o);

  // Keep the nodes that answered; more answers than requests: two nodes on one ID.
  std::vector<Probe> live;
  for (auto& p : probes) {
    if (!p.answered && p.answers == 0) continue;
    if (p.answers > p.requests) {
      p.node.problems.push_back("two or more devices answer on node-ID " + std::to_string(p.id) +
                                " (" + std::to_string(p.answers) + " answers to one request): give each device its "
                                "own node-ID (switches, parameter or LSS) and scan again");
      r.nodes.push_back(p.node);
      continue;
    }
    p.answers = 0;
    p.requests = 0;
    live.push_back(std::move(p));
  }

  // Phase 2: identity and drive objects of the nodes present.
  for (auto& p : live) {
    ScannedNode* n = &p.node;
    Probe* pp = &p;
    auto up = [&](co::ObjectAddress a, auto&& on_ok) {
      ++pp->requests;
      p.sdo->upload(a, [pp, on_ok](const co::SdoResult& res) {
        if (res.ok()) on_ok(res);
        else if (res.aborted_by_client && res.abort_code != 0x05040000) pp->protocol_error = true;
      });
    };
    up({0x1018, 1}, [n](const co::SdoResult& s) { n->vendor_id = s.as<uint32_t>(); });
    up({0x1018, 2}, [n](const co::SdoResult& s) { n->product_code = s.as<uint32_t>(); });
    up({0x1018, 3}, [n](const co::SdoResult& s) { n->revision = s.as<uint32_t>(); });
    up({0x1018, 4}, [n](const co::SdoResult& s) { n->serial = s.as<uint32_t>(); });
    up({0x1008, 0}, [n](const co::SdoResult& s) { n->name = text_of(s.data); });
    up({0x100A, 0}, [n](const co::SdoResult& s) { n->firmware = text_of(s.data); });
    if ((p.node.device_type & 0xFFFF) == 402) {
      up({0x6502, 0}, [n](const co::SdoResult& s) { n->supported_modes = s.as<uint32_t>(); });
      up({0x6041, 0}, [n](const co::SdoResult& s) { n->statusword = s.as<uint16_t>(); });
      up({0x603F, 0}, [n](const co::SdoResult& s) { n->error_code = s.as<uint16_t>(); });
      up({0x608F, 1}, [n](const co::SdoResult& s) { n->encoder_increments = s.as<uint32_t>(); });
      up({0x608F, 2}, [n](const co::SdoResult& s) { n->encoder_motor_revs = s.as<uint32_t>(); });
      up({0x6091, 1}, [n](const co::SdoResult& s) { n->gear_motor_revs = s.as<uint32_t>(); });
      up({0x6091, 2}, [n](const co::SdoResult& s) { n->gear_shaft_revs = s.as<uint32_t>(); });
      up({0x6092, 1}, [n](const co::SdoResult& s) { n->feed = s.as<uint32_t>(); });
      up({0x6092, 2}, [n](const co::SdoResult& s) { n->feed_shaft_revs = s.as<uint32_t>(); });
      up({0x6072, 0}, [n](const co::SdoResult& s) { n->max_torque = s.as<uint16_t>(); });  // the tuning's torque limit
    }
  }
  run(bus, live, o);

  for (auto& p : live) {
    ScannedNode& n = p.node;
    const std::string id = std::to_string(p.id);
    // (Segmented transfers answer with several frames: only broken
    // transfers count here.)
    if (p.protocol_error)
      n.problems.push_back("SDO transfers with node-ID " + id +
                           " broke off (toggle or sequence errors): two devices on one ID? give each its own "
                           "node-ID and scan again");
    if ((n.device_type & 0xFFFF) == 402) {
      if (!n.supported_modes)
        n.problems.push_back("device profile 402 but no supported drive modes (0x6502): check the drive's firmware");
      else if (!(*n.supported_modes & (1u << 7)))
        n.problems.push_back("the drive does not support cyclic synchronous position (CSP, bit 7 of 0x6502 = " +
                             hex32(*n.supported_modes) + "): the controller drives axes in CSP");
      n.cia402 = n.supported_modes && (*n.supported_modes & (1u << 7));
      if (n.statusword && (*n.statusword & 0x4F) == 0x08) {
        n.fault = true;
        char b[64];
        std::snprintf(b, sizeof b, "0x%04X", n.error_code.value_or(0));
        n.problems.push_back(std::string("the drive is in fault (statusword 0x") + [&] {
          char s[8];
          std::snprintf(s, sizeof s, "%04X", *n.statusword);
          return std::string(s);
        }() + ", error code " + b + "): read the drive's display or manual, remove the cause, then reset it");
      }
    }
    if (!o.eds_dir.empty()) {
      if (const EdsInfo* e = match_eds(lib, n.vendor_id, n.product_code, n.revision)) {
        n.eds = e->file.filename().string();
      } else {
        n.problems.push_back("no description file (EDS) in " + o.eds_dir.string() + " for vendor " +
                             hex32(n.vendor_id) + " product " + hex32(n.product_code) +
                             ": get it from the device's maker and put it there");
      }
    }
    r.nodes.push_back(n);
  }
  std::sort(r.nodes.begin(), r.nodes.end(), [](const auto& a, const auto& b) { return a.node_id < b.node_id; });
  for (int id : o.expected) {
    const bool found = std::any_of(r.nodes.begin(), r.nodes.end(), [&](const auto& n) { return n.node_id == id; });
    if (!found)
      r.problems.push_back("node " + std::to_string(id) + " does not answer on " + bus.name() +
                           ": check its power, the cable and termination (120 ohm at both ends), its bit rate and "
                           "its node-ID");
  }
  if (o.lss_window_ns > 0 && unconfigured_devices_present(bus, o.lss_window_ns)) {
    r.problems.push_back("one or more devices without node-ID answer LSS on " + bus.name() +
                         ": give them node-IDs with 'cnc-commission lss' (or on the devices themselves), then scan "
                         "again");
  }
  return r;
}

bool EthercatScanResult::ok() const noexcept {
  if (!problems.empty()) return false;
  for (const auto& s : slaves)
    if (!s.problems.empty()) return false;
  return true;
}

namespace {
// The CiA 402 objects the scaling step uses, read over CoE from every slave
// with a mailbox once the segment is in PREOP: supported modes (0x6502)
// and the factor group (0x608F, 0x6091, 0x6092), as the CANopen scan
// reads them. An object a slave lacks stays unknown; a segment that does
// not reach PREOP is a problem (the identities stand).
void read_factor_groups(ethercat::Master& m, EthercatScanResult& r) {
  const bool any = std::any_of(r.slaves.begin(), r.slaves.end(), [](const ScannedSlave& s) { return s.coe; });
  if (!any) return;
  try {
    m.to_preop();
  } catch (const std::exception& e) {
    r.problems.push_back(std::string("the slaves did not reach PREOP (") + e.what() +
                         "): their encoder resolution and gear (0x608F, 0x6091) were not read");
    return;
  }
  for (ScannedSlave& n : r.slaves) {
    if (!n.coe) continue;
    auto u32 = [&](uint16_t index, uint8_t sub) -> std::optional<uint32_t> {
      const ethercat::SdoResult res = m.sdo_upload(n.position, index, sub);
      if (!res.ok || res.data.empty()) return std::nullopt;
      uint32_t v = 0;
      for (std::size_t i = 0; i < res.data.size() && i < 4; ++i) v |= static_cast<uint32_t>(res.data[i]) << (8 * i);
      return v;
    };
    n.supported_modes = u32(0x6502, 0);
    n.encoder_increments = u32(0x608F, 1);
    n.encoder_motor_revs = u32(0x608F, 2);
    n.gear_motor_revs = u32(0x6091, 1);
    n.gear_shaft_revs = u32(0x6091, 2);
    n.feed = u32(0x6092, 1);
    n.feed_shaft_revs = u32(0x6092, 2);
    if (const auto t = u32(0x6072, 0)) n.max_torque = static_cast<uint16_t>(*t);  // the tuning's torque limit
  }
}
}  // namespace

EthercatScanResult scan_ethercat(const std::string& interface, const std::filesystem::path& esi_dir) {
  EthercatScanResult r;
  std::vector<ethercat::EsiFile> esis;
  if (!esi_dir.empty()) {
    std::error_code ec;
    if (!std::filesystem::is_directory(esi_dir, ec)) {
      r.problems.push_back(esi_dir.string() + ": not a folder of ESI files");
    } else {
      std::vector<std::filesystem::path> files;
      for (const auto& e : std::filesystem::directory_iterator(esi_dir, ec))
        if (e.path().extension() == ".xml") files.push_back(e.path());
      std::sort(files.begin(), files.end());
      for (const auto& f : files) {
        try {
          esis.push_back(ethercat::load_esi(f));
        } catch (const std::exception& e) {
          r.problems.push_back(e.what());
        }
      }
    }
  }
  ethercat::MasterConfig cfg;
  cfg.interface = interface;
  try {
    ethercat::Master m(cfg, nullptr);
    m.scan();
    for (const ethercat::SlaveInfo& s : m.slaves()) {
      ScannedSlave n;
      n.position = s.position;
      n.vendor_id = s.sii.vendor_id;
      n.product_code = s.sii.product_code;
      n.revision = s.sii.revision;
      n.serial = s.sii.serial;
      n.name = s.sii.name;
      n.order = s.sii.order;
      n.coe = s.sii.has_coe();
      n.dc = s.has_dc;
      if (!s.sii.checksum_ok)
        n.problems.push_back("its SII (EEPROM) checksum is wrong: the identity read may be wrong; ask the maker");
      if (!esi_dir.empty()) {
        for (const auto& f : esis) {
          if (f.vendor_id == n.vendor_id && f.find(n.product_code, n.revision)) {
            n.esi = std::filesystem::path(f.path).filename().string();
            break;
          }
        }
        if (n.esi.empty())
          n.problems.push_back("no ESI file in " + esi_dir.string() + " for vendor " + hex32(n.vendor_id) +
                               " product " + hex32(n.product_code) + ": get it from the device's maker and put it there");
      }
      r.slaves.push_back(n);
    }
    read_factor_groups(m, r);
    m.stop();
  } catch (const std::exception& e) {
    r.problems.push_back(interface + ": " + e.what());
  }
  return r;
}

std::string describe(const ScannedSlave& n) {
  std::string s = "slave " + std::to_string(n.position) + ": " + (n.name.empty() ? "(no name)" : n.name);
  s += ", vendor " + hex32(n.vendor_id) + " product " + hex32(n.product_code) + " revision " + hex32(n.revision);
  if (!n.order.empty()) s += ", order " + n.order;
  s += n.coe ? ", CoE" : ", no mailbox";
  if (n.dc) s += ", DC";
  if (n.encoder_increments) s += ", " + std::to_string(*n.encoder_increments) + " increments/rev";
  s += n.esi.empty() ? ", no ESI" : ", ESI " + n.esi;
  for (const auto& p : n.problems) s += "\n  problem: " + p;
  return s;
}

std::string describe(const ScannedNode& n) {
  std::string s = "node " + std::to_string(n.node_id) + ": ";
  s += n.name.empty() ? std::string("(no name)") : n.name;
  s += ", vendor " + hex32(n.vendor_id) + " product " + hex32(n.product_code) + " revision " + hex32(n.revision) +
       " serial " + std::to_string(n.serial);
  if (!n.firmware.empty()) s += ", firmware " + n.firmware;
  s += ", device type " + hex32(n.device_type);
  if (n.supported_modes) {
    s += ", CiA 402 (";
    bool first = true;
    for (int b = 0; b < 16; ++b)
      if ((*n.supported_modes & (1u << b)) && mode_name(b)) {
        s += (first ? "" : " ") + std::string(mode_name(b));
        first = false;
      }
    s += ")";
  }
  if (n.encoder_increments) s += ", " + std::to_string(*n.encoder_increments) + " increments/rev";
  s += n.eds.empty() ? ", no EDS" : ", EDS " + n.eds;
  for (const auto& p : n.problems) s += "\n  problem: " + p;
  return s;
}

}  // namespace cnc::commission
