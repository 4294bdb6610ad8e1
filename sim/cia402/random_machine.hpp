// A randomised simulated machine for commissioning tests: per axis drive a
// random encoder resolution, gear, screw lead, motor direction, backlash
// and pitch error, drawn from a seed. The machine is written as the
// simulator's INI sections ([CIA402_SIM], docs/configuration.md) and HAL
// lines, plus its truth as JSON for the test's final checks; the
// commissioning code under test never reads the truth. Simulation only.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace cnc::cia402::sim {

struct RandomAxis {
  int node = 1;
  double encoder_counts = 131072;  // increments per motor revolution
  double gear = 1;                 // motor revolutions per screw revolution
  double lead_mm = 5;              // table travel per screw revolution
  bool motor_reversed = false;
  double backlash_mm = 0;
  std::vector<std::pair<double, double>> pitch_error;  // (position mm, error mm)
  double counts_per_mm() const noexcept { return encoder_counts * gear / lead_mm; }
};

struct RandomMachine {
  uint64_t seed = 0;
  std::string interface = "virtual:commission";
  std::vector<RandomAxis> axes;
};

// Axes on nodes `nodes`, drawn from `seed` (the same seed, the same machine).
RandomMachine make_random_machine(uint64_t seed, const std::vector<int>& nodes, const std::string& interface);

// The simulator's INI sections (section [CIA402_SIM], CLOCK = SERVO).
std::string sim_ini(const RandomMachine& m);
// The HAL lines that load the simulated drives (before the bus master)
// and that step them in the servo thread (after the master's write).
std::string sim_hal_load();
std::string sim_hal_run();
// The truth, as JSON: seed, and per axis node, counts, gear, lead,
// reversed, counts per mm.
std::string truth_json(const RandomMachine& m);

}  // namespace cnc::cia402::sim
