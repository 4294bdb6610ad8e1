// Step 8 of commissioning, compensation of an axis's positioning error:
// the ISO 230-2 cycle that comp/ generates (comp/cycle.hpp), inside the
// axis's soft limits; the cycle run on the controller with the position
// at each stop read from a laser (a HAL pin that gives the laser's reading,
// in simulation the simulator's true table position), a laser's CSV file
// or entered by hand; the fit, ISO 230-2 figures and compensation table of
// comp/ (comp/fit.hpp, comp/iso230.hpp, comp/tables.hpp); the table and
// the INI keys that load it for the configuration writer. Results live in
// Axis::compensation of the state. Functions check their input and throw
// std::invalid_argument naming the axis (cnc::ConfigError naming file and
// line for files). Non-realtime.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "comp/cycle.hpp"
#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

// The cycle's defaults for an axis: from its soft limits less the overshoot
// and 1 mm, runs 5, dwell 0.8 s, feed half the axis's MAX_VELOCITY (at most
// 3000 mm/min).
AxisCompensation default_compensation(const Axis& a);
// Checks the cycle against the axis: targets and overshoot inside the soft
// limits, at least two runs each way (the ISO evaluation needs two), feed
// within MAX_VELOCITY, dwell at least 0.2 s (the reading settles).
void check_cycle(const Axis& a, const AxisCompensation& c);
comp::CycleOptions cycle_options(const Axis& a, const AxisCompensation& c);

// The stops of the cycle where a reading is taken, in the order the
// program makes them: each run up through the targets (direction +1),
// then down (-1).
struct CycleStop {
  double target = 0;
  int direction = 1;
  int run = 1;
};
std::vector<CycleStop> cycle_stops(const Axis& a, const AxisCompensation& c);
// "stop 3: X 52.100 moving +" lines, for the person entering readings.
std::string describe_stops(char axis, const std::vector<CycleStop>& stops);

// Points from laser readings (mm, the laser's position at each stop, any
// zero): deviations = reading - target, both relative to the first stop
// (as a laser zeroed at the first target). A deviation above 1 mm is
// refused naming the stop (wrong scaling or units, as comp/'s files).
std::vector<CompPoint> points_from_readings(const std::vector<CycleStop>& stops, const std::vector<double>& readings_mm);
// A laser's CSV file: '#' comments, then either one reading (mm) per line,
// or a header naming the columns, `reading_mm` (or `position_mm`) required,
// `target` and `direction` (+/-) optional and checked against the cycle's
// stops. One reading per stop, in the cycle's order. Errors name file and
// line (cnc::ConfigError).
std::vector<double> parse_laser_csv(const std::string& text, const std::string& file_name,
                                    const std::vector<CycleStop>& stops);
std::vector<double> load_laser_csv(const std::filesystem::path& file, const std::vector<CycleStop>& stops);
// Hand-entered deviations (micrometres, position reached minus target), one
// per stop in the cycle's order, separated by commas.
std::vector<CompPoint> points_from_values(const std::vector<CycleStop>& stops, const std::string& values);
// A measurement file of comp/ (docs/compensation.md: target,run,direction,
// deviation_um...), checked by comp::parse_measurement; its targets must
// lie inside the axis's soft limits.
std::vector<CompPoint> points_from_measurement_file(const Axis& a, const std::filesystem::path& file);

// ISO 230-2 figures of points (comp::evaluate_iso230); throws
// std::invalid_argument when a target lacks two runs in each direction.
CompFigures figures_of(const std::vector<CompPoint>& points);
std::string describe(const CompFigures& f);

// Stores a measurement in the axis (the fit's input, or with `check` a
// check of the compensated machine) with its figures.
const CompFigures& set_measurement(State& s, char letter, std::vector<CompPoint> points, const std::string& source,
                                   bool check = false);

// Fits the axis's measurement (comp::fit_error_model; no periodic or
// thermal term: the ISO cycle alone supports neither), makes the table
// (comp::make_comp_table, zero mean correction at the first target) and
// the figures before and predicted after; writes to `out_dir`
// measurement.csv, <axis>.comp (COMP_FILE_TYPE 1) and report.txt.
// `install` marks the table for `write`. Returns the report.
std::string fit_compensation(State& s, char letter, const std::filesystem::path& out_dir, bool install);

// For the configuration writer: the table's file name in the configuration
// folder ("<name>-x.comp"), the [JOINT_n] keys that load it ("" when the
// axis has no installed table), whether any axis has one (the HAL file then
// loads screwcomp), and the table files themselves; these throw
// std::invalid_argument when the axis's scaling changed since the
// measurement (the table belongs to the old one), as comp-fit does.
std::string comp_file_name(const Axis& a, const std::string& name);
std::string comp_ini_keys(const Axis& a, const std::string& name);
bool any_compensation(const State& s);
std::vector<GeneratedFile> compensation_files(const State& s, const std::filesystem::path& dir, const std::string& name);

// The cycle on the running controller: homes the machine when a joint is
// not homed, opens `program` (the cycle of `c`) in auto mode and runs it,
// watching the joint's command (the controller's status) for the stops;
// at each stop, once the command has stood still for 40 % of the dwell,
// reads HAL pin `laser_pin` (a laser's reading, mm; "" none: the stops
// only) until the command moves on, and keeps the mean. Time-limited
// (twice the cycle's time + 60 s); request_abort() aborts the program.
// Whatever happens the machine is switched off at the end. Throws
// std::runtime_error saying why it stopped.
struct CompRunResult {
  std::vector<CycleStop> stops;
  std::vector<double> readings_mm;  // one per stop (laser pin given)
};
using Progress = std::function<void(int done, int total, const std::string& what)>;
CompRunResult run_comp_cycle(const Controller& ctl, const Axis& a, const AxisCompensation& c,
                             const std::filesystem::path& program, const std::string& laser_pin,
                             const Progress& progress = {});
// The same with any source of the readings: `read(target)` gives the
// table's position (mm, any zero) at a stop at `target` (a laser's pin, a
// camera over a glass scale: commission/comp_camera.hpp); empty: the stops
// only. A reading during which the command moved on is dropped. What it
// throws stops the cycle (machine off), its message naming the stop.
// `readings_per_stop` > 0 takes at most that many per stop (a camera: its
// reading averages frames itself, and rendering or reading a frame costs
// the host what the servo thread needs); 0 reads all the time the command
// stands.
using StopReader = std::function<double(double target_mm)>;
CompRunResult run_comp_cycle(const Controller& ctl, const Axis& a, const AxisCompensation& c,
                             const std::filesystem::path& program, const StopReader& read,
                             const Progress& progress = {}, int readings_per_stop = 0);

}  // namespace cnc::commission
