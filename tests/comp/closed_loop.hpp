// The compensation closed loop on a simulated machine, run by the
// controller as on a real one: the ISO 230-2 standard test cycle and the
// dense periodic runs as G-code programs, the interferometer's readings
// logged by complog, the error model fitted, the compensation table loaded
// into the running controller (JOINT_LOAD_COMP), the ISO cycle run again.
// Shared by the closed-loop test and the benchmark.
#pragma once

#include <chrono>
#include <string>

#include "comp/comp_table.hpp"
#include "comp/cycle.hpp"
#include "comp/fit.hpp"
#include "comp/iso230.hpp"
#include "comp/plot.hpp"
#include "comp/report.hpp"
#include "comp/tables.hpp"
#include "tests/comp/sim_mill.hpp"

namespace cnc::testing {

struct ClosedLoopOptions {
  int joint = 0;
  comp::CycleOptions cycle;     // targets, runs, feed, dwell, lead
  comp::FitOptions fit;
  comp::TableOptions table;
  double program_timeout_s = 3000;
};

struct ClosedLoopResult {
  std::string error;            // empty: every step worked
  comp::Measurement before, periodic, after;
  comp::Iso230Result iso_before, iso_after;
  comp::FitResult fit;
  std::size_t table_entries = 0;
  double table_interpolation_um = 0;
  double fit_ms = 0;
  double simulated_s = 0;
  std::string report;           // before/after comparison, both ISO reports, the fit
};

inline ClosedLoopResult run_closed_loop(SimMill& mill, const ClosedLoopOptions& o) {
  ClosedLoopResult r;
  const auto fail = [&](const std::string& e) {
    r.error = e;
    return r;
  };
  if (std::string e = mill.power_up(); !e.empty()) return fail("power up: " + e);
  const std::string iso_program = comp::iso_cycle_gcode(o.cycle);
  // 1. Measure: the ISO cycle and the periodic runs.
  if (std::string e = mill.run_program("iso230.ngc", iso_program, o.program_timeout_s); !e.empty()) {
    return fail("ISO cycle: " + e);
  }
  if (mill.logger().finished().size() != 1) return fail("complog did not finish the first measurement");
  r.before = comp::load_measurement(mill.logger().finished().back());
  const bool periodic = o.cycle.lead_mm > 0 && o.fit.lead_mm > 0;
  if (periodic) {
    if (std::string e = mill.run_program("periodic.ngc", comp::periodic_cycle_gcode(o.cycle), o.program_timeout_s);
        !e.empty()) {
      return fail("periodic runs: " + e);
    }
    r.periodic = comp::load_measurement(mill.logger().finished().back());
  }
  // 2. Fit and make the table.
  std::vector<comp::Measurement> data{r.before};
  if (periodic) data.push_back(r.periodic);
  const auto t0 = std::chrono::steady_clock::now();
  r.fit = comp::fit_error_model(data, o.fit);
  r.fit_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  comp::TableOptions to = o.table;
  to.reference_mm = r.before.points.front().target;
  const comp::CompTable table = comp::make_comp_table(r.fit.model, to);
  r.table_entries = table.size();
  r.table_interpolation_um = comp::interpolation_error_um(table, r.fit.model, comp::reference_offset_um(r.fit.model, to));
  const auto file = mill.dir() / "fitted.comp";
  write_file_atomically(file, comp::format_comp_table(table, comp::CompFileType::Trims, {"fitted by the closed loop"}));
  // 3. Load it into the running controller.
  const SimMill::Reply load = mill.load_comp(o.joint, file, 1);
  if (load.first != ipc::CommandState::Done) return fail("JOINT_LOAD_COMP: " + load.second);
  // 4. Measure again.
  if (std::string e = mill.run_program("iso230-after.ngc", iso_program, o.program_timeout_s); !e.empty()) {
    return fail("ISO cycle after: " + e);
  }
  r.after = comp::load_measurement(mill.logger().finished().back());
  r.iso_before = comp::evaluate_iso230(r.before);
  r.iso_after = comp::evaluate_iso230(r.after);
  r.simulated_s = mill.seconds();
  r.report = comp::iso230_comparison(r.iso_before, r.iso_after, "before", "after") + "\n" +
             comp::iso230_report(r.iso_before, "Before compensation") + "\n" +
             comp::iso230_report(r.iso_after, "After compensation") + "\n" + comp::fit_report(r.fit);
  write_file_atomically(mill.dir() / "report.txt", r.report);
  comp::write_plot(mill.dir() / "iso230.png",
                   {comp::PlotPanel{"Before compensation", &r.before, &r.iso_before, &r.fit.model},
                    comp::PlotPanel{"After compensation (table loaded while running)", &r.after, &r.iso_after}});
  return r;
}

}  // namespace cnc::testing
