// The bus scan of a simulated machine's drives for the commissioning tests:
// the drives of `sim_ini` (the [CIA402_SIM] section cnc-sim-random-machine
// and e2e::write_machine_files write) hosted in the test's own process on
// their virtual bus and scanned there with the library's scan. A child
// process (cnc-commission scan, the wizard's page 1) cannot reach them: a
// `virtual:` bus is in-process, and inside cncd its drives are cncd's own.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "commission/scan.hpp"
#include "core/ini/ini_file.hpp"
#include "sim/can/virtual_bus.hpp"
#include "sim/cia402/sim_config.hpp"
#include "sim/cia402/sim_host.hpp"

namespace cnc::commission::e2e {

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
