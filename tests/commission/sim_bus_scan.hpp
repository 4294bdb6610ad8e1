// The bus scan of a simulated machine's drives for the commissioning tests:
// the drives of `sim_ini` (the [CIA402_SIM] section cnc-sim-random-machine
// and e2e::write_machine_files write) hosted in the test's own process on
// their virtual bus and scanned there with the library's scan (a child
// process reaches a `virtual:` bus only when it is shared, `,share`, and
// the machine files do not share theirs). And the simulated CANopen drives
// of the unit tests (scan, backup, restore) on a bus of their own.
#pragma once

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "commission/scan.hpp"
#include "core/ini/ini_file.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"

namespace cnc::commission::e2e {

// Simulated CANopen drives on a virtual bus of the test's own (wall
// clock), and `client`, the port the library under test uses.
struct SimulatedCanDrives {
  std::shared_ptr<can::VirtualBus> bus;
  std::unique_ptr<can::VirtualPort> host_port, client;
  std::unique_ptr<cia402::sim::SimHost> host;

  SimulatedCanDrives() {
    can::VirtualBusOptions o;
    o.manual_clock = false;
    bus = can::VirtualBus::create(o);
    host_port = bus->open_port("host");
    client = bus->open_port("commission");
    host = std::make_unique<cia402::sim::SimHost>(*host_port);
  }
  ~SimulatedCanDrives() { host->stop(); }
  // A drive "drive N" (10000 counts per turn); two on one node-ID get
  // ports of their own.
  cia402::sim::CanopenDrive& add(uint8_t node, uint32_t product = 0x402, uint32_t serial = 0,
                                 bool lss_unconfigured = false) {
    cia402::sim::SimNodeConfig c;
    c.node_id = node;
    c.lss_unconfigured = lss_unconfigured;
    c.identity.product_code = product;
    c.identity.serial = serial ? serial : node;
    c.drive.name = "drive " + std::to_string(node);
    c.drive.plant.encoder_counts = 10000;
    return host->add(c, bus->open_port("node-" + std::to_string(node) + "-" + std::to_string(host->size())));
  }
  // The drives' initialisation (20 ms), with room for a loaded host; an
  // SDO time-out of the library covers a late one too.
  void start() {
    host->start();
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
};

inline ScanResult scan_simulated_bus(const std::filesystem::path& sim_ini, const std::vector<int>& expected, int last) {
  namespace csim = cnc::cia402::sim;
  const auto cfg = csim::load_sim_config(ini::IniFile::load(sim_ini), "CIA402_SIM");
  can::VirtualBusOptions vo;
  vo.manual_clock = false;
  auto vbus = can::VirtualBus::create(vo);
  auto host_port = vbus->open_port("host");
  auto scanner = vbus->open_port("scanner");
  csim::SimHost host(*host_port);
  for (const auto& n : cfg.nodes) host.add(n, vbus->open_port("node-" + std::to_string(n.node_id)));
  host.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ScanOptions so;
  so.timeout_ns = 1'000'000'000;
  so.last = last;
  so.expected = expected;
  const ScanResult r = scan_canopen(*scanner, so);
  host.stop();
  return r;
}

}  // namespace cnc::commission::e2e
