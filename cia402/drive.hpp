// Master-side control of one CiA 402 drive in the servo cycle: runs the
// drive's state machine from the controller's wishes (enable, quick stop,
// fault reset), switches modes only when safe and waits for 0x6061, makes
// the enable bumpless (target := actual before operation enabled), homes
// through the drive (mode HM) for the motion controller's homing hook, arms
// the touch probes (probe input and encoder index), scales counts to machine
// units, and explains faults (0x603F) on the error channel.
//
// read() runs before the motion controller (inputs -> feedback), write()
// after it (commands -> outputs). Both are realtime: no allocation, no
// locks, no exceptions; the only acyclic traffic goes through the link's
// realtime request/poll path. Transport-independent (see link.hpp).
#pragma once

#include <cstdint>
#include <string>

#include "cia402/link.hpp"
#include "cia402/profile.hpp"
#include "cia402/scaling.hpp"
#include "core/util/fixed_string.hpp"

namespace cnc {
class MessageQueue;
}

namespace cnc::cia402 {

struct DriveConfig {
  std::string name;            // "x-axis": for messages
  std::string source;          // "cia402.0.drive.00": message source and HAL prefix
  std::string origin;          // "[CIA402_DRIVE_0]" for configuration errors
  int address = 0;             // node-ID (CANopen), position (EtherCAT)
  int joint = -1;              // motion joint this drive moves (status, HOME_OFFSET), -1 none
  Mode mode = Mode::CyclicSyncPosition;  // operating mode
  Scaling scaling;

  // Drive homing (mode HM); method 0: the drive is not homed by itself.
  int home_method = 0;
  double home_search_vel = 0;  // units/s, 0x6099:1
  double home_latch_vel = 0;   // units/s, 0x6099:2
  double home_accel = 0;       // units/s^2, 0x609A (0: leave the drive's)
  double home_offset = 0;      // units: the drive's position reads this at its reference (0x607C)

  // Written at start-up when set (0: leave the drive's value).
  double ferror_window = 0;        // units, 0x6065
  uint16_t ferror_timeout_ms = 0;  // 0x6066
  double quick_stop_decel = 0;     // units/s^2, 0x6085
  double profile_decel = 0;        // units/s^2, 0x6084
  double max_torque_percent = 0;   // 0x6072
  int16_t quick_stop_option = kQuickStopRamp;     // 0x605A
  int16_t fault_reaction_option = kQuickStopRamp; // 0x605E
  int16_t abort_connection_option = kAbortFault;  // 0x6007

