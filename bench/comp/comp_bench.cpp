// comp_bench: the figures issue 10 asks for, reproducible from the
// repository.
//  1. Fit time for 1000 measured points (median, min and max of repeated
//     fits, wall clock of fit_error_model alone).
//  2. Model error on synthetic data: the fitted model against the known
//     truth at 20 C over the whole travel, both directions (max and RMS),
//     over several seeds with noise and gross outliers; and the recovered
//     parameters. Goal: at most 0.5 um.
//  3. Table lookup in the servo path (ScrewCompensation::correction),
//     nanoseconds per call for several table sizes.
//  4. The closed loop on the simulated axis (tests/comp: controller,
//     ISO 230-2 cycle, fit, JOINT_LOAD_COMP, cycle again): A and B before
//     and after. Goals: A reduced by at least 90 %, B at most 1 um.
//  5. With --cia402: the same loop on configs/sim's CiA 402 X axis (minutes).
// Usage: comp_bench [--seeds N] [--repeats N] [--no-closed-loop] [--cia402] [--keep DIR]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "comp/cycle.hpp"
#include "comp/fit.hpp"
#include "comp/screw_compensation.hpp"
#include "comp/synthetic.hpp"
#include "tests/comp/closed_loop.hpp"
#include "tests/comp/lead_screw_plant.hpp"
#ifdef CNC_HAVE_CIA402
#include "cia402/components.hpp"
#include "fieldbus/canopen/components.hpp"
#endif

using namespace cnc;
using namespace cnc::comp;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * (v.size() - 1))];
}

// The ISO cycle plus the periodic runs of a synthetic axis.
std::vector<Measurement> iso_and_periodic(const SyntheticAxis& axis, uint64_t seed, int targets = 0) {
  CycleOptions co;
  co.x_min = axis.x_min;
  co.x_max = axis.x_max;
  co.seed = seed;
  co.targets = targets;
  co.lead_mm = axis.lead_mm;
  std::vector<Measurement> data{synthesize_cycle(axis, iso_targets(co), 5, seed, true)};
  double t = data[0].points.back().time_s;
  for (int place = 0; place < co.periodic_places; ++place) {
    data.push_back(synthesize_cycle(axis, periodic_targets(co, place), co.periodic_runs, seed * 100 + place, true, t));
    t = data.back().points.back().time_s;
  }
  return data;
}

std::size_t points(const std::vector<Measurement>& d) {
  std::size_t n = 0;
  for (const auto& m : d) n += m.points.size();
  return n;
}

void fit_time(int repeats) {
  std::printf("1. Fit time (fit_error_model: Ceres, dense QR, robust loss, covariance)\n");
  SyntheticAxis axis;
  // 1000 points: 80 ISO targets x 5 runs x 2 directions + 3 x 17 periodic
  // points x 2 runs x 2 directions = 800 + 204 = 1004.
  for (const int targets : {13, 80}) {
    const auto data = iso_and_periodic(axis, 1, targets);
    FitOptions o;
    o.lead_mm = axis.lead_mm;
    std::vector<double> t;
    FitResult f;
    for (int i = 0; i < repeats; ++i) {
      const auto t0 = Clock::now();
      f = fit_error_model(data, o);
      t.push_back(ms_since(t0));
    }
    std::printf("   %5zu points, %zu spline segments: median %.1f ms, min %.1f, max %.1f (%d fits, %d iterations)\n",
                points(data), f.model.segments(), percentile(t, 0.5), percentile(t, 0), percentile(t, 1), repeats,
                f.iterations);
  }
}

