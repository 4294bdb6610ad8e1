// A simulated CiA 402 servo drive, independent of the transport: it adds
// the profile's objects to an object dictionary (CANopen's; CoE serves the
// same dictionary), runs the state machine on the controlword, the modes
// CSP, CSV, CST and HM, the touch probes, software and hardware limits, the
// following-error window and time-out (0x6065/0x6066), quick stop, halt and
// fault reactions (0x605A-0x605E, 0x6007), and a cascaded position /
// velocity loop with feed-forward over the plant (plant.hpp) at a fine
// time step, its gains in the dictionary (0x60F9 velocity and 0x60FB
// position control parameter sets, ServoGains: units), read every step. Faults raise an error code (0x603F) and an emergency through a
// hook. Injected faults: overcurrent, overtemperature, a mechanical jam
// (following error), encoder loss, refused parameter writes.
//
// Time: at each SYNC the outputs received take effect and the plant is run
// to the next SYNC (the sampled inputs of the next SYNC are then those of
// that instant); between SYNCs advance_to() keeps the drive alive when
// SYNCs stop (lost master). No allocation after construction.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "cia402/profile.hpp"
#include "sim/cia402/homing.hpp"
#include "sim/cia402/plant.hpp"
#include "fieldbus/canopen/object_dictionary.hpp"

namespace cnc::cia402::sim {

// The loops' gains, the defaults of the parameter-set objects (written
// by SDO or CoE at run time, they take effect at the next step):
// 0x60F9:1 velocity gain, UNSIGNED32 in 0.1 mN m s/rad (1e-4 N m per rad/s);
// 0x60F9:2 integration time constant, UNSIGNED16 in 0.1 ms (0: none);
// 0x60FB:1 position gain, UNSIGNED32 in 0.01 1/s; 0x60FB:2 and :3
// (integration and differentiation time) read 0: the position loop is P;
// 0x60FB:4 velocity and :5 acceleration (torque) feed-forward, UNSIGNED16
// in per mille.
struct ServoGains {
  double position_gain = 150;         // 1/s
  double velocity_bandwidth_hz = 200; // the velocity loop's P gain = reflected inertia x 2 pi f
  double velocity_gain = 0;           // N m s/rad; overrides the bandwidth when > 0
  double velocity_integral_time = 0.006;  // s; 0: no integral action
  double velocity_ff = 1.0;           // 0..1
  double torque_ff = 1.0;             // 0..1: acceleration x reflected inertia
  double velocity_filter_tau = 2e-4;  // s: low-pass on the encoder-derived velocity
};

struct DriveSimConfig {
  std::string name = "drive";
  PlantConfig plant;
  ServoGains gains;
  double step_s = 20e-6;               // plant and servo-loop step
  int64_t default_period_ns = 1'000'000;  // SYNC period until 0x60C2 or 0x1006 says otherwise
  int64_t init_ns = 20'000'000;         // not ready to switch on after power-on
  int64_t sync_timeout_ns = 200'000'000;  // cyclic modes in OE: SYNCs missing this long = lost connection
  // Object defaults (increments, increments/s, increments/s^2).
  uint32_t max_motor_speed_rpm = 6000; // 0x6080; 0xFFFFFFFF: no limit
  uint32_t ferror_window = 0;          // 0: one motor revolution
  uint16_t ferror_timeout_ms = 10;
  uint32_t quick_stop_decel = 0;       // 0: from the plant's torque limit
  uint32_t profile_decel = 0;
  uint32_t supported_modes = (1u << 5) | (1u << 7) | (1u << 8) | (1u << 9);  // HM, CSP, CSV, CST
  double ambient_c = 35, warning_c = 80, trip_c = 90;  // temperatures
  double thermal_tau_s = 30, thermal_c_per_a2 = 0.15;
  // The motor mounted the other way round (or wired with its phases and
  // encoder swapped): positive increments and torque move the table towards
  // minus. What commissioning's direction test must find (REVERSE). The
  // limit switches are wired by the motor's direction, as a drive expects
  // them: the switch at the table's + end is then the drive's negative
  // limit input (0x60FD bit 0), and the drive's own limit stop and homing
  // guard the right side.
  bool motor_reversed = false;
  // The limit and home switch inputs read inverted in 0x60FD (normally
  // closed switches on inputs set for normally open): what commissioning's
  // switch search must find (the active level). The drive's own limit
  // stop and homing still act on the actuated switch.
  bool switches_active_low = false;
};

class DriveModel {
 public:
  // Adds the profile objects to `od` (which must outlive the model).
  DriveModel(const DriveSimConfig& config, canopen::ObjectDictionary& od);
  DriveModel(const DriveModel&) = delete;
  DriveModel& operator=(const DriveModel&) = delete;

