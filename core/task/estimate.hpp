// A program's run time estimated from the trajectory planner, offline: the
// program is read by the interpreter through the task controller's own
// canon (TaskCanon: G20, G5x with the parameter file, G92, XY rotation, tool
// length offsets, feeds and blending tolerances as cncd builds them), and
// its moves run through tp::LookaheadPlanner inline, one servo period at a
// time, with the limits the motion controller would have in force on the
// same INI file. Where cncd's task waits for motion to be at rest (a synch
// point: M6, M66, probes, spindle and override commands, M0/M1) the motion
// stops here too. What it does not count: tool changes, spindle spin-up
// waits, operator pauses, probe contacts (a probe move runs to its end).
// The interpreter runs as for a preview: #<_task> is 0, and M99 at the end
// of the main program ends it after one pass (cncd repeats it).
// Used by bench_tp (bench/tp) and cnc-estimate (docs/tp.md, "Time
// estimate"); the operator screen may call it for "time estimate from the
// planner". Not realtime: allocates, reads files, throws.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/interp/interp.hpp"
#include "core/interp/python_host.hpp"
#include "core/task/task_canon.hpp"
#include "core/tooltable/tool_table.hpp"
#include "core/tp/trajectory_check.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::estimate {

// What an INI file says the planner and the canon work with, each
// parameter read by its owner (motion::load_motion_config,
// task::canon_config, interp::Config::from_ini, io::IoConfig::from_ini).
struct Machine {
  std::filesystem::path ini;
  // As the motion controller sets it: [AXIS_L] limits narrowed by the
  // joints' ([JOINT_n] under trivkins, less COMP_RESERVE where backlash or
  // compensation applies), [TRAJ]MAX_LINEAR_*, LOOKAHEAD_SEGMENTS, the
  // servo period ([EMCMOT]SERVO_PERIOD; cncd takes the HAL thread's).
  tp::PlannerConfig planner;
  task::CanonConfig canon;
  task::MachineView view;  // path limits as motion publishes them (tools: set per run)
  interp::Config interp;
  interp::PythonSettings python;  // [PYTHON]: each run has its own host
  tooltable::ToolTable tools{tooltable::ChangerKind::NonRandom};
  Pose home;  // where "home all" leaves the machine ([JOINT_n]HOME through the kinematics)
  // "trivkins coordinates=XYZ", or why the joint limits were not applied
  // (kinematics other than trivkins couple joints: axis limits only).
  std::string kinematics;
  bool joint_limits_applied = false;
};

// Reads `ini_path`. Throws ConfigError (file, line, key) on a bad value.
Machine load_machine(const std::filesystem::path& ini_path);
// The same from a parsed INI file (bench_tp builds one from its options).
Machine load_machine(const ini::IniFile& ini);

// A program's moves in machine coordinates, in sections: the machine comes
// to rest at the end of each (cncd's synch points).
struct Moves {
  std::vector<tp::Program> sections;
  Pose start;          // where the program starts (machine coordinates)
  Pose end;            // where the last move ends (machine coordinates)
  std::size_t count = 0;  // moves (lines, arcs, dwells, probes)
  std::string error;   // file:line: why the program could not be read (nothing run then)
};

// Reads `program` from `start` (machine coordinates).
Moves read_program(const Machine& machine, const std::filesystem::path& program, const Pose& start);

struct Options {
  std::optional<Pose> start;  // machine coordinates; default: machine.home
  bool measure_cpu = false;   // run_cycle and add_* durations (bench_tp)
  // Moves offered to the planner per servo cycle while it has room (an
  // interpreter that keeps up, as cncd's task cycle does).
  int moves_per_cycle = 64;
  // Tell the planner when no more moves come (tp flush) at each section's
  // end; cncd does not (the planner decides after flush_idle_cycles).
  bool flush_at_end = false;
  // Called after every servo cycle (sections one after the other):
  // bench_tp --profile writes time, speed and program line from it.
  std::function<void(const tp::CycleOutputs&)> after_cycle;
};

struct Result {
  bool completed = false;  // every section ran to rest
  std::string error;       // the program's error, or why a section did not finish
  double time_s = 0;       // motion time: servo periods until each section's rest, summed
  Pose end;                // commanded position at the end (machine coordinates)
  std::size_t moves = 0;
  std::size_t stops = 0;   // sections after the first (synch points)
  // Worst per-axis |v|, |a|, |j| relative to the limits, deviation from the
  // path relative to G64 P, share of time at feed (time-weighted over the
  // sections).
  tp::StreamStats stats;
  // Pieces the servo thread split itself, the hand-over ring being full
  // (tp::RunResult::servo_split; bench_tp's `split` column).
  uint64_t servo_split = 0;
    std::vector<double> cycle_ns, add_ns;  // with measure_cpu
};

Result run(const Machine& machine, const Moves& moves, const Options& options = {});
// read_program from options.start (or machine.home), then run.
Result estimate(const Machine& machine, const std::filesystem::path& program, const Options& options = {});

}  // namespace cnc::estimate