void model_error(int seeds) {
  std::printf("\n2. Model error on synthetic data (truth: 15 ppm scale error, 3 um bump, 1.5 um at the 5 mm lead,\n"
              "   backlash 8 um +- 1 um along travel, 11.5 ppm/K with a 2 K warm-up, noise 0.1 um, 3 outliers of\n"
              "   25 um per measurement; model vs truth at 20 C, both directions, 3000 positions)\n");
  std::vector<double> worst, rms, b0, amp, k, res;
  for (int s = 1; s <= seeds; ++s) {
    SyntheticAxis axis;
    const auto data = iso_and_periodic(axis, static_cast<uint64_t>(s));
    FitOptions o;
    o.lead_mm = axis.lead_mm;
    const FitResult f = fit_error_model(data, o);
    double w = 0, ss = 0;
    int n = 0;
    for (int i = 0; i <= 3000; ++i) {
      const double x = axis.x_min + (axis.x_max - axis.x_min) * i / 3000.0;
      for (int d : {1, -1}) {
        const double e = f.model.deviation_um(x, d) - axis.deviation_um(x, d, axis.reference_c);
        w = std::max(w, std::fabs(e));
        ss += e * e;
        ++n;
      }
    }
    worst.push_back(w);
    rms.push_back(std::sqrt(ss / n));
    b0.push_back(f.model.backlash0_um);
    amp.push_back(std::hypot(f.model.sin_um[0], f.model.cos_um[0]));
    k.push_back(f.model.thermal_ppm_per_k);
    res.push_back(f.residual_rms_um);
  }
  const auto range = [](const std::vector<double>& v) {
    return std::make_pair(*std::min_element(v.begin(), v.end()), *std::max_element(v.begin(), v.end()));
  };
  std::printf("   %d seeds (1..%d), 334 points each\n", seeds, seeds);
  std::printf("   max |model - truth|: worst seed %.3f um, median %.3f um   (goal <= 0.5 um)\n", range(worst).second,
              percentile(worst, 0.5));
  std::printf("   RMS  model - truth : worst seed %.3f um, median %.3f um\n", range(rms).second, percentile(rms, 0.5));
  std::printf("   residual RMS vs the measurements: %.3f..%.3f um (noise 0.100 um)\n", range(res).first, range(res).second);
  std::printf("   recovered: backlash b0 %.3f..%.3f um (8), periodic amplitude %.3f..%.3f um (1.5), k %.2f..%.2f ppm/K (11.5)\n",
              range(b0).first, range(b0).second, range(amp).first, range(amp).second, range(k).first, range(k).second);
}

void lookup_time() {
  std::printf("\n3. Table lookup in the servo path (ScrewCompensation::correction, ns per call, random positions)\n");
  volatile double sink = 0;
  for (const int size : {256, 5000, 100000}) {
    CompTable t;
    for (int i = 0; i < size; ++i) {
      t.nominal.push_back(i * 300.0 / size);
      t.forward.push_back(1e-3 * std::sin(i * 0.01));
      t.reverse.push_back(-1e-3 * std::cos(i * 0.01));
    }
    ScrewCompensation c;
    c.install(t);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> pos(-5, 305);
    std::vector<double> xs(1 << 16);
    for (double& x : xs) x = pos(rng);
    std::vector<double> per_call;
    for (int rep = 0; rep < 15; ++rep) {
      const auto t0 = Clock::now();
      for (std::size_t i = 0; i < xs.size(); ++i) {
        double v = 0;
        c.correction(xs[i], (i & 1) ? 1.0 : -1.0, v);
        sink = sink + v;
      }
      per_call.push_back(ms_since(t0) * 1e6 / static_cast<double>(xs.size()));
    }
    std::printf("   %6d entries: median %.1f ns, min %.1f ns\n", size, percentile(per_call, 0.5), percentile(per_call, 0));
  }
}

void closed_loop(const char* keep) {
  std::printf("\n4. Closed loop on the simulated axis (tests/comp/data/screw_mill: motion controller, task and\n"
              "   interpreter in simulated time, sim_joint and the test lead-screw plant; ISO 230-2 cycle, 13 targets,\n"
              "   5 runs, and periodic runs; fit; table loaded with JOINT_LOAD_COMP; ISO cycle again)\n");
  const std::filesystem::path work =
      keep ? std::filesystem::path(keep) : std::filesystem::temp_directory_path() / ("comp_bench_" + std::to_string(::getpid()));
  const auto t0 = Clock::now();
  cnc::testing::SimMill mill(std::filesystem::path(CNC_SOURCE_DIR) / "tests/comp/data/screw_mill", work, "mill.ini",
                             cnc::testing::register_lead_screw_plant);
  cnc::testing::ClosedLoopOptions o;
  o.cycle.x_min = 5;
  o.cycle.x_max = 295;
  o.cycle.seed = 3;
  o.cycle.lead_mm = 5;
  o.fit.lead_mm = 5;
  const auto r = cnc::testing::run_closed_loop(mill, o);
  if (!r.error.empty()) {
    std::printf("   FAILED: %s\n", r.error.c_str());
    return;
  }
  const auto& a = r.iso_before;
  const auto& b = r.iso_after;
  std::printf("   A: %.3f -> %.3f um (%.1f %% less; goal >= 90 %%)\n", a.A, b.A, (a.A - b.A) / a.A * 100);
  std::printf("   B: %.3f -> %.3f um (goal <= 1 um)\n", a.B, b.B);
  std::printf("   E: %.3f -> %.3f um, R: %.3f -> %.3f um, M: %.3f -> %.3f um\n", a.E, b.E, a.R, b.R, a.M, b.M);
  std::printf("   table %zu entries (within %.3f um of the model), fit %.1f ms, %.0f s simulated in %.1f s\n",
              r.table_entries, r.table_interpolation_um, r.fit_ms, r.simulated_s, ms_since(t0) / 1000);
  std::printf("   report and plot: %s\n", keep ? (work / "report.txt").c_str() : "(pass --keep DIR to keep them)");
  if (!keep) std::filesystem::remove_all(work);
}