  // An emergency: error code and error register (0x1001 bits); code 0 =
  // error reset. Set by the transport glue (CANopen EMCY, CoE emergency).
  std::function<void(uint16_t code, uint8_t error_register)> on_emcy;

  void power_on(int64_t now_ns) noexcept;
  // SYNC: the outputs received since the last SYNC take effect, the plant
  // runs to the next SYNC.
  void on_sync(int64_t now_ns) noexcept;
  // Between SYNCs: runs the plant up to `now_ns` when SYNCs are late or
  // stopped (fault reactions, coasting, lost connection detection).
  void advance_to(int64_t now_ns) noexcept;
  // The controlword was written acyclically (SDO): act on it now.
  void controlword_written() noexcept;
  // The link to the master broke (heartbeat or RPDO time-out, NMT stop):
  // reaction per 0x6007, fault code `code`.
  void connection_lost(uint16_t code) noexcept;

  // --- fault injection (from the host's thread, between steps) ---
  void inject_overcurrent() noexcept;
  void set_temperature_offset(double kelvin) noexcept { temperature_offset_ = kelvin; }
  void set_jam_force(double newton) noexcept { jam_force_ = newton; }  // a load that does not want to move
  void set_encoder_lost(bool lost) noexcept;
  void set_refuse_writes(bool refuse) noexcept { refuse_writes_ = refuse; }
  void clear_injections() noexcept;

  // --- observation (tests, HAL pins of the simulator) ---
  State state() const noexcept { return state_; }
  uint16_t statusword() const noexcept { return statusword_; }
  Mode mode() const noexcept { return mode_; }
  uint16_t error_code() const noexcept { return error_code_; }
  int64_t position() const noexcept;       // 0x6064, unwrapped
  double demand() const noexcept { return demand_; }
  double following_error() const noexcept { return demand_ - measured_; }
  double temperature() const noexcept { return temperature_ + temperature_offset_; }
  const Plant& plant() const noexcept { return plant_; }
  Plant& plant() noexcept { return plant_; }
  int64_t plant_time_ns() const noexcept { return time_ns_; }
  uint64_t syncs() const noexcept { return syncs_; }
  bool homed() const noexcept { return homed_; }
  const char* homing_error() const noexcept { return homing_.error(); }
  const DriveSimConfig& config() const noexcept { return cfg_; }

 private:
  enum class Stop : uint8_t { None, Ramp, Coast, CurrentLimit };
  struct ProbeState {
    bool enabled = false, latched = false;
    uint16_t function = 0;
  };

  void add_objects();
  uint32_t check_write(const canopen::OdEntry& e, const uint8_t* d, std::size_t n) const noexcept;
  int64_t period_ns() const noexcept;
  void run_until(int64_t t_ns) noexcept;
  void step(double dt) noexcept;
  void process_controlword(uint16_t cw) noexcept;
  void enter(State s) noexcept;
  void begin_stop(int16_t option, State then) noexcept;
  void raise_fault(uint16_t code, uint8_t reg, bool coast) noexcept;
  bool fault_cause_present() const noexcept;
  void apply_mode() noexcept;
  void start_segment() noexcept;
  double max_velocity() const noexcept;  // counts/s: 0x607F and 0x6080
  void update_probes(const StepEvents& ev) noexcept;
  void update_statusword() noexcept;
  double encoder_counts() const noexcept;
  double motor_sign() const noexcept { return cfg_.motor_reversed ? -1.0 : 1.0; }
  // The limit switches in the motor's direction (see motor_reversed).
  bool drive_neg_limit() const noexcept { return cfg_.motor_reversed ? plant_.pos_limit() : plant_.neg_limit(); }
  bool drive_pos_limit() const noexcept { return cfg_.motor_reversed ? plant_.neg_limit() : plant_.pos_limit(); }  // exact counts the drive sees (frozen on encoder loss)

  DriveSimConfig cfg_;
  canopen::ObjectDictionary& od_;
  Plant plant_;
  HomingEngine homing_;

