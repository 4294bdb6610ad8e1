// A randomised simulated machine for commissioning tests: per axis drive a
// random encoder resolution, gear, screw lead, motor direction, backlash,
// pitch error, limit and home switch positions and the switches' active
// level, drawn from a seed. The machine is written as the
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
  // Switches at table positions (mm from where the table stands at
  // power-on): limits active at or beyond, home active in [min, max].
  double neg_limit_mm = -15, pos_limit_mm = 215;
  double home_min_mm = -10, home_max_mm = -6;
  bool switches_active_low = false;  // the inputs read 0 when actuated
  double counts_per_mm() const noexcept { return encoder_counts * gear / lead_mm; }
};

struct RandomMachine {
  uint64_t seed = 0;
  std::string interface = "virtual:commission";
  std::vector<RandomAxis> axes;
};

// Axes on nodes `nodes`, drawn from `seed` (the same seed, the same
// machine). The travel fits configs/sim/nc_files/demo.ngc: the first,
// fourth... axis (X-like) has its limits near -30 and +215 mm, the second
// (Y-like) near -30 and +135, the third (Z-like) near -65 and +30, each a
// few mm off at random (a 20 mm direction test either way stays clear), the home switch (4 to 6 mm long) 2 to 4 mm inside
// the negative limit (the Z-like axis: inside the positive one).
RandomMachine make_random_machine(uint64_t seed, const std::vector<int>& nodes, const std::string& interface);

// The simulator's INI sections (section [CIA402_SIM], CLOCK = SERVO).
std::string sim_ini(const RandomMachine& m);
// The HAL lines that load the simulated drives (before the bus master)
// and that step them in the servo thread (after the master's write).
std::string sim_hal_load();
std::string sim_hal_run();
// The truth, as JSON: seed, and per axis node, counts, gear, lead,
// reversed, counts per mm, switch positions and active level.
std::string truth_json(const RandomMachine& m);

}  // namespace cnc::cia402::sim
