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

#include <algorithm>
#include <cmath>

#include "commission/state.hpp"
#include "sim/cia402/random_machine.hpp"
#include "sim/cia402/sim_config.hpp"
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

// Where the motor (the joint position the controller reads) is when the
// table reaches a switch edge at `edge_mm` (the simulator's switches are
// at table positions) moving in `dir` (+1, -1): the table is the nut
// (nominal + pitch error, sim/cia402/plant.hpp) less half the backlash on
// the side the nut pushes it from.
inline double motor_side_edge(const cia402::sim::RandomAxis& a, double edge_mm, double dir) {
  const auto& p = a.pitch_error;
  double pe = p.empty() ? 0.0 : edge_mm <= p.front().first ? p.front().second : p.back().second;
  for (std::size_t i = 1; i < p.size(); ++i)
    if (edge_mm > p[i - 1].first && edge_mm <= p[i].first) {
      const double f = (edge_mm - p[i - 1].first) / (p[i].first - p[i - 1].first);
      pe = p[i - 1].second + f * (p[i].second - p[i - 1].second);
    }
  return edge_mm + dir * a.backlash_mm / 2 - pe;
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

// The simulated drive's true limits, from its configuration (the same INI
// the controller loads) and the drive model's rules
// (sim/cia402/drive_model.cpp, plant.cpp):
// - velocity: the drive's CSP interpolation is bounded by its maximum
//   motor speed 0x6080 (MAX_MOTOR_SPEED, 6000 rpm): lead / gear x rpm / 60;
// - acceleration at `velocity_for_acc`: the torque the drive gives,
//   min(0x6072 x rated torque, torque constant x current limit) =
//   min(300 % x 3.2, 0.8 x 15) N m, less Coulomb and viscous friction,
//   over the reflected inertia (motor + table mass x (lead / 2 pi gear)^2),
//   times lead / 2 pi gear.
struct Capability {
  double velocity = 0;      // mm/s
  double acceleration = 0;  // mm/s^2
};
inline Capability capability(const cia402::sim::SimNodeConfig& n, double velocity_for_acc) {
  const cia402::sim::PlantConfig& p = n.drive.plant;
  const double r = p.lead_m / (2 * M_PI * p.gear);  // m per motor radian
  Capability c;
  c.velocity = n.drive.max_motor_speed_rpm / 60.0 * 2 * M_PI * r * 1000;
  const double torque = std::min(3.0 * p.rated_torque, p.torque_constant * p.max_current);  // 0x6072 = 300 %
  const double omega = velocity_for_acc / 1000 / r;
  const double friction = p.motor_coulomb + p.load_coulomb * r + (p.motor_viscous + p.load_viscous * r * r) * omega;
  const double j = p.motor_inertia + p.load_mass * r * r;
  c.acceleration = (torque - friction) / j * r * 1000;
  return c;
}

}  // namespace cnc::commission::e2e
