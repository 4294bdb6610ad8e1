// The commissioning wizard's logic without widgets (docs/commissioning.md,
// "The wizard"): the command line of `cnc-commission` each page runs for
// its inputs, the reading of the child's output (`progress: I/N text`
// lines, result lines, error text, exit status) into a result, which of the
// nine steps the state has done, the tune test recordings (CSV), the hold-
// to-run button's protocol and the status strip's text. Every step has one
// implementation, the command-line program's; the Qt pages only collect
// inputs, start the child and show what this code makes of its output.
// Non-realtime; throws std::invalid_argument naming the field at fault.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "commission/state.hpp"
#include "commission/steps.hpp"

namespace cnc::ipc {
struct Status;
}

namespace cnc::commission::wizard {

inline constexpr int kSteps = 9;

// "Bus", "Axes", ... for steps 0..8 (pages 1..9).
const char* step_title(int step) noexcept;

using Argv = std::vector<std::string>;

// Step 8's cycle options (comp-program), 0 for the step's default (min
// and max: both or neither).
struct CompCycle {
  double min = 0, max = 0;
  int targets = 0, runs = 0;
  double dwell_s = 0, feed_mm_min = 0;
};

// Builds the arguments of `cnc-commission` (after the program name) for
// each step; every command line starts with `--state FILE`. Inputs are
// checked here (axis letter, numbers finite and in range, required fields)
// so a page shows a clear message before starting anything.
class CommandBuilder {
 public:
  explicit CommandBuilder(std::filesystem::path state_file) : state_(std::move(state_file)) {}
  const std::filesystem::path& state_file() const noexcept { return state_; }

  // Step 1. CANopen: `scan --interface SPEC [--eds-dir DIR] [--expect L]`;
  // EtherCAT: `scan-ethercat --interface SPEC [--esi-dir DIR]`.
  Argv scan(bool ethercat, const std::string& interface, const std::string& description_dir,
            const std::string& expect = "") const;
  // Step 1, drives without node-ID: `lss --interface SPEC --first ID`.
  Argv lss(const std::string& interface, int first) const;
  // Step 2.
  // A gantry pair: `gantry_node` the second drive (0 none, its joint the
  // next free one), `gantry_reverse` when it turns the other way.
  Argv assign(char letter, int node, int joint, int gantry_node = 0, bool gantry_reverse = false) const;
  // Step 2's identification aid: a tiny, slow, time-limited jog of the
  // axis' drive (a direction test of kIdentifyDistance mm) on the running
  // controller, run on `scratch_state` (a copy of the state the caller
  // makes) so that the jog's result never replaces the axis' real
  // direction test.
  Argv identify(char letter, const std::filesystem::path& scratch_state) const;
  // Step 3. counts <= 0 / gear <= 0: from the drive.
  Argv scaling(char letter, double lead, double counts, double gear_motor, double gear_load) const;
  // Step 4 (hold-to-run) and its dial reading.
  Argv direction_test(char letter, double distance, double velocity, const std::string& bring_up_dir = "") const;
  Argv dial(char letter, double mm) const;
  // Steps 5-8 take `bring_up_dir` as the direction test does: non-empty,
  // the step writes the state's configuration there and runs on a
  // controller of its own (`--bring-up DIR`), shut down afterwards.
  // Step 5.
  Argv limits(char letter, double min, double max, double velocity, double acceleration) const;
  Argv switches(char letter, double search_mm, double velocity, const std::string& bring_up_dir = "") const;
  Argv soft_limits(char letter, double margin_mm) const;
  // Step 6. method: "controller" or "drive:N".
  Argv homing_methods() const;
  Argv homing(char letter, const std::string& method, int repeat, const std::string& bring_up_dir = "") const;
  // Step 7. record_dir: where the test recordings (CSV) go; steps: tests
  // per series (0: the step's default, else 2-20).
  Argv tune(char letter, double max_velocity, double max_acceleration, double margin_pct,
            const std::string& record_dir, int steps = 0, const std::string& bring_up_dir = "") const;
  // Step 7's recommendations accepted: the axis' limits (its soft limits
  // kept) get the recommended MAX_VELOCITY and MAX_ACCELERATION, so the
  // steps after it (the compensation cycle's feed) run at them; `write`
  // takes all of them from the tuning. Throws when the axis has none.
  Argv accept_tuning(const Axis& a) const;
  // Step 7's loop response (step and swept sine of the drive's velocity
  // loop), always on a response configuration of its own in
  // `bring_up_dir`; velocity_gain > 0 is written to 0x60F9:1 first.
  Argv response(char letter, long velocity_gain, const std::string& record_dir, const std::string& bring_up_dir) const;
  // Step 8.
  Argv comp_program(char letter, const std::string& out_ngc, const CompCycle& cycle = {}) const;
  // The cycle run; the readings from a laser's HAL pin (laser_pin, mm) or
  // its CSV file after the run (laser_csv), at most one of them; neither:
  // entered afterwards with comp_measurements.
  Argv comp_run(char letter, const std::string& laser_csv = "", const std::string& laser_pin = "",
                const std::string& bring_up_dir = "") const;
  // The cycle run with a camera reading a glass scale at each stop
  // (`camera`: /dev/videoN, folder:PATH, or exec:COMMAND a capture program;
  // the scale's pitch and the pixel scale, 0: the defaults).
  Argv comp_run_camera(char letter, const std::string& camera, double pitch_mm = 0, double um_per_px = 0,
                       const std::string& bring_up_dir = "") const;
  // values: the deviations entered (um, one per stop of the cycle;
  // separated by commas, blanks or new lines) or csv: a measurement file;
  // one of them.
  Argv comp_measurements(char letter, const std::string& csv, const std::string& values) const;
  Argv comp_fit(char letter, bool install) const;
  // Step 9. yes=false: the difference only.
  Argv write(const std::string& dir, const std::string& name, bool yes) const;
  Argv backup(const std::string& dir) const;
  // Step 9's last part: `check [--program FILE] [--timeout S]` starts cncd
  // on the written configuration and runs the check program (default: the
  // one write put beside the INI). timeout_s 0: the step's default.
  Argv check(const std::string& program = "", double timeout_s = 0) const;
  Argv bring_up(const std::string& dir) const;
  Argv shutdown() const;

