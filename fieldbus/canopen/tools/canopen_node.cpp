// cnc-canopen-node: simulated CANopen devices on a CAN interface, for tests
// across processes (VM, vcan) and for trying a configuration without
// hardware. Each device is built from an EDS (or a small built-in
// dictionary) and may echo objects at every SYNC (--echo 0x607A:0=0x6064:0:
// the position follows the target). Writing a code to 0x2FFF:00 sends that
// EMCY (0 = error reset), for fault-path tests.
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/util/strings.hpp"
#include "core/util/time.hpp"
#include "fieldbus/can/transport.hpp"
#include "fieldbus/canopen/eds.hpp"
#include "fieldbus/canopen/slave_runner.hpp"

using namespace cnc;
using namespace cnc::canopen;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

void usage() {
  std::fprintf(stderr,
               "usage: cnc-canopen-node --interface IF --node ID [--node ID ...] [options]\n"
               "  --interface IF        socketcan:vcan0, virtual:<bus> (same process only)\n"
               "  --node ID             a device with this node-ID (repeatable)\n"
               "  --lss-unconfigured SERIAL  a device without node-ID (LSS, CiA 305) with this\n"
               "                        serial number, waiting for an LSS master (repeatable)\n"
               "  --lss                 the devices of --node answer LSS too\n"
               "  --eds FILE            its object dictionary (default: a built-in CiA-402-like one)\n"
               "  --echo A=B            at each SYNC copy object A to B (index:sub), repeatable\n"
               "  --heartbeat-ms N      default producer heartbeat time (0x1017)\n"
               "  --vendor N --product N --revision N   identity (built-in dictionary)\n"
               "  --duration-s S        exit after S seconds (default: until SIGINT/SIGTERM)\n"
               "  --quiet               no status line at exit\n");
}

struct Echo {
  ObjectAddress from, to;
};

struct Device {
  std::unique_ptr<ObjectDictionary> od;
  std::unique_ptr<SlaveNode> node;
};

std::optional<ObjectAddress> parse_addr(const std::string& s) {
  const auto parts = split(s, ':');
  if (parts.size() != 2) return std::nullopt;
  const auto i = parse_uint(parts[0]);
  const auto k = parse_uint(parts[1]);
  if (!i || !k || *i > 0xFFFF || *k > 0xFF) return std::nullopt;
  return ObjectAddress{static_cast<uint16_t>(*i), static_cast<uint8_t>(*k)};
}

void builtin_dictionary(ObjectDictionary& od) {
  using D = DataType;
  using A = Access;
  od.add({0x6040, 0}, D::Unsigned16, A::ReadWrite, 0, true, "Controlword");
  od.add({0x6041, 0}, D::Unsigned16, A::ReadOnly, 0x0250, true, "Statusword");
  od.add({0x6060, 0}, D::Integer8, A::ReadWrite, 8, true, "Modes of operation");
  od.add({0x6061, 0}, D::Integer8, A::ReadOnly, 8, true, "Modes of operation display");
  od.add({0x6064, 0}, D::Integer32, A::ReadOnly, 0, true, "Position actual value");
  od.add({0x606C, 0}, D::Integer32, A::ReadOnly, 0, true, "Velocity actual value");
  od.add({0x607A, 0}, D::Integer32, A::ReadWrite, 0, true, "Target position");
  od.add({0x60FD, 0}, D::Unsigned32, A::ReadOnly, 0, true, "Digital inputs");
  od.add({0x6502, 0}, D::Unsigned32, A::ReadOnly, 0x380, false, "Supported drive modes");
  od.add_bytes({0x2001, 0}, D::Domain, A::ReadWrite, {}, 4096, "Scratch domain");
}

}  // namespace

