// cia402_bench: the figures issue 8 asks for, reproducible from the
// repository. The simulated mill of configs/sim (three CiA 402 drive
// simulators with their plants on an in-process CANopen bus at 1 kHz, the
// CANopen master, the drive layer, motion, task and interpreter) is built
// in-process and stepped in simulated time (tests/comp/sim_mill.hpp); after
// E-stop reset, machine on and homing it runs benchmark programs and
// samples every servo cycle while they run:
//  1. following error per joint: motion's (joint.N.f-error: command minus
//     feedback, which includes the bus's transport delay of two cycles) and
//     the drive layer's (cia402.0.drive.NN.following-error: the target of
//     two cycles ago minus the position actual, i.e. the drive's tracking
//     error), max and RMS;
//  2. compute time of the drive layer's servo functions (cia402.N.read,
//     cia402.N.write) and, for scale, of the CANopen master's and the
//     simulator's, from the functions' `.time` parameters: median, p99, max.
// Timing figures are wall-clock on a shared machine: medians mean something,
// maxima are scheduler noise.
// Usage: cia402_bench [--keep DIR] [--program FILE.ngc ...]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "cia402/components.hpp"
#include "fieldbus/canopen/components.hpp"
#include "tests/comp/sim_mill.hpp"
#include "tests/fieldbus/canopen/pace.hpp"

using namespace cnc;

