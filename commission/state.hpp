// The commissioning state: what each step found or decided, kept in one
// JSON file beside the machine's configuration so that work can be left and
// resumed (a person at the wizard, a script between subcommands). Every
// step reads the state, does its work and saves it again (atomically: a
// crash leaves the old file). Non-realtime.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace cnc::commission {

// One CANopen node as the bus scan found it.
struct ScannedNode {
  int node_id = 0;
  uint32_t device_type = 0;                 // 0x1000
  uint32_t vendor_id = 0, product_code = 0, revision = 0, serial = 0;  // 0x1018
  std::string name;                         // 0x1008 (empty: the node has none)
  std::string firmware;                     // 0x100A
  std::optional<uint32_t> supported_modes;  // 0x6502 (CiA 402 drives)
  std::optional<uint16_t> statusword;       // 0x6041
  std::optional<uint16_t> error_code;       // 0x603F
  std::optional<uint32_t> encoder_increments, encoder_motor_revs;  // 0x608F:1/2
  std::optional<uint32_t> gear_motor_revs, gear_shaft_revs;        // 0x6091:1/2
  std::optional<uint32_t> feed, feed_shaft_revs;                   // 0x6092:1/2
  std::optional<uint16_t> max_torque;       // 0x6072, per thousand of rated torque
  std::string eds;                          // matched description file ("" unknown)
  bool cia402 = false;                      // device profile 402 with CSP among its modes
  bool fault = false;                       // statusword says Fault
  std::vector<std::string> problems;        // what to check, one sentence each
};

// One EtherCAT slave as the segment scan found it (its SII).
struct ScannedSlave {
  unsigned position = 0;                    // 1-based, in the line
  uint32_t vendor_id = 0, product_code = 0, revision = 0, serial = 0;
  std::string name, order;
  bool coe = false, dc = false;
  std::string esi;                          // matched ESI file ("" unknown)
  // Read over CoE where the slave has a mailbox and the objects (as a
  // CANopen node's: ScannedNode).
  std::optional<uint32_t> supported_modes;                          // 0x6502
  std::optional<uint32_t> encoder_increments, encoder_motor_revs;  // 0x608F:1/2
  std::optional<uint32_t> gear_motor_revs, gear_shaft_revs;        // 0x6091:1/2
  std::optional<uint32_t> feed, feed_shaft_revs;                   // 0x6092:1/2
  std::optional<uint16_t> max_torque;                               // 0x6072, per thousand of rated torque
  std::vector<std::string> problems;
};

// Drive scaling of one axis: encoder increments per motor revolution, gear
// (motor revolutions per screw revolution, as GEAR_MOTOR_REVS:GEAR_LOAD_REVS)
// and the screw lead (mm per screw revolution); `correction` multiplies the
// nominal counts per mm after a measured travel (direction test).
struct AxisScaling {
  double encoder_counts = 0;
  double gear_motor_revs = 1, gear_load_revs = 1;
  double screw_lead = 0;
  double correction = 1.0;
  bool reverse = false;
  bool dial_checked = false;  // a direction test's dial reading checked it (reset by a new nominal scaling)
  std::string source;   // "drive 0x608F, entered lead" ...
  double nominal_counts_per_mm() const noexcept;
  double counts_per_mm() const noexcept { return nominal_counts_per_mm() * correction; }
};

// The outcome of one direction and scaling test.
struct DirectionTest {
  double commanded_mm = 0;      // the jog asked for (machine units at the provisional scaling)
  double feedback_mm = 0;       // what the drive's encoder reported (same scaling)
  double dial_mm = 0;           // what the dial indicator showed (entered)
  bool has_dial = false;
  bool reversed = false;        // the test flipped REVERSE
  double correction = 1.0;      // factor applied to counts per mm
  std::string verdict;
};

// --- Step 8, compensation (commission/compensation.hpp) ---
// One measured point of the ISO 230-2 cycle (as comp::MeasurementPoint).
struct CompPoint {
  double target = 0;        // mm, machine coordinates
  int run = 1;              // per target and direction
  int direction = 1;        // +1 approached moving +, -1 moving -
  double deviation_um = 0;  // position reached minus target
};
// The ISO 230-2 figures of one measurement (comp::Iso230Result), um.
struct CompFigures {
  double A = 0, A_up = 0, A_down = 0, E = 0, E_up = 0, E_down = 0, R = 0, B = 0, B_mean = 0, M = 0;
};
struct AxisCompensation {
  // The cycle (comp::CycleOptions): first and last target, targets (0:
  // comp/'s choice), runs each way, overshoot, dwell, feed (mm/min), seed.
  double x_min = 0, x_max = 0;
  int targets = 0, runs = 5;
  double overshoot_mm = 2, dwell_s = 0.8, feed_mm_min = 1000;
  uint64_t seed = 1;
  std::string program;                  // the .ngc written (absolute path)
  std::vector<CompPoint> points;        // the measurement the fit uses
  std::string source;                   // where its readings came from
  double scaling_counts_per_mm = 0;     // the axis's scaling when it was measured
  bool scaling_reverse = false;         //   (a table belongs to that scaling)
  std::optional<CompFigures> measured;  // its figures
  std::vector<CompPoint> check_points;  // a check measurement (comp-run --check), on the compensated machine
  std::optional<CompFigures> checked;
  bool fitted = false;
  CompFigures before, predicted;        // of the fit: measured, and predicted with the table
  std::vector<double> nominal, forward, reverse;  // the table (mm; COMP_FILE_TYPE 1 trims)
  std::string fit_dir;                  // where comp-fit wrote its files
  bool install = false;                 // write puts the table into the configuration
};