#ifdef CNC_HAVE_CIA402
// 5. The same loop on configs/sim: X is a CiA 402 drive behind CANopen, its
// simulator's true table position the interferometer (the test
// CompensationClosedLoop.DISABLED_SimulatedMillOnCia402DrivesXAxis; it needs
// motion to hold its compensation ramp during drive homing, see
// docs/compensation.md, and reports the homing error until then).
void closed_loop_cia402(const char* keep) {
  std::printf("\n5. Closed loop on configs/sim (X: CiA 402 drive simulator with pitch error and backlash behind\n"
              "   CANopen at 1 kHz; screwcomp and complog added; ISO 230-2 cycle, fit, JOINT_LOAD_COMP, cycle again)\n");
  const std::filesystem::path work = keep ? std::filesystem::path(keep) / "cia402"
                                          : std::filesystem::temp_directory_path() /
                                                ("comp_bench_cia402_" + std::to_string(::getpid()));
  const auto t0 = Clock::now();
  const std::string extra_hal =
      "loadrt screwcomp\n"
      "loadrt complog file=measurement-%d.csv axis=X\n"
      "addf complog servo-thread\n"
      "net comp-x-cmd joint.0.pos-cmd => complog.commanded\n"
      "net comp-x-laser cia402-sim.0.node.01.table-position => complog.actual\n"
      "net comp-measuring motion.digital-out-00 => complog.enable\n"
      "net comp-measured motion.digital-out-01 => complog.stop\n";
  cnc::testing::SimMill mill(
      std::filesystem::path(CNC_SOURCE_DIR) / "configs/sim", work, "sim.ini",
      [](hal::ComponentRegistry& r) {
        canopen::register_components(r);
        cia402::register_components(r);
      },
      extra_hal);
  cnc::testing::ClosedLoopOptions o;
  o.cycle.x_min = 5;
  o.cycle.x_max = 295;
  o.cycle.seed = 3;
  o.cycle.lead_mm = 0;
  o.fit.lead_mm = 0;
  const auto r = cnc::testing::run_closed_loop(mill, o);
  if (!r.error.empty()) {
    std::printf("   FAILED: %s\n", r.error.c_str());
    return;
  }
  const auto& a = r.iso_before;
  const auto& b = r.iso_after;
  std::printf("   A: %.3f -> %.3f um (%.1f %% less; goal >= 90 %%)\n", a.A, b.A, (a.A - b.A) / a.A * 100);
  std::printf("   B: %.3f -> %.3f um (goal <= 1 um)\n", a.B, b.B);
  std::printf("   E: %.3f -> %.3f um, R: %.3f -> %.3f um, M: %.3f -> %.3f um\n", a.E, b.E, a.R, b.R, a.M, b.M);
  std::printf("   table %zu entries (within %.3f um of the model), fit %.1f ms, %.0f s simulated in %.1f s\n",
              r.table_entries, r.table_interpolation_um, r.fit_ms, r.simulated_s, ms_since(t0) / 1000);
  if (!keep) std::filesystem::remove_all(work);
}
#endif

}  // namespace

int main(int argc, char** argv) {
  int seeds = 20, repeats = 20;
  bool loop = true, cia402 = false;
  const char* keep = nullptr;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--seeds") && i + 1 < argc) seeds = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--repeats") && i + 1 < argc) repeats = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--no-closed-loop")) loop = false;
    else if (!std::strcmp(argv[i], "--keep") && i + 1 < argc) keep = argv[++i];
    else if (!std::strcmp(argv[i], "--cia402")) cia402 = true;
    else {
      std::fprintf(stderr, "usage: comp_bench [--seeds N] [--repeats N] [--no-closed-loop] [--cia402] [--keep DIR]\n");
      return 2;
    }
  }
  fit_time(std::max(repeats, 1));
  model_error(std::max(seeds, 1));
  lookup_time();
  if (loop) closed_loop(keep);
  if (cia402) {
#ifdef CNC_HAVE_CIA402
    closed_loop_cia402(keep);
#else
    std::printf("\n5. --cia402: not built (cnc_cia402 and cnc_canopen missing)\n");
#endif
  }
  return 0;
}
