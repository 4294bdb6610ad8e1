// What the commissioning end-to-end tests share: a random simulated
// machine (sim/cia402/random_machine) written as the files cncd includes,
// its seed (CNC_COMMISSION_SEED, else a random one, printed so a failure
// can be repeated), and small file and `cnc` helpers.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "commission/state.hpp"
#include "sim/cia402/random_machine.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission::e2e {

inline void write_text(const std::filesystem::path& p, const std::string& s) {
  std::ofstream out(p);
  out << s;
}

inline std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A shell command line running the build's `cnc` with `args`.
inline std::string cnc_cmd(const std::string& args) {
  return "'" + (testing::binary_dir() / "bin/cnc").string() + "' " + args;
}

// CNC_COMMISSION_SEED, else a random seed; printed either way.
inline uint64_t machine_seed() {
  uint64_t seed = std::random_device{}();
  if (const char* s = std::getenv("CNC_COMMISSION_SEED")) seed = std::strtoull(s, nullptr, 10);
  std::printf("random machine seed %llu (CNC_COMMISSION_SEED=%llu repeats it)\n", static_cast<unsigned long long>(seed),
              static_cast<unsigned long long>(seed));
  return seed;
}

// The machine's simulator sections and HAL files in `dir`
// (sim-machine.ini, sim-machine.hal, sim-machine-run.hal), and the state's
// references to them, so that every configuration written includes them.
inline void write_machine_files(const std::filesystem::path& dir, const cia402::sim::RandomMachine& m) {
  write_text(dir / "sim-machine.ini", cia402::sim::sim_ini(m));
  write_text(dir / "sim-machine.hal", cia402::sim::sim_hal_load());
  write_text(dir / "sim-machine-run.hal", cia402::sim::sim_hal_run());
}
inline void include_machine_files(State& s) {
  s.ini_includes = {"sim-machine.ini"};
  s.hal_before_bus = {"sim-machine.hal"};
  s.hal_after_bus = {"sim-machine-run.hal"};
}

}  // namespace cnc::commission::e2e