// --- Step 9, drive-parameter backup (commission/backup.hpp) ---
struct DriveBackup {
  std::string dir;                      // absolute
  std::string time;                     // UTC, ISO 8601
  std::vector<std::string> files;       // one per drive, names in dir
};
// --- Steps 5 and 6 (helper A): switches and homing. ---
// One switch as the switch search saw it: `seen` it change, at which joint
// position (mm, in the frame the controller had during the search; for
// the home switch the edge on its negative side, `position_high` the one on
// its positive side when both were seen), and its active level (true: the
// input reads 1 when the switch is actuated).
struct SwitchFinding {
  bool seen = false;
  double position = 0;
  double position_high = 0;     // home switch: its positive edge (0: not seen)
  bool has_high = false;
  bool active_high = true;
  std::string pin;              // the HAL pin watched
};
struct AxisSwitches {
  double search_mm = 0, velocity = 0;  // how they were searched
  double start = 0;                    // where the search started (joint mm)
  SwitchFinding neg_limit, pos_limit, home;
  std::vector<std::string> problems;   // switches that never changed, ...
};
// Homing repeatability: `method` "controller" (motion's homing sequence on
// the home switch) or "drive:N" (CiA 402 method N in the drive);
// `references` the reference position of each run (mm, see
// docs/commissioning.md for what is measured), `spread` max - min.
struct AxisHoming {
  std::string method;
  std::vector<double> references;
  double spread = 0;
  double search_velocity = 0, latch_velocity = 0;  // mm/s, signed as written
  double home_offset = 0, home = 0;   // HOME_OFFSET, HOME (joint mm)
  std::string measured;         // what `references` are
};
// --- end of steps 5 and 6 ---
// --- step 7, tuning (helper B) ---
// One move test of the tuning step: back and forth at a commanded
// velocity, acceleration and jerk, recorded per servo cycle (csv).
struct TuningTest {
  std::string series;           // "velocity" or "acceleration": which limit it raises
  double velocity = 0, acceleration = 0, jerk = 0;  // commanded (mm/s, mm/s^2, mm/s^3)
  double reached_velocity = 0, reached_acceleration = 0;  // peak of the command
  double max_ferror = 0;        // peak |following error| (mm)
  double max_torque = 0;        // peak |torque| (% of rated)
  double ferror_per_velocity = 0;  // s: peak |ferror| / |velocity| above a quarter of the peak velocity
  double standstill_ferror = 0; // peak |ferror| below a quarter of the peak velocity (mm)
  int limit_cycles = 0;         // cycles with the drive's internal limit (statusword bit 11)
  bool saturated = false;       // the test found a limit (finding says which)
  bool fault = false;           // the drive faulted or motion stopped during the test
  std::string finding;          // "" clean
  std::string csv;              // the record: time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct
};

// The tuning step's result: the tests and the recommended limits, each
// the highest clean test's value less `margin_pct`; FERROR and MIN_FERROR
// twice the following error the clean tests needed (docs/commissioning.md).
struct AxisTuning {
  std::vector<TuningTest> tests;
  double margin_pct = 20;
  double max_velocity = 0, max_acceleration = 0, max_jerk = 0;  // recommended
  double ferror = 0, min_ferror = 0;                            // recommended
  std::string velocity_limit, acceleration_limit;  // what bounded each: a saturated test, a ceiling, the travel
};
// Step 7's response of the drive's velocity loop (commission/response.hpp):
// the gains read from the drive (raw object values; units in
// docs/commissioning.md), the step's figures and the swept sine's points.
struct LoopGains {
  uint32_t velocity_gain = 0;       // 0x60F9:1
  uint16_t velocity_integral = 0;   // 0x60F9:2
  std::optional<uint32_t> position_gain;  // 0x60FB:1 (when the drive has it)
};
struct StepResponse {
  double amplitude_mm_s = 0;        // the command steps between -amplitude and +amplitude
  int edges = 0;                    // steps analysed
  double rise_time_s = 0;           // 10 % to 90 %, mean over the edges
  double overshoot_pct = 0;         // peak over the step, mean
  double settling_time_s = -1;      // from the edge into +-5 % for good (-1: did not settle)
  std::string csv;                  // the record
};
struct FrequencyPoint {
  double frequency_hz = 0, gain_db = 0, phase_deg = 0;  // velocity feedback over command
};
struct ChirpResponse {
  double amplitude_mm_s = 0;
  std::vector<FrequencyPoint> points;
  double bandwidth_hz = 0;          // -3 dB against the lowest frequency's gain
  bool bandwidth_above = false;     // no point below -3 dB: it lies above bandwidth_hz (the highest tested)
  std::string csv;
};
struct AxisResponse {
  std::string skipped;              // why nothing was measured ("" measured)
  LoopGains gains;
  std::optional<StepResponse> step;   // the velocity loop (amplitudes in mm/s)
  std::optional<ChirpResponse> chirp;
  // The position loop (`response --loop position`): the same figures of
  // the position feedback over the position command, amplitudes in mm.
  std::optional<StepResponse> position_step;
  std::optional<ChirpResponse> position_chirp;
};
// --- end of step 7 ---

