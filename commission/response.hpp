// Step 7's loop response: a step and a swept sine (a stepped chirp) of the
// drive's velocity loop, on drives that expose its gains (CiA 402 0x60F9,
// read by SDO on CANopen, CoE SDO on EtherCAT; a drive without it is
// skipped and the result says so). The
// drive is switched to CSV for each test (the drive layer's mode-request)
// and its velocity command comes from a signal generator in the servo
// thread (siggen), small in amplitude, time-limited, inside the known
// travel, with the E-stop chain live; whatever happens the machine ends off
// and the drive disabled. The analysis (step figures, gain and phase, the
// -3 dB bandwidth) is pure and tested on synthetic records; the tests run
// on a controller this step brings up itself on the response configuration.
// Non-realtime.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "commission/config_writer.hpp"
#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

class DriveChannel;  // commission/restore.hpp: one drive by SDO or CoE SDO

// The loop a response test excites: the velocity loop (the drive in CSV,
// the generator's output its velocity command) or the position loop (the
// drive stays in CSP, the generator's output added to its position
// command).
enum class Loop { Velocity, Position };
const char* loop_name(Loop l) noexcept;  // "velocity", "position"

// One servo cycle of a response test. On the position loop the command and
// feedback are positions (mm): pos-cmd and pos-fb.
struct ResponseSample {
  double time_s = 0;
  double vel_cmd_mm_s = 0;    // the drive's velocity command (cia402...vel-cmd)
  double velocity_mm_s = 0;   // its velocity feedback (vel-fb, 0x606C)
  double torque_pct = 0;      // torque actual (0x6077), % of rated
};

inline constexpr const char* kResponseCsvHeader = "frequency_hz,time_s,vel_cmd_mm_s,velocity_mm_s,torque_pct";
inline constexpr const char* kPositionResponseCsvHeader = "frequency_hz,time_s,pos_cmd_mm,position_mm,torque_pct";
// `frequency_hz` 0 for the step's rows.
std::string response_csv(const std::vector<ResponseSample>& samples, double frequency_hz);
// A record written as kResponseCsvHeader (or kPositionResponseCsvHeader)
// + response_csv rows: the samples and each one's frequency; `loop` says
// which header it had. Throws std::runtime_error naming the file, line and
// column.
std::vector<ResponseSample> load_response_csv(const std::filesystem::path& file, std::vector<double>* frequency_hz = nullptr,
                                              Loop* loop = nullptr);
// The scope's CSV of response_scope_pins as samples.
std::vector<ResponseSample> parse_response_scope_csv(const std::string& text);
// Of CiA 402 drive `drive` of group 0: vel-cmd, vel-fb, torque (velocity
// loop) or pos-cmd, pos-fb, torque (position loop).
std::vector<std::string> response_scope_pins(int drive, Loop loop = Loop::Velocity);

// The step figures of a record whose command is a square wave: every edge
// (a change of more than 3/4 of the command's span between two samples)
// followed by at least `min_hold_s` of command is analysed against the
// command's levels before and after it (10-90 % rise time, overshoot, and
// the time from the edge until the response stays within `band` of the
// step for good), and the figures are the edges' means. Throws
// std::invalid_argument when no edge is found.
StepResponse analyse_step(const std::vector<ResponseSample>& samples, double band = 0.05, double min_hold_s = 0.02);

// Gain and phase of the feedback over the command at `frequency_hz`, from
// the whole cycles at the end of `samples` (a single-bin Fourier transform
// of each). Throws std::invalid_argument without a whole cycle.
FrequencyPoint analyse_sine(const std::vector<ResponseSample>& samples, double frequency_hz);

// The -3 dB bandwidth of `points` (ascending frequencies; phases are
// unwrapped in place): the first crossing below the lowest frequency's
// gain less 3 dB, interpolated on a logarithmic frequency axis; without one
// the highest frequency with `above` set.
double bandwidth_hz(std::vector<FrequencyPoint>& points, bool& above);

// --- the drive's gains, by SDO (CANopen) or CoE SDO (EtherCAT) ---