namespace {

// A program at the machine's limits: rapids across the travel, long feeds
// at 6 m/min, short zig-zags and full circles at 3 m/min.
const char* kFastProgram = R"(%
(cia402_bench: traverses and feeds at the machine's limits)
G21 G17 G40 G49 G80 G90 G94 G64 P0.01
G53 G0 Z-5
G53 G0 X10 Y10
G53 G0 X290 Y190
G53 G0 X10 Y10
G53 G0 X290 Y10
G53 G0 X10 Y190
G53 G1 X150 Y100 F6000
G53 G1 X250 Y100
G53 G1 X250 Y150
G53 G1 X150 Y150
G53 G1 X150 Y100
#<i> = 0
o100 while [#<i> LT 40]
  G53 G1 X[150 + #<i> * 2 + 1] Y110 F3000
  G53 G1 X[150 + #<i> * 2 + 2] Y112
  #<i> = [#<i> + 1]
o100 endwhile
G53 G0 X150 Y100
G17 G91 G2 X0 Y0 I30 J0 F3000
G2 X0 Y0 I30 J0
G3 X0 Y0 I30 J0
G90
G53 G0 Z-60
G53 G1 Z-5 F3000
G53 G0 X180 Y110
M2
%
)";

struct Series {
  std::vector<double> v;
  double max_abs() const {
    double m = 0;
    for (double x : v) m = std::max(m, std::fabs(x));
    return m;
  }
  double rms() const {
    double s = 0;
    for (double x : v) s += x * x;
    return v.empty() ? 0 : std::sqrt(s / static_cast<double>(v.size()));
  }
  double pct(double q) const {
    if (v.empty()) return 0;
    std::vector<double> c = v;
    std::sort(c.begin(), c.end());
    return c[static_cast<std::size_t>(q * static_cast<double>(c.size() - 1))];
  }
};

struct Probe {
  std::string name;
  Series s;
};

double value(hal::Hal& hal, const std::string& name) { return std::stod(hal.get_value(name)); }

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

int main(int argc, char** argv) {
  const char* keep = nullptr;
  std::vector<std::pair<std::string, std::string>> programs;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--keep") && i + 1 < argc) keep = argv[++i];
    else if (!std::strcmp(argv[i], "--program") && i + 1 < argc) {
      const std::string p = argv[++i];
      programs.emplace_back(std::filesystem::path(p).filename().string(), read_file(p));
    } else {
      std::fprintf(stderr, "usage: cia402_bench [--keep DIR] [--program FILE.ngc ...]\n");
      return 2;
    }
  }
  const std::filesystem::path src(CNC_SOURCE_DIR);
  if (programs.empty()) {
    programs.emplace_back("demo.ngc", read_file((src / "configs/sim/nc_files/demo.ngc").string()));
    programs.emplace_back("fast.ngc", kFastProgram);
  }
  const std::filesystem::path work =
      keep ? std::filesystem::path(keep) : std::filesystem::temp_directory_path() / ("cia402_bench_" + std::to_string(::getpid()));
  cnc::testing::SimMill mill(src / "configs/sim", work, "sim.ini", [](hal::ComponentRegistry& r) {
    canopen::register_components(r);
    cia402::register_components(r);
  });
  mill.pace = canopen::test::acyclic_pacer(mill.hal());
  if (std::string e = mill.power_up(); !e.empty()) {
    std::printf("FAILED: power up: %s\n", e.c_str());
    return 1;
  }
  hal::Hal& hal = mill.hal();
  std::vector<Probe> motion_fe, drive_fe, times;
  for (int j = 0; j < 3; ++j) {
    motion_fe.push_back({"joint." + std::to_string(j) + ".f-error", {}});
    // X and Y on canopen.0 (cia402.0), Z on canopen.1 beside the spindle.
    static const char* const kDrive[] = {"cia402.0.drive.00", "cia402.0.drive.01", "cia402.1.drive.01"};
    drive_fe.push_back({std::string(kDrive[j]) + ".following-error", {}});
  }
  for (const char* f : {"cia402.0.read", "cia402.0.write", "cia402.1.read", "cia402.1.write", "canopen.0.read",
                        "canopen.0.write", "canopen.1.read", "canopen.1.write", "cia402-sim.0.update", "cia402-sim.1.update",
                        "motion-controller"}) {
    times.push_back({f, {}});
  }
  // A TPDO that missed its SYNC leaves last cycle's position in
  // the input image: the drive layer's error is then one cycle of motion
  // too large. Such samples are counted and kept apart.
  std::vector<Probe> drive_fe_fresh, sim_fe;
  for (int j = 0; j < 3; ++j) {
    char d[48];
    std::snprintf(d, sizeof d, "cia402-sim.%d.node.%02d.following-error", j < 2 ? 0 : 1, j + 1);
    sim_fe.push_back({d, {}});
  }
  std::vector<double> missed_before(3, 0);
  std::vector<int> stale(3, 0);
  for (const auto& p : drive_fe) drive_fe_fresh.push_back({p.name, {}});
  bool sampling = false;
  mill.on_cycle = [&] {
    if (!sampling) return;
    for (auto& p : motion_fe) p.s.v.push_back(value(hal, p.name));
    for (auto& p : sim_fe) p.s.v.push_back(value(hal, p.name));  // increments, inside the drive
    for (std::size_t j = 0; j < drive_fe.size(); ++j) {
      const double fe = value(hal, drive_fe[j].name);
      drive_fe[j].s.v.push_back(fe);
      char pin[48];
      std::snprintf(pin, sizeof pin, "canopen.%d.node.%02zu.pdo-missed", j < 2 ? 0 : 1, j + 1);
      const double missed = value(hal, pin);
      if (missed != missed_before[j]) ++stale[j];
      else drive_fe_fresh[j].s.v.push_back(fe);
      missed_before[j] = missed;
    }
    for (auto& p : times) p.s.v.push_back(value(hal, p.name + ".time") * 1e-3);  // us
  };
  std::printf("cia402_bench: configs/sim in simulated time (1 kHz servo, CANopen at 1 Mbit/s, drives at 20 us steps)\n");
  for (const auto& [name, text] : programs) {
    for (auto* group : {&motion_fe, &drive_fe, &drive_fe_fresh, &sim_fe, &times}) {
      for (auto& p : *group) p.s.v.clear();
    }
    std::fill(stale.begin(), stale.end(), 0);
    const double t0 = mill.seconds();
    sampling = true;
    const std::string e = mill.run_program(name, text, 600);
    sampling = false;
    if (!e.empty()) {
      std::printf("FAILED: %s: %s\n", name.c_str(), e.c_str());
      return 1;
    }
    std::printf("\n%s: %.1f s simulated, %zu cycles sampled\n", name.c_str(), mill.seconds() - t0,
                motion_fe[0].s.v.size());
    std::printf("  following error (um)          max      RMS\n");
    for (int j = 0; j < 3; ++j) {
      std::printf("  joint %d  motion (cmd - fb)  %7.1f  %7.1f     drive (target[k-2] - actual)  %6.2f  %6.2f"
                  "   fresh inputs only  %6.2f  %6.2f  (%d cycles with a missed TPDO)\n",
                  j, motion_fe[j].s.max_abs() * 1e3, motion_fe[j].s.rms() * 1e3, drive_fe[j].s.max_abs() * 1e3,
                  drive_fe[j].s.rms() * 1e3, drive_fe_fresh[j].s.max_abs() * 1e3, drive_fe_fresh[j].s.rms() * 1e3,
                  stale[static_cast<std::size_t>(j)]);
    }
    std::printf("  inside the simulated drives (demand - actual, sampled at the cycle end), um:");
    for (int j = 0; j < 3; ++j) {
      std::printf("  joint %d %.2f / %.2f", j, sim_fe[static_cast<std::size_t>(j)].s.max_abs() / 26.2144,
                  sim_fe[static_cast<std::size_t>(j)].s.rms() / 26.2144);
    }
    std::printf("\n");
    std::printf("  servo function time (us)      median    p99      max\n");
    for (const auto& p : times) {
      std::printf("  %-24s  %7.2f  %7.2f  %7.1f\n", p.name.c_str(), p.s.pct(0.5), p.s.pct(0.99), p.s.pct(1.0));
    }
  }
  if (!keep) std::filesystem::remove_all(work);
  return 0;
}