// --- Step 9's check (cnc-commission check) ---
// The last run of the check program on the written configuration.
struct CheckRun {
  std::string program;          // absolute path of the program run
  std::string ini;              // the configuration it ran on
  bool passed = false;
  std::string message;          // what was found (passed: the end position)
  double duration_s = 0;        // from starting cncd to its shut-down
  std::string time;             // UTC, ISO 8601, when it ended
};

// The second drive of a gantry pair (two joints, one axis letter): it
// moves the same axis on its own joint, with the axis' scaling, limits,
// tuning, switches' polarity and homing, the pair homed together; `reverse`
// when it turns the other way for the same travel (mounted mirrored).
struct GantryDrive {
  int node = 0;                 // CANopen node-ID (0: an EtherCAT drive)
  int slave = 0;                // EtherCAT position (0: CANopen)
  int joint = 0;
  bool reverse = false;         // REVERSE against the axis' (the first drive's)
  // What steps 4-6 found on this drive's own joint, each side of the pair
  // measured on its own (none: the axis' findings stand for it too).
  double correction = 1.0;      // its counts-per-mm correction (as AxisScaling::correction)
  bool dial_checked = false;
  std::optional<DirectionTest> direction;
  std::optional<AxisSwitches> switches;
  std::optional<AxisHoming> homing;   // its own switch's HOME_OFFSET, plus `squaring`
  double squaring = 0;          // mm added to its HOME_OFFSET so the pair ends square
};

struct Axis {
  char letter = 'X';            // X Y Z A B C U V W
  int joint = 0;
  int node = 0;                 // CANopen node-ID of its drive (0: an EtherCAT drive)
  int slave = 0;                // EtherCAT: the drive's position in the segment (1-based); 0: CANopen
  std::optional<GantryDrive> gantry;  // the second drive of a gantry pair (none: one drive)
  AxisScaling scaling;
  std::optional<DirectionTest> direction;
  double min_limit = -10, max_limit = 10;  // provisional soft limits (mm)
  // Where the soft limits come from: "" the defaults above (the travel is
  // not known: tune and the compensation cycle refuse to move), "entered"
  // (axis L limits), "switches" (axis L soft-limits, step 5).
  std::string limits_source;
  double max_velocity = 10, max_acceleration = 100;  // provisional
  bool enabled = true;          // false: left out of the written configuration
  std::optional<AxisCompensation> compensation;  // step 8
  std::optional<AxisSwitches> switches;  // step 5
  std::optional<AxisHoming> homing;      // step 6
  std::optional<AxisTuning> tuning;  // step 7: the writer uses its recommendations
  std::optional<AxisResponse> response;  // step 7: the velocity loop's step and swept-sine response
};

struct State {
  static constexpr int kVersion = 1;
  std::string machine = "Commissioned machine";
  std::string interface;        // CAN transport of the scan ("socketcan:can0", "virtual:comm")
  uint32_t bitrate = 1'000'000;
  std::string eds_dir;
  std::vector<ScannedNode> nodes;
  std::string ethercat_interface;  // "raw:eth0", "sim:<segment>"
  std::string esi_dir;
  std::vector<ScannedSlave> slaves;
  std::vector<Axis> axes;
  // What the configuration keeps beside the generated part: INI files
  // included at the end (#INCLUDE), and HAL files sourced before the bus
  // masters are loaded and after their functions are added (site I/O, or a
  // simulated machine's drives).
  std::vector<std::string> ini_includes;
  std::vector<std::string> hal_before_bus, hal_after_bus;
  std::vector<std::string> log;  // one line per step done, oldest first
  std::optional<DriveBackup> backup;  // step 9: the last drive-parameter backup
  std::string config_ini;       // step 9: the INI `write --yes` wrote last (absolute; "" none)
  std::optional<CheckRun> check;  // step 9: the last `check` on it

  const ScannedNode* node(int id) const noexcept;
  const ScannedSlave* slave(int position) const noexcept;
  Axis* axis(char letter) noexcept;
  const Axis* axis(char letter) const noexcept;
};

// Reads a state file; a missing file gives a fresh state. Throws
// std::runtime_error naming the file and the key at fault.
State load_state(const std::filesystem::path& file);
// Writes it atomically (a temporary file renamed over the old one).
void save_state(const State& s, const std::filesystem::path& file);
std::string to_json_text(const State& s);
State from_json_text(const std::string& text, const std::string& origin);

}  // namespace cnc::commission