  // objects
  canopen::ObjectDictionary::Var<uint16_t> controlword_, statusword_obj_, error_code_obj_;
  canopen::ObjectDictionary::Var<int8_t> modes_, modes_display_;
  canopen::ObjectDictionary::Var<int32_t> target_position_, position_actual_, position_demand_, velocity_actual_,
      target_velocity_, ferror_actual_, home_offset_, probe1_rise_, probe1_fall_, probe2_rise_, probe2_fall_,
      sw_limit_min_, sw_limit_max_, velocity_offset_;
  canopen::ObjectDictionary::Var<int16_t> target_torque_, torque_actual_, torque_offset_, quick_stop_option_,
      shutdown_option_, disable_option_, halt_option_, fault_reaction_option_, abort_option_;
  canopen::ObjectDictionary::Var<uint32_t> max_profile_velocity_, max_motor_speed_;
  canopen::ObjectDictionary::Var<uint32_t> ferror_window_, quick_stop_decel_, profile_decel_, homing_speed_switch_,
      homing_speed_zero_, homing_accel_, digital_inputs_, supported_modes_, position_window_;
  canopen::ObjectDictionary::Var<uint16_t> ferror_timeout_, probe_function_, probe_status_, max_torque_;
  canopen::ObjectDictionary::Var<int8_t> homing_method_, ip_index_;
  canopen::ObjectDictionary::Var<uint8_t> ip_value_, error_register_;
  canopen::ObjectDictionary::Var<uint32_t> comm_cycle_us_;  // 0x1006 when present
  canopen::ObjectDictionary::Var<int16_t> temperature_obj_;
  canopen::ObjectDictionary::Var<double> table_position_obj_;
  canopen::ObjectDictionary::Var<uint32_t> velocity_gain_obj_, position_gain_obj_;
  canopen::ObjectDictionary::Var<uint16_t> velocity_ti_obj_, velocity_ff_obj_, torque_ff_obj_;

  // state machine
  State state_ = State::NotReadyToSwitchOn;
  uint16_t statusword_ = 0;
  uint16_t last_cw_ = 0;
  uint16_t error_code_ = 0;
  uint8_t error_register_bits_ = 0;
  Mode mode_ = Mode::None;
  Stop stop_ = Stop::None;
  State after_stop_ = State::SwitchOnDisabled;
  double stop_decel_ = 0;
  double ramp_velocity_ = 0;
  bool halted_ = false;
  bool warning_ = false;
  int64_t fault_at_ns_ = -1;        // lost connection: the fault reaction starts then
  uint16_t pending_fault_ = 0;

  // time
  int64_t time_ns_ = 0;
  int64_t power_on_ns_ = -1;
  int64_t last_sync_ns_ = -1;
  int64_t sync_phase_ns_ = 0;    // the drive's own cycle, locked to SYNC
  uint64_t syncs_ = 0;
  double step_carry_ = 0;

  // servo
  double demand_ = 0;               // position demand, counts
  double measured_ = 0;             // encoder counts (quantised) + offset
  double velocity_est_ = 0;         // counts/s, for the velocity loop
  double velocity_report_ = 0;      // counts/s, 0x606C
  double settle_s_ = 0;
  double last_counts_ = 0;
  double integral_ = 0;             // N m
  double vff_ = 0, aff_ = 0;        // feed-forward, counts/s and counts/s^2
  double seg_start_ = 0, seg_end_ = 0, seg_elapsed_ = 0, seg_length_ = 0.001, seg_velocity_ = 0;
  int64_t offset_ = 0;              // position actual = encoder + offset
  int64_t target_unwrapped_ = 0;
  int32_t target_raw_ = 0;
  bool target_valid_ = false;
  double ferror_time_ = 0;
  bool ferror_exceeded_ = false;
  bool internal_limit_ = false;
  bool velocity_limited_ = false;   // the CSP segment was cut to the velocity limit
  bool torque_limited_ = false;     // the loop asks for more than 0x6072 / the current limit
  bool homed_ = false;
  bool homing_started_ = false;
  double frozen_counts_ = 0;

  // probes
  ProbeState probe_[2];
  StepEvents last_events_;

  // injection
  bool encoder_lost_ = false, overcurrent_ = false, refuse_writes_ = false;
  double temperature_offset_ = 0, temperature_ = 35, jam_force_ = 0;
};

}  // namespace cnc::cia402::sim
