// cnc-sim-random-machine: writes a randomised simulated machine for
// commissioning tests (sim/cia402/random_machine.hpp): its simulator INI
// sections, the HAL files that load and step the simulated drives, and its
// truth as JSON.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "sim/cia402/random_machine.hpp"

int main(int argc, char** argv) {
  uint64_t seed = 1;
  std::filesystem::path dir = ".";
  std::string interface = "virtual:commission";
  std::vector<int> nodes = {1, 2, 3};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "cnc-sim-random-machine: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--seed") seed = std::strtoull(value().c_str(), nullptr, 10);
    else if (a == "--dir") dir = value();
    else if (a == "--interface") interface = value();
    else if (a == "--nodes") {
      nodes.clear();
      const std::string v = value();
      for (std::size_t p = 0; p < v.size();) {
        const std::size_t c = v.find(',', p);
        nodes.push_back(std::atoi(v.substr(p, c - p).c_str()));
        p = c == std::string::npos ? v.size() : c + 1;
      }
    } else {
      std::fputs("usage: cnc-sim-random-machine [--seed N] [--dir DIR] [--interface virtual:BUS] [--nodes 1,2,3]\n"
                 "writes DIR/sim-machine.ini, sim-machine.hal, sim-machine-run.hal and sim-truth.json\n",
                 a == "--help" ? stdout : stderr);
      return a == "--help" ? 0 : 2;
    }
  }
  const auto m = cnc::cia402::sim::make_random_machine(seed, nodes, interface);
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "sim-machine.ini") << cnc::cia402::sim::sim_ini(m);
  std::ofstream(dir / "sim-machine.hal") << cnc::cia402::sim::sim_hal_load();
  std::ofstream(dir / "sim-machine-run.hal") << cnc::cia402::sim::sim_hal_run();
  std::ofstream(dir / "sim-truth.json") << cnc::cia402::sim::truth_json(m);
  return 0;
}
