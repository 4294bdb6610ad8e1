// Step 7 of commissioning, tuning: move tests at rising velocity, then at
// rising acceleration, each a back-and-forth move of one joint in free
// mode inside its provisional soft limits, recorded every servo cycle by
// the controller's HAL scope (command, feedback, following error,
// velocity, torque, the drive's internal-limit bit). Raising stops at the
// first test that shows saturation (torque near the drive's limit, the
// drive reporting a limit, the following error growing out of proportion
// with the velocity, or a fault), and the limits recommended are the
// highest clean test's less a margin (docs/commissioning.md, "7. Tuning").
//
// The analysis (records, saturation, recommendation, CSV) is pure and
// tested on synthetic records; run_tuning() drives the controller
// (Controller: `cnc`, `halcmd scope ...`). Non-realtime.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

// One servo cycle of a test.
struct TuningSample {
  double time_s = 0;
  double command_mm = 0;    // joint.N.motor-pos-cmd
  double feedback_mm = 0;   // joint.N.motor-pos-fb
  double ferror_mm = 0;     // joint.N.f-error (motion's: command - feedback)
  double velocity_mm_s = 0; // the drive's velocity feedback (vel-fb)
  double torque_pct = 0;    // the drive's torque actual, % of rated (0x6077)
  double vel_cmd_mm_s = 0;  // joint.N.vel-cmd (not in the CSV)
  bool limit = false;       // statusword bit 11, internal limit active (not in the CSV)
};

// The CSV header every record has (the wizard plots these columns).
inline constexpr const char* kTuningCsvHeader = "time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct";
std::string tuning_csv(const std::vector<TuningSample>& samples);
// Reads a record written by tuning_csv (the columns by name; vel_cmd is
// derived from the command). Throws std::runtime_error naming `origin`,
// the line and the column.
std::vector<TuningSample> parse_tuning_csv(const std::string& text, const std::string& origin);

// The scope's CSV of one capture (time_s and the pins in the order of
// tuning_scope_pins) as samples.
std::vector<TuningSample> parse_scope_csv(const std::string& text);
// The same for a capture of `sides` joints' pins one after the other (a
// gantry pair: both sides in one capture): the samples of each joint.
std::vector<std::vector<TuningSample>> parse_scope_csv_sides(const std::string& text, int sides);
inline constexpr int kTuningPinsPerJoint = 7;
// The pins a test records for joint `joint` driven by CiA 402 drive
// `drive` of group 0: motor-pos-cmd, motor-pos-fb, f-error, vel-fb,
// torque, vel-cmd, statusword.
std::vector<std::string> tuning_scope_pins(int joint, int drive);

// When a test counts as saturated.
struct SaturationRule {
  double torque_limit_pct = 300;   // the drive's torque limit (0x6072), % of rated
  double torque_share = 0.9;       // saturated at this share of it
  int limit_cycles = 10;           // statusword bit 11 in this many cycles or more (sustained)
  double ferror_growth = 2.0;      // ferror per velocity above this times the first test's
  double ferror_floor_mm = 0.02;   // ... and the peak above this (quantisation of slow tests)
};

// Fills the test's measured figures (peaks, ferror per velocity, limit
// cycles) from its samples, and decides saturation against `rule`;
// `reference_ferror_per_velocity` is the first clean test's (0: none yet).
void analyse_test(TuningTest& t, const std::vector<TuningSample>& samples, const SaturationRule& rule,
                  double reference_ferror_per_velocity);

// A gantry pair's test, both sides recorded at once: the worse of the two
// analyses (peaks and lags the larger, reached velocity and acceleration
// the smaller, saturated when either side is; the finding and the record
// of the side that saturated, the first side's when both or neither did).
TuningTest worse_side(const TuningTest& first, const TuningTest& second);

// The recommendation from the tests (their measured figures): MAX_VELOCITY,
// MAX_ACCELERATION and MAX_JERK = (1 - margin) x the highest clean test's
// reached value; MIN_FERROR = 2 x (the largest standstill following error
// of the clean tests + lag^2 x the joint's MAX_ACCELERATION: the error a
// braking axis carries over the velocity-scaled limit, lag = the largest
// ferror per velocity), FERROR = 2 x the largest ferror per velocity x the
// joint's MAX_VELOCITY (written 5 % above the axis'), neither below 10
// encoder counts (`counts_per_mm`) nor 0.05 mm. Throws
// std::invalid_argument when no test is clean. `velocity_ceiling` and
// `acceleration_ceiling` name what bounded each when no test saturated.
AxisTuning recommend_tuning(const std::vector<TuningTest>& tests, double margin_pct, double counts_per_mm);

struct TuneOptions {
  double max_velocity = 250;         // ceiling of the velocity series (mm/s)
  double max_acceleration = 5000;    // ceiling of the acceleration series (mm/s^2)
  double margin_pct = 20;
  std::filesystem::path record_dir;  // the CSV files
  int steps = 6;                     // tests per series, geometric from ceiling / 8
  SaturationRule rule;
  std::function<void(const std::string&)> progress;  // "I/N text" lines
  std::function<void(const std::string&)> report;    // result lines
};

// The tests on joint `a.joint` (drive index = joint) of the controller:
// switches the machine on, runs the series, switches it off whatever
// happens. A gantry pair (a.gantry) is tuned as one axis: homed first
// (both sides together; step 6 must have run), then jogged by its letter
// in teleop mode with both sides recorded in each test (worse_side); it
// is never moved one side at a time. A fault during a test is reset (machine off and on once) and
// reported; the series stops there. Throws std::runtime_error (machine
// off, nothing recorded in the state) on an abort, a time limit, a joint
// outside its soft limits, a configuration whose joint limits are below
// the ceilings, or no clean test.
AxisTuning run_tuning(const Controller& c, const Axis& a, const TuneOptions& o);

// The configuration for tuning (--bring-up): the state with the axis'
// limits at the ceilings and a following-error limit wide enough for
// them, so that the drive's own limits decide.
State tuning_configuration(const State& s, char letter, const TuneOptions& o);

}  // namespace cnc::commission