 private:
  Argv base() const;
  Argv axis(char letter, const char* step) const;
  std::filesystem::path state_;
};

// The identification jog: 0.5 mm at 1 mm/s.
inline constexpr double kIdentifyDistance = 0.5;
inline constexpr double kIdentifyVelocity = 1.0;

// A number as the command line gets it: the shortest text that reads back
// to the same value ("5", "0.25", "-1e-05").
std::string number_arg(double v);

// One `progress: I/N text` line of a subcommand.
struct Progress {
  int index = 0, count = 0;
  std::string text;
  double fraction() const noexcept { return count > 0 ? static_cast<double>(index) / count : 0.0; }
};
std::optional<Progress> parse_progress(std::string_view line);

// What a run of a subcommand came to.
struct StepResult {
  enum class Outcome {
    Done,      // exit 0
    Problem,   // exit 1: the step found a problem; nothing saved
    Usage,     // exit 2: the command line was refused (e.g. a subcommand this build lacks)
    Aborted,   // stopped by the wizard (hold-to-run released, Stop pressed)
    Crashed,   // killed by a signal the wizard did not send, or failed to start
  };
  Outcome outcome = Outcome::Crashed;
  int exit_code = -1;
  std::vector<std::string> lines;     // the result lines of stdout (progress lines left out)
  std::string error;                  // stderr as it came (trimmed)
  std::optional<Progress> last_progress;
  bool ok() const noexcept { return outcome == Outcome::Done; }
  // One paragraph for the page: "done" or what went wrong with the child's
  // own error text.
  std::string summary() const;
};
const char* to_string(StepResult::Outcome o) noexcept;

// Collects a child's output as it arrives (in any chunks) and gives the
// result when it has ended.
class OutputCollector {
 public:
  // Returns the progress lines completed by this chunk (newest last).
  std::vector<Progress> add_stdout(std::string_view chunk);
  void add_stderr(std::string_view chunk);
  // exited_normally false: killed by a signal (exit_code ignored);
  // abort_requested: the wizard had asked it to stop.
  StepResult finish(bool exited_normally, int exit_code, bool abort_requested);
  const std::optional<Progress>& progress() const noexcept { return progress_; }
  const std::vector<std::string>& lines() const noexcept { return lines_; }

 private:
  void take_line(std::string line);
  std::string out_partial_, err_;
  std::vector<std::string> lines_;
  std::optional<Progress> progress_;
  std::vector<Progress> fresh_;
};

// The hold-to-run protocol: pressing starts the motion's subcommand,
// releasing (or losing the window's focus) asks it to stop with SIGINT;
// a press while a run is still going starts nothing.
class HoldToRun {
 public:
  enum class Action { None, Start, Interrupt };
  Action press() noexcept;
  Action release() noexcept;
  // The child has started / ended.
  void started() noexcept;
  void finished() noexcept;
  bool running() const noexcept { return running_ || starting_; }
  bool interrupt_requested() const noexcept { return interrupted_; }

 private:
  bool starting_ = false, running_ = false, held_ = false, interrupted_ = false;
};

// Which steps the state has done (its results are in the state), from the
// state and the state file's JSON text (for the results of steps 5-8,
// read by key: each enabled axis has "switches", "homing", "tuning",
// "compensation"). Step 9: the log says a configuration was written.
std::array<bool, kSteps> steps_done(const State& s, const std::string& state_json_text);
// The same from the state file (missing: nothing done). Throws
// std::runtime_error naming the file and key at fault.
std::array<bool, kSteps> steps_done(const std::filesystem::path& state_file);

// One test recording of the tuning step: columns time_s, command_mm,
// feedback_mm, ferror_mm, velocity_mm_s, torque_pct (by header name, any
// order; other columns ignored).
struct TuneTrace {
  std::vector<double> time_s, command_mm, feedback_mm, ferror_mm, velocity_mm_s, torque_pct;
  std::size_t size() const noexcept { return time_s.size(); }
};
// Throws std::invalid_argument naming origin:line and the column.
TuneTrace parse_tune_csv(const std::string& text, const std::string& origin);
TuneTrace load_tune_csv(const std::filesystem::path& file);

// The methods `homing-methods` lists: the first word of each line that
// names one ("controller", "drive:N", or a bare drive method number N,
// taken as "drive:N"), with the line as its description.
struct HomingMethod {
  std::string method, description;
};
std::vector<HomingMethod> parse_homing_methods(const std::vector<std::string>& lines);

// The live status strip from the controller's status.
struct StatusStrip {
  std::string estop;                 // "E-stop chain closed", "E-STOP (chain open)", ...
  bool estop_ok = false;
  std::vector<std::string> drives;   // "J0 operation enabled", "J1 fault: ..."
  std::vector<std::string> joints;   // "J0 12.345"
};
StatusStrip status_strip(const ipc::Status& s);

}  // namespace cnc::commission::wizard
