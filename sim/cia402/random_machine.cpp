#include "sim/cia402/random_machine.hpp"

#include <cstdio>
#include <random>
#include <sstream>

namespace cnc::cia402::sim {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}
template <class T, std::size_t N>
T pick(std::mt19937_64& rng, const T (&v)[N]) {
  return v[std::uniform_int_distribution<std::size_t>(0, N - 1)(rng)];
}
}  // namespace

RandomMachine make_random_machine(uint64_t seed, const std::vector<int>& nodes, const std::string& interface) {
  RandomMachine m;
  m.seed = seed;
  m.interface = interface;
  std::mt19937_64 rng(seed);
  // Values a retrofit meets: encoders of 4096 (1024-line quadrature) to
  // 2^17 increments, belt or gearbox reductions, metric screw leads.
  const double counts[] = {4096, 8000, 10000, 131072};
  const double gears[] = {1, 1.5, 2, 3};
  const double leads[] = {4, 5, 10};
  for (int n : nodes) {
    RandomAxis a;
    a.node = n;
    a.encoder_counts = pick(rng, counts);
    a.gear = pick(rng, gears);
    a.lead_mm = pick(rng, leads);
    a.motor_reversed = std::uniform_int_distribution<int>(0, 1)(rng) == 1;
    a.backlash_mm = std::uniform_real_distribution<double>(0.0, 0.008)(rng);
    std::uniform_real_distribution<double> err(-0.005, 0.005);
    for (double x = -300; x <= 300; x += 100) a.pitch_error.emplace_back(x, x == 0 ? 0.0 : err(rng));
    // Switches (drawn after the rest, so older seeds keep their drives).
    static const double kTravel[3][2] = {{-30, 215}, {-30, 135}, {-65, 30}};
    const std::size_t k = m.axes.size() % 3;
    std::uniform_real_distribution<double> jitter(-3.0, 3.0), inside(2.0, 4.0), length(4.0, 6.0);
    a.neg_limit_mm = kTravel[k][0] + jitter(rng);
    a.pos_limit_mm = kTravel[k][1] + jitter(rng);
    const double len = length(rng);
    if (k == 2) {
      a.home_max_mm = a.pos_limit_mm - inside(rng);
      a.home_min_mm = a.home_max_mm - len;
    } else {
      a.home_min_mm = a.neg_limit_mm + inside(rng);
      a.home_max_mm = a.home_min_mm + len;
    }
    a.switches_active_low = std::uniform_int_distribution<int>(0, 1)(rng) == 1;
    m.axes.push_back(a);
  }
  return m;
}

std::string sim_ini(const RandomMachine& m) {
  std::ostringstream o;
  o << "# A randomised simulated machine (seed " << m.seed << "), made by cnc-sim-random-machine.\n"
    << "[CIA402_SIM]\nINTERFACE = " << m.interface << "\nCLOCK = SERVO\nNODE =";
  for (const auto& a : m.axes) o << " " << a.node;
  o << "\nSTEP_US = 20\n";
  for (const auto& a : m.axes) {
    o << "\n[CIA402_SIM_NODE_" << a.node << "]\nNAME = axis-" << a.node << "\nENCODER_COUNTS = " << num(a.encoder_counts)
      << "\nGEAR = " << num(a.gear) << "\nSCREW_LEAD = " << num(a.lead_mm)
      << "\nMOTOR_REVERSED = " << (a.motor_reversed ? "YES" : "NO")
      << "\nLOAD_MASS = 200\nLOAD_COULOMB = 40\nMAX_CURRENT = 15\nSYNC_TIMEOUT_MS = 500\nBACKLASH = "
      << num(a.backlash_mm) << "\nNEG_LIMIT_SWITCH = " << num(a.neg_limit_mm) << "\nPOS_LIMIT_SWITCH = "
      << num(a.pos_limit_mm) << "\nHOME_SWITCH = " << num(a.home_min_mm) << " " << num(a.home_max_mm)
      << "\nSWITCHES_ACTIVE_LOW = " << (a.switches_active_low ? "YES" : "NO") << "\nPITCH_ERROR =";
    for (const auto& [x, e] : a.pitch_error) o << " " << num(x) << ":" << num(e);
    o << "\n";
  }
  return o.str();
}

std::string sim_hal_load() { return "# The simulated drives: loaded before the bus master.\nloadrt cia402_sim sections=CIA402_SIM\n"; }
std::string sim_hal_run() {
  return "# The simulated drives step after the master's write.\naddf cia402-sim.0.update servo-thread\n";
}

std::string truth_json(const RandomMachine& m) {
  std::ostringstream o;
  o << "{\"seed\": " << m.seed << ", \"axes\": [";
  for (std::size_t i = 0; i < m.axes.size(); ++i) {
    const auto& a = m.axes[i];
    o << (i ? ", " : "") << "{\"node\": " << a.node << ", \"encoder_counts\": " << num(a.encoder_counts)
      << ", \"gear\": " << num(a.gear) << ", \"lead_mm\": " << num(a.lead_mm)
      << ", \"motor_reversed\": " << (a.motor_reversed ? "true" : "false")
      << ", \"counts_per_mm\": " << num(a.counts_per_mm()) << ", \"neg_limit_mm\": " << num(a.neg_limit_mm)
      << ", \"pos_limit_mm\": " << num(a.pos_limit_mm) << ", \"home_min_mm\": " << num(a.home_min_mm)
      << ", \"home_max_mm\": " << num(a.home_max_mm)
      << ", \"switches_active_low\": " << (a.switches_active_low ? "true" : "false") << "}";
  }
  o << "]}\n";
  return o.str();
}

}  // namespace cnc::cia402::sim