  // Master timing.
  int64_t enable_timeout_ns = 1'000'000'000;      // SOD -> OE with bit 12
  int64_t fault_reset_holdoff_ns = 1'000'000'000; // between two fault resets
  int64_t fault_reset_timeout_ns = 300'000'000;   // the fault must clear within
  int64_t mode_timeout_ns = 500'000'000;          // 0x6061 must confirm within
  int64_t home_timeout_ns = 120'000'000'000;
  // After the drive's homing completed: the return to CSP waits until
  // motion's command is still and within this window of the drive's
  // position (units), for at most this long, then reports a homing error.
  double home_return_window = 0.01;
  int64_t home_return_timeout_ns = 2'000'000'000;
  int64_t quick_stop_timeout_ns = 2'000'000'000;  // QSA -> disable voltage after
  double standstill_velocity = 0.01;  // units/s: below this a mode switch is safe
  bool probe = true;                  // arm touch probe 1 (probe input) when mapped
  // Commissioning (DISABLED = YES): the drive is never configured or enabled;
  // its joint follows its command (pos-fb = pos-cmd) so the rest of the
  // machine runs without it. Said loudly at start-up.
  bool disabled = false;
  int probe_hold_cycles = 2;          // a latch stays visible at least this long
  // Consecutive cycles of stale inputs (the bus's inputs_fresh false) after
  // which the link counts as not ok and the axis stops; 0 = only the bus's
  // own limit (PDO_MISS_LIMIT, MISS_LIMIT). [CIA402]STALE_LIMIT.
  int stale_limit = 3;
};

// What the machine asks of the drive this cycle (HAL pins or a test).
struct DriveCommand {
  bool enable = false;        // motion's amp-enable-out
  bool quick_stop = false;    // an external quick stop (E-stop chain)
  bool fault_reset = false;   // acts on its rising edge
  double pos_cmd = 0;         // CSP: machine units (motor-pos-cmd)
  double vel_cmd = 0;         // CSV: units/s
  double torque_cmd = 0;      // CST: percent of rated torque
  int32_t mode_request = 0;   // 0: the configured mode; else 8 (CSP), 9 (CSV), 10 (CST)
  bool home_start = false;    // motion's drive-home-start
  bool index_enable = false;  // motion's index-enable (I/O)
  bool inhibit = false;       // the group's watchdog or shutdown: no torque
};

// What the drive reports (to HAL pins or a test).
struct DriveFeedback {
  double pos_fb = 0;          // units (motor-pos-fb)
  double vel_fb = 0;          // units/s
  double ferror = 0;          // units: 0x60F4 when mapped, else target - actual
  double torque = 0;          // percent of rated (0x6077)
  State state = State::NotReadyToSwitchOn;
  Mode mode_display = Mode::None;
  uint16_t statusword = 0;
  uint16_t controlword = 0;
  uint16_t error_code = 0;    // 0x603F (or the last EMCY when 0x603F is not mapped)
  uint32_t digital_inputs = 0;
  bool enabled = false;       // operation enabled and following the command
  bool fault = false;         // the drive is in fault (or its fault reaction)
  bool amp_fault = false;     // for motion's amp-fault-in: the drive cannot do what motion wants
  bool warning = false;
  bool link_ok = false;
  bool home_busy = false, home_done = false, home_error = false;
  bool home_sw = false, pos_lim_sw = false, neg_lim_sw = false;
  bool index_found = false;   // this cycle: clear index-enable, index_position is valid
  double index_position = 0;  // units, latched by touch probe 2 (encoder zero pulse)
  bool probe_input = false;   // touch probe 1 latched (and held) or its input active
  double probe_position = 0;  // units, latched by touch probe 1
  uint32_t probe_count = 0;   // latches so far
  bool switching_mode = false;
};

// Where the drive's objects live in the process image (empty = not mapped).
struct DriveSlots {
  Slot controlword, target_position, target_velocity, target_torque, modes, probe_function;
  Slot statusword, position_actual, velocity_actual, torque_actual, ferror_actual, modes_display, error_code,
      digital_inputs, probe_status, probe1_rising, probe2_rising;
  static DriveSlots find(const DriveLink& link, int address) noexcept;
};

class Drive {
 public:
  // `link` and `messages` (may be null) must outlive the drive.
  Drive(DriveConfig config, DriveLink& link, MessageQueue* messages);

  const DriveConfig& config() const noexcept { return config_; }
  const DriveSlots& slots() const noexcept { return slots_; }
  // Throws std::runtime_error naming the drive and what is missing
  // (statusword, controlword, position actual for CSP...).
  void check_mapping() const;
  // Takes the bus cycle again (it is known for sure once the bus's thread
  // is, at start-up): the period velocities are differentiated over.
  void update_period() noexcept;

  // Servo thread.
  void read(int64_t now_ns, const DriveCommand& cmd, DriveFeedback& fb) noexcept;
  void write(int64_t now_ns, const DriveCommand& cmd, DriveFeedback& fb) noexcept;

  // True when the power stage is off or the drive stopped by itself (for
  // shutdown: outputs safe).
  bool is_safe() const noexcept;
  // Text of the last fault explained (for the status block).
  const char* fault_text() const noexcept { return fault_text_.c_str(); }

 private:
  enum class HomePhase : uint8_t { Idle, SwitchToHm, Start, Running, SwitchBack, Done, Error, Aborting };
  struct Probe {
    enum class St : uint8_t { Off, Disarming, Arming, Armed, Latched } st = St::Off;
    uint16_t bits = 0;     // function bits when armed (already shifted)
    int shift = 0;         // 0 probe 1, 8 probe 2
    int held = 0;          // cycles in Latched
    // Latched, but the position slot still holds a value from before the
    // status frame that showed it (another PDO, not yet received): taken
    // once a frame after `status_sequence` brings it.
    bool position_pending = false;
    uint64_t status_sequence = 0;
    // Feed the status; returns true on the latch event.
    bool update(bool want, uint16_t status) noexcept;
    uint16_t function() const noexcept { return (st == St::Arming || st == St::Armed || st == St::Latched) ? bits : 0; }
  };
  enum class Acyclic : uint8_t { None, WriteMode, ReadMode, WriteProbe, ReadError };