int main(int argc, char** argv) {
  std::string interface, eds_file;
  std::vector<uint8_t> ids;
  std::vector<uint32_t> lss_serials;  // devices without node-ID
  bool lss = false;
  std::vector<Echo> echoes;
  uint16_t heartbeat_ms = 0;
  double duration_s = 0;
  bool quiet = false;
  SlaveIdentity identity{0x00020192, 0xCC1, 0x402, 0x00010002, 0, "cnc-canopen-node"};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        usage();
        std::exit(2);
      }
      return argv[++i];
    };
    auto number = [&](const std::string& v) -> uint64_t {
      const auto n = parse_uint(v);
      if (!n) {
        std::fprintf(stderr, "cnc-canopen-node: %s: expected a number, got \"%s\"\n", a.c_str(), v.c_str());
        std::exit(2);
      }
      return *n;
    };
    if (a == "--interface") interface = next();
    else if (a == "--node") {
      const uint64_t id = number(next());
      if (!is_valid_node_id(static_cast<unsigned>(id)) || id > 127) {
        std::fprintf(stderr, "cnc-canopen-node: --node %llu: expected 1..127\n", static_cast<unsigned long long>(id));
        return 2;
      }
      ids.push_back(static_cast<uint8_t>(id));
    } else if (a == "--lss-unconfigured") {
      lss_serials.push_back(static_cast<uint32_t>(number(next())));
    } else if (a == "--lss") lss = true;
    else if (a == "--eds") eds_file = next();
    else if (a == "--echo") {
      const std::string v = next();
      const auto eq = v.find('=');
      const auto from = parse_addr(v.substr(0, eq));
      const auto to = eq == std::string::npos ? std::nullopt : parse_addr(v.substr(eq + 1));
      if (!from || !to) {
        std::fprintf(stderr, "cnc-canopen-node: --echo %s: expected index:sub=index:sub\n", v.c_str());
        return 2;
      }
      echoes.push_back({*from, *to});
    } else if (a == "--heartbeat-ms") heartbeat_ms = static_cast<uint16_t>(number(next()));
    else if (a == "--vendor") identity.vendor_id = static_cast<uint32_t>(number(next()));
    else if (a == "--product") identity.product_code = static_cast<uint32_t>(number(next()));
    else if (a == "--revision") identity.revision = static_cast<uint32_t>(number(next()));
    else if (a == "--duration-s") duration_s = static_cast<double>(number(next()));
    else if (a == "--quiet") quiet = true;
    else {
      usage();
      return 2;
    }
  }
  if (interface.empty() || (ids.empty() && lss_serials.empty())) {
    usage();
    return 2;
  }
  try {
    std::unique_ptr<DeviceDescription> eds;
    if (!eds_file.empty()) eds = std::make_unique<DeviceDescription>(load_eds(eds_file));
    auto transport = can::open_transport(interface);
    SlaveRunner runner(*transport);
    std::vector<Device> devices;
    // Devices without node-ID are 0xFF until LSS gives them one.
    std::vector<std::pair<uint8_t, uint32_t>> devs;
    for (uint8_t id : ids) devs.emplace_back(id, id);
    for (uint32_t serial : lss_serials) devs.emplace_back(lss::kUnconfigured, serial);
    for (const auto& [id, serial] : devs) {
      Device d;
      d.od = std::make_unique<ObjectDictionary>();
      if (eds) eds->build_dictionary(*d.od, id);
      else builtin_dictionary(*d.od);
      if (!d.od->find({0x2FFF, 0})) d.od->add({0x2FFF, 0}, DataType::Unsigned16, Access::ReadWrite, 0, false, "EMCY trigger");
      SlaveOptions o;
      o.node_id = id;
      o.identity = identity;
      o.identity.serial = serial;
      o.lss = lss || id == lss::kUnconfigured;
      o.heartbeat_ms = heartbeat_ms;
      d.node = std::make_unique<SlaveNode>(*d.od, *transport, o);
      for (const Echo& e : echoes) {
        if (!d.od->find(e.from) || !d.od->find(e.to)) {
          std::fprintf(stderr, "cnc-canopen-node: --echo: object missing in the dictionary of node %u\n", id);
          return 2;
        }
      }
      ObjectDictionary* od = d.od.get();
      SlaveNode* node = d.node.get();
      d.node->on_sync = [od, echoes](uint8_t, int64_t) {
        for (const Echo& e : echoes) {
          const OdEntry* from = od->find(e.from);
          const OdEntry* to = od->find(e.to);
          std::memcpy(od->data(*to), od->data(*from), std::min(from->capacity, to->capacity));
        }
      };
      d.od->set_after_write({0x2FFF, 0}, [od, node](const OdEntry&) {
        const uint16_t code = od->get<uint16_t>({0x2FFF, 0});
        if (code) node->emcy(code, 0x80);
        else node->clear_emcy();
      });
      runner.add(*d.node);
      devices.push_back(std::move(d));
    }
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    runner.start();
    const int64_t end = duration_s > 0 ? monotonic_ns() + static_cast<int64_t>(duration_s * 1e9) : INT64_MAX;
    while (!g_stop && monotonic_ns() < end) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    runner.stop();
    if (!quiet) {
      for (const Device& d : devices) {
        const auto& c = d.node->counters();
        std::printf("node %u: %s, %llu SYNC, %llu RPDO, %llu TPDO, %llu EMCY\n", d.node->node_id(),
                    to_string(d.node->state()), static_cast<unsigned long long>(c.syncs),
                    static_cast<unsigned long long>(c.rpdos), static_cast<unsigned long long>(c.tpdos),
                    static_cast<unsigned long long>(c.emcys));
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cnc-canopen-node: %s\n", e.what());
    return 1;
  }
  return 0;
}