// 0x60F9:1/2 and 0x60FB:1 of the drive behind `drive`, called `who` in
// messages ("node 3", "EtherCAT slave 1"). nullopt with `why` (the object,
// the abort) when the drive has no 0x60F9 or does not answer.
std::optional<LoopGains> read_loop_gains(DriveChannel& drive, const std::string& who, std::string& why);
// Writes 0x60F9:1 (the velocity loop's gain); throws std::runtime_error
// naming the drive, the object and the abort.
void write_velocity_gain(DriveChannel& drive, const std::string& who, uint32_t gain);
// What the response found in the axis' drive before it changed anything,
// to be put back afterwards (restore_drive): the velocity gain before
// --velocity-gain was written, and on EtherCAT the mode of operation 0x6060
// that the response controller's drive layer overwrites (on CANopen that
// controller puts its own mode back before it stops: run_response).
struct DriveFound {
  std::optional<uint32_t> velocity_gain;  // 0x60F9:1
  std::optional<int8_t> mode;             // 0x6060
  bool changed() const noexcept { return velocity_gain || mode; }
};

// The gains of axis `a`'s drive for the response step: `velocity_gain`
// written first when given, then read (back); what the write and the
// response controller change is noted in `found`. nullopt with `why`: the
// drive is skipped. Each bus has its moment: an EtherCAT axis before the
// response controller starts (this program's own master takes the segment
// in PREOP, as the backup does; the controller's master owns it once it
// runs), a CANopen axis while it runs (over response_sdo_interface: a
// virtual bus exists only then). Throws std::runtime_error when the bus
// cannot be opened or the write is refused (`found` then says what to put
// back).
std::optional<LoopGains> response_gains(const State& s, const Axis& a, std::optional<uint32_t> velocity_gain,
                                        std::string& why, DriveFound& found);
// Puts back what `found` holds, each value read back: on EtherCAT after the
// response controller stopped (this program's master in PREOP), on CANopen
// while it runs (by SDO). Throws std::runtime_error naming the drive, the
// object and the value that could not be put back.
void restore_drive(const State& s, const Axis& a, const DriveFound& found);
// The same over one drive's channel (`who` in messages).
void restore_drive(DriveChannel& drive, const std::string& who, const DriveFound& found);
// A CANopen axis: waits until the response controller's master has booted
// the axis' node (canopen.0.node.NN.operational), so that the step's SDO
// transfers do not meet the master's own configuration of the node on the
// bus. Throws std::runtime_error naming the node after `timeout_s`.
void wait_node_operational(const Controller& c, const Axis& a, double timeout_s = 20);
// Whether response_gains is called before the response controller starts.
inline bool response_gains_before_controller(const Axis& a) { return a.slave != 0; }

// --- on a controller ---

struct ResponseOptions {
  Loop loop = Loop::Velocity;
  bool step = true, chirp = true;
  double amplitude_mm_s = 2;        // the velocity loop's, at most kMaxResponseAmplitude
  double amplitude_mm = 0.02;       // the position loop's, at most kMaxPositionResponseAmplitude
  double step_period_s = 0.2;       // the square wave's period: each step holds half of it
  int step_edges = 6;
  double min_frequency_hz = 2;
  double max_frequency_hz = 0;      // 0: a fifth of the servo rate
  int frequencies = 10;             // logarithmically spaced
  double max_excursion_mm = 1.0;    // the axis may wander this far from where it started
  std::filesystem::path record_dir;
  std::function<void(const std::string&)> progress;
  std::function<void(const std::string&)> report;
};
inline constexpr double kMaxResponseAmplitude = 20;           // mm/s
inline constexpr double kMaxPositionResponseAmplitude = 0.2;   // mm

// Runs the tests on joint `a.joint` (drive index = joint) of the
// controller (the response configuration: siggen "response" wired to the
// drive's vel-cmd, siggen "response-pos" added to its pos-cmd). Switches
// the machine on for each test (the velocity loop: the drive to CSV), off
// (and back to CSP) after it. The figures go to `step`/`chirp` (velocity)
// or `position_step`/`position_chirp`. Throws std::runtime_error (machine
// off) on an abort, a time limit, an open E-stop chain, a joint outside its
// travel or wandering beyond max_excursion_mm.
AxisResponse run_response(const Controller& c, const Axis& a, const ResponseOptions& o);

// The response configuration for axis `letter`: tuning_configuration's
// state (its following-error limits wide enough for the excursion) written
// with the writer's response option (WriterOptions::response_axis: 0x60FF
// mapped on the axis' drive, the signal generator on its vel-cmd, a
// virtual CAN bus shared).
std::vector<GeneratedFile> response_configuration(const State& s, char letter, const std::filesystem::path& dir,
                                                  const std::string& name);
// The CAN interface this program opens to reach the drives of the response
// configuration by SDO: the shared socket of a virtual bus, else the
// state's interface itself.
std::string response_sdo_interface(const State& s);

}  // namespace cnc::commission