  void post(bool error, const char* fmt, ...) noexcept __attribute__((format(printf, 3, 4)));
  Mode wanted_mode(const DriveCommand& cmd) const noexcept;
  bool mode_switch_is_safe(const DriveCommand& cmd) const noexcept;
  double position_units() const noexcept;  // position actual, units
  void run_modes(int64_t now, const DriveCommand& cmd) noexcept;
  void run_homing(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept;
  uint16_t run_state_machine(int64_t now, const DriveCommand& cmd, DriveFeedback& fb) noexcept;
  void write_targets(const DriveCommand& cmd, bool operating) noexcept;
  void run_acyclic(int64_t now) noexcept;
  void explain_fault(uint16_t code, const char* how) noexcept;

  DriveConfig config_;
  DriveLink& link_;
  DriveSlots slots_;
  MessageQueue* messages_;
  double period_s_ = 0.001;

  // inputs
  State state_ = State::NotReadyToSwitchOn;
  State prev_state_ = State::NotReadyToSwitchOn;
  uint16_t statusword_ = 0;
  PositionUnwrap position_;
  int64_t prev_position_ = 0;
  bool have_prev_position_ = false;
  Mode mode_display_ = Mode::None;
  bool mode_display_known_ = false;
  uint16_t error_code_ = 0;
  bool error_code_known_ = false;
  uint16_t probe_status_ = 0;
  // Why the link is not ok: Start until it first came up (no message).
  enum class LinkDown : uint8_t { Start, No, Stale, Lost };
  LinkDown link_down_ = LinkDown::Start;
  double vel_fb_ = 0;
  bool invalid_reported_ = false;
  LinkHealth health_;
  static constexpr int kStaleCountMax = 1'000'000;
  int stale_cycles_ = 0;               // consecutive cycles of stale inputs
  int64_t fresh_lag_ = 0;              // counts: demand minus position at the last fresh sample
  bool have_fresh_lag_ = false;

  // outputs and history
  uint16_t controlword_ = 0;
  int64_t target_ = 0;                 // counts, last written
  int64_t target_history_[2] = {0, 0};  // targets of the last two cycles (ferror without 0x60F4)
  int64_t hold_position_ = 0;
  double prev_pos_cmd_ = 0;
  bool have_prev_cmd_ = false;

  // state machine
  bool prev_enable_ = false, prev_reset_ = false, prev_quick_stop_ = false;
  bool resetting_ = false;
  int reset_phase_ = 0;
  int64_t reset_started_ns_ = 0;
  int64_t last_reset_ns_ = INT64_MIN / 2;
  bool reset_failed_ = false;
  bool enable_failed_ = false;
  int64_t enable_started_ns_ = -1;
  bool reached_oe_ = false;
  bool lost_enable_ = false;
  bool following_ = false;              // OE and statusword bit 12 (cyclic modes)
  int64_t quick_stop_since_ns_ = -1;
  bool fault_explained_ = false;
  bool holdoff_reported_ = false;

  // modes
  Mode mode_cmd_ = Mode::None;          // written to 0x6060
  bool switching_ = false;
  bool mode_failed_ = false;
  int64_t switch_started_ns_ = 0;
  int64_t unsafe_since_ns_ = -1;
  bool unsafe_reported_ = false;

  // homing
  HomePhase home_ = HomePhase::Idle;
  bool prev_home_start_ = false;
  bool home_seen_progress_ = false;
  bool home_seen_other_ = false;
  int64_t home_started_ns_ = 0;

  // touch probes
  Probe probe1_, probe2_;
  bool index_armed_ = false;
  bool probe_latched_ = false;
  double probe_position_ = 0;
  uint32_t probe_count_ = 0;

  // acyclic requests (one at a time)
  Acyclic pending_ = Acyclic::None;
  int handle_ = -1;
  int64_t acyclic_started_ns_ = 0;
  Mode mode_written_ = Mode::None;       // confirmed by the link (0x6060 not mapped)
  bool mode_write_known_ = false;
  uint16_t probe_written_ = 0;
  bool probe_write_known_ = false;
  bool error_read_wanted_ = false;
  int64_t next_mode_read_ns_ = 0;

  FixedString<96> fault_text_;
};

}  // namespace cnc::cia402
