#include "sim/cia402/drive_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cnc::cia402::sim {
namespace {

using canopen::Access;
using canopen::DataType;
using canopen::ObjectAddress;

constexpr uint32_t kAbortValueRange = 0x06090030;
constexpr uint32_t kAbortDeviceState = 0x08000022;

ObjectAddress at(Object o) { return ObjectAddress{o.index, o.sub}; }
uint64_t bits_of(int64_t v) { return static_cast<uint64_t>(v); }
int32_t wrap32(int64_t v) { return static_cast<int32_t>(static_cast<uint32_t>(static_cast<uint64_t>(v))); }

}  // namespace

DriveModel::DriveModel(const DriveSimConfig& config, canopen::ObjectDictionary& od)
    : cfg_(config), od_(od), plant_(config.plant) {
  add_objects();
  temperature_ = cfg_.ambient_c;
}

void DriveModel::add_objects() {
  const double j = plant_.reflected_inertia();
  const double torque_limit = cfg_.plant.torque_constant * cfg_.plant.max_current;
  const double cpr = plant_.counts_per_rad();
  const uint32_t a_max = static_cast<uint32_t>(std::min(4e9, 0.5 * torque_limit / j * cpr));
  const uint32_t qs_decel = cfg_.quick_stop_decel ? cfg_.quick_stop_decel : a_max;
  const uint32_t pf_decel = cfg_.profile_decel ? cfg_.profile_decel : a_max / 3;
  const uint32_t window = cfg_.ferror_window ? cfg_.ferror_window
                                             : static_cast<uint32_t>(std::min(4e9, cfg_.plant.encoder_counts));
  auto& od = od_;
  using D = DataType;
  using A = Access;
  auto add = [&](Object o, D t, A a, uint64_t def, bool pdo, const char* name) { od.add(at(o), t, a, def, pdo, name); };
  auto count = [&](uint16_t index, uint8_t n, const char* name) {
    od.add({index, 0}, D::Unsigned8, A::Const, n, false, name);
  };
  add(obj::kAbortConnection, D::Integer16, A::ReadWrite, kAbortFault, false, "Abort connection option code");
  add(obj::kErrorCode, D::Unsigned16, A::ReadOnly, 0, true, "Error code");
  add(obj::kControlword, D::Unsigned16, A::ReadWrite, 0, true, "Controlword");
  add(obj::kStatusword, D::Unsigned16, A::ReadOnly, 0, true, "Statusword");
  add(obj::kQuickStopOption, D::Integer16, A::ReadWrite, kQuickStopRamp, false, "Quick stop option code");
  add(obj::kShutdownOption, D::Integer16, A::ReadWrite, 0, false, "Shutdown option code");
  add(obj::kDisableOperationOption, D::Integer16, A::ReadWrite, 1, false, "Disable operation option code");
  add(obj::kHaltOption, D::Integer16, A::ReadWrite, 1, false, "Halt option code");
  add(obj::kFaultReactionOption, D::Integer16, A::ReadWrite, kQuickStopRamp, false, "Fault reaction option code");
  add(obj::kModes, D::Integer8, A::ReadWrite, 0, true, "Modes of operation");
  add(obj::kModesDisplay, D::Integer8, A::ReadOnly, 0, true, "Modes of operation display");
  add(obj::kPositionDemand, D::Integer32, A::ReadOnly, 0, true, "Position demand value");
  add(obj::kPositionActual, D::Integer32, A::ReadOnly, 0, true, "Position actual value");
  add(obj::kFollowingErrorWindow, D::Unsigned32, A::ReadWrite, window, false, "Following error window");
  add(obj::kFollowingErrorTimeout, D::Unsigned16, A::ReadWrite, cfg_.ferror_timeout_ms, false, "Following error time out");
  add(obj::kPositionWindow, D::Unsigned32, A::ReadWrite, 10, false, "Position window");
  add(obj::kPositionWindowTime, D::Unsigned16, A::ReadWrite, 1, false, "Position window time");
  add(obj::kVelocityActual, D::Integer32, A::ReadOnly, 0, true, "Velocity actual value");
  add(obj::kTargetTorque, D::Integer16, A::ReadWrite, 0, true, "Target torque");
  add(obj::kMaxTorque, D::Unsigned16, A::ReadWrite, 3000, false, "Max torque");
  add(obj::kRatedTorque, D::Unsigned32, A::ReadOnly, static_cast<uint64_t>(cfg_.plant.rated_torque * 1000), false,
      "Motor rated torque (mN m)");
  add(obj::kTorqueActual, D::Integer16, A::ReadOnly, 0, true, "Torque actual value");
  add(obj::kTargetPosition, D::Integer32, A::ReadWrite, 0, true, "Target position");
  add(obj::kHomeOffset, D::Integer32, A::ReadWrite, 0, false, "Home offset");
  count(0x607D, 2, "Software position limit");
  add(obj::kSwLimitMin, D::Integer32, A::ReadWrite, 0, false, "Min position limit");
  add(obj::kSwLimitMax, D::Integer32, A::ReadWrite, 0, false, "Max position limit");
  add(obj::kPolarity, D::Unsigned8, A::ReadOnly, 0, false, "Polarity");
  add(obj::kMaxProfileVelocity, D::Unsigned32, A::ReadWrite, 0xFFFFFFFF, false, "Max profile velocity");
  add(obj::kMaxMotorSpeed, D::Unsigned32, A::ReadWrite, cfg_.max_motor_speed_rpm, false, "Max motor speed (rpm)");
  add(obj::kProfileAcceleration, D::Unsigned32, A::ReadWrite, pf_decel, false, "Profile acceleration");
  add(obj::kProfileDeceleration, D::Unsigned32, A::ReadWrite, pf_decel, false, "Profile deceleration");
  add(obj::kQuickStopDeceleration, D::Unsigned32, A::ReadWrite, qs_decel, false, "Quick stop deceleration");
  // Factor group 1:1: positions in encoder increments (the master scales).
  const auto counts = static_cast<uint64_t>(cfg_.plant.encoder_counts);
  count(0x608F, 2, "Position encoder resolution");
  add(obj::kEncoderIncrements, D::Unsigned32, A::ReadOnly, counts, false, "Encoder increments");
  add(obj::kEncoderMotorRevs, D::Unsigned32, A::ReadOnly, 1, false, "Motor revolutions");
  count(0x6091, 2, "Gear ratio");
  add(obj::kGearMotorRevs, D::Unsigned32, A::ReadOnly, 1, false, "Motor shaft revolutions");
  add(obj::kGearShaftRevs, D::Unsigned32, A::ReadOnly, 1, false, "Driving shaft revolutions");
  count(0x6092, 2, "Feed constant");
  add(obj::kFeed, D::Unsigned32, A::ReadOnly, counts, false, "Feed");
  add(obj::kFeedShaftRevs, D::Unsigned32, A::ReadOnly, 1, false, "Shaft revolutions");
  add(obj::kHomingMethod, D::Integer8, A::ReadWrite, 0, false, "Homing method");
  count(0x6099, 2, "Homing speeds");
  add(obj::kHomingSpeedSwitch, D::Unsigned32, A::ReadWrite, counts, false, "Speed during search for switch");
  add(obj::kHomingSpeedZero, D::Unsigned32, A::ReadWrite, counts / 10, false, "Speed during search for zero");
  add(obj::kHomingAcceleration, D::Unsigned32, A::ReadWrite, pf_decel, false, "Homing acceleration");
  add(obj::kVelocityOffset, D::Integer32, A::ReadWrite, 0, true, "Velocity offset");
  add(obj::kTorqueOffset, D::Integer16, A::ReadWrite, 0, true, "Torque offset");
  add(obj::kTouchProbeFunction, D::Unsigned16, A::ReadWrite, 0, true, "Touch probe function");
  add(obj::kTouchProbeStatus, D::Unsigned16, A::ReadOnly, 0, true, "Touch probe status");
  add(obj::kTouchProbe1Rising, D::Integer32, A::ReadOnly, 0, true, "Touch probe 1 positive edge");
  add(obj::kTouchProbe1Falling, D::Integer32, A::ReadOnly, 0, true, "Touch probe 1 negative edge");
  add(obj::kTouchProbe2Rising, D::Integer32, A::ReadOnly, 0, true, "Touch probe 2 positive edge");
  add(obj::kTouchProbe2Falling, D::Integer32, A::ReadOnly, 0, true, "Touch probe 2 negative edge");
  count(0x60C2, 2, "Interpolation time period");
  add(obj::kInterpolationPeriodValue, D::Unsigned8, A::ReadWrite, 1, false, "Interpolation time period value");
  add(obj::kInterpolationPeriodIndex, D::Integer8, A::ReadWrite, bits_of(-3) & 0xFF, false,
      "Interpolation time index");
  add(obj::kFollowingErrorActual, D::Integer32, A::ReadOnly, 0, true, "Following error actual value");
  add(obj::kDigitalInputs, D::Unsigned32, A::ReadOnly, 0, true, "Digital inputs");
  count(0x60FE, 2, "Digital outputs");
  add(obj::kDigitalOutputs, D::Unsigned32, A::ReadWrite, 0, true, "Physical outputs");
  od.add({0x60FE, 2}, D::Unsigned32, A::ReadWrite, 0, false, "Bit mask");
  add(obj::kTargetVelocity, D::Integer32, A::ReadWrite, 0, true, "Target velocity");
  add(obj::kSupportedModes, D::Unsigned32, A::ReadOnly, cfg_.supported_modes, false, "Supported drive modes");
  // The loops' parameter sets (ServoGains: units).
  const double kv_default = cfg_.gains.velocity_gain > 0 ? cfg_.gains.velocity_gain
                                                         : j * 6.283185307179586 * cfg_.gains.velocity_bandwidth_hz;
  auto scaled = [](double v, double unit, double max) {
    return static_cast<uint64_t>(std::llround(std::clamp(v / unit, 0.0, max)));
  };
  count(0x60F9, 2, "Velocity control parameter set");
  od.add({0x60F9, 1}, D::Unsigned32, A::ReadWrite, std::max<uint64_t>(1, scaled(kv_default, 1e-4, 4e9)), false,
         "Velocity gain (0.1 mN m s/rad)");
  od.add({0x60F9, 2}, D::Unsigned16, A::ReadWrite, scaled(cfg_.gains.velocity_integral_time, 1e-4, 65535), false,
         "Velocity integration time constant (0.1 ms)");
  count(0x60FB, 5, "Position control parameter set");
  od.add({0x60FB, 1}, D::Unsigned32, A::ReadWrite, scaled(cfg_.gains.position_gain, 0.01, 4e9), false,
         "Position gain (0.01 1/s)");
  od.add({0x60FB, 2}, D::Unsigned16, A::ReadOnly, 0, false, "Position integration time constant (none)");
  od.add({0x60FB, 3}, D::Unsigned16, A::ReadOnly, 0, false, "Position differentiation time constant (none)");
  od.add({0x60FB, 4}, D::Unsigned16, A::ReadWrite, scaled(cfg_.gains.velocity_ff, 1e-3, 1000), false,
         "Velocity feed-forward (per mille)");
  od.add({0x60FB, 5}, D::Unsigned16, A::ReadWrite, scaled(cfg_.gains.torque_ff, 1e-3, 1000), false,
         "Acceleration feed-forward (per mille)");
  // Simulator objects (manufacturer range).
  od.add({0x2000, 0}, D::Integer16, A::ReadOnly, 0, true, "Drive temperature (0.1 C)");
  od.add({0x2001, 0}, D::Real64, A::ReadOnly, 0, false, "True table position (mm, interferometer)");

  controlword_ = od.var<uint16_t>(at(obj::kControlword));
  statusword_obj_ = od.var<uint16_t>(at(obj::kStatusword));
  error_code_obj_ = od.var<uint16_t>(at(obj::kErrorCode));
  modes_ = od.var<int8_t>(at(obj::kModes));
  modes_display_ = od.var<int8_t>(at(obj::kModesDisplay));
  target_position_ = od.var<int32_t>(at(obj::kTargetPosition));
  position_actual_ = od.var<int32_t>(at(obj::kPositionActual));
  position_demand_ = od.var<int32_t>(at(obj::kPositionDemand));
  velocity_actual_ = od.var<int32_t>(at(obj::kVelocityActual));
  target_velocity_ = od.var<int32_t>(at(obj::kTargetVelocity));
  ferror_actual_ = od.var<int32_t>(at(obj::kFollowingErrorActual));
  home_offset_ = od.var<int32_t>(at(obj::kHomeOffset));
  probe1_rise_ = od.var<int32_t>(at(obj::kTouchProbe1Rising));
  probe1_fall_ = od.var<int32_t>(at(obj::kTouchProbe1Falling));
  probe2_rise_ = od.var<int32_t>(at(obj::kTouchProbe2Rising));
  probe2_fall_ = od.var<int32_t>(at(obj::kTouchProbe2Falling));
  sw_limit_min_ = od.var<int32_t>(at(obj::kSwLimitMin));
  sw_limit_max_ = od.var<int32_t>(at(obj::kSwLimitMax));
  velocity_offset_ = od.var<int32_t>(at(obj::kVelocityOffset));
  target_torque_ = od.var<int16_t>(at(obj::kTargetTorque));
  torque_actual_ = od.var<int16_t>(at(obj::kTorqueActual));
  torque_offset_ = od.var<int16_t>(at(obj::kTorqueOffset));
  quick_stop_option_ = od.var<int16_t>(at(obj::kQuickStopOption));
  shutdown_option_ = od.var<int16_t>(at(obj::kShutdownOption));
  disable_option_ = od.var<int16_t>(at(obj::kDisableOperationOption));
  halt_option_ = od.var<int16_t>(at(obj::kHaltOption));
  fault_reaction_option_ = od.var<int16_t>(at(obj::kFaultReactionOption));
  abort_option_ = od.var<int16_t>(at(obj::kAbortConnection));
  ferror_window_ = od.var<uint32_t>(at(obj::kFollowingErrorWindow));
  max_profile_velocity_ = od.var<uint32_t>(at(obj::kMaxProfileVelocity));
  max_motor_speed_ = od.var<uint32_t>(at(obj::kMaxMotorSpeed));
  quick_stop_decel_ = od.var<uint32_t>(at(obj::kQuickStopDeceleration));
  profile_decel_ = od.var<uint32_t>(at(obj::kProfileDeceleration));
  homing_speed_switch_ = od.var<uint32_t>(at(obj::kHomingSpeedSwitch));
  homing_speed_zero_ = od.var<uint32_t>(at(obj::kHomingSpeedZero));
  homing_accel_ = od.var<uint32_t>(at(obj::kHomingAcceleration));
  digital_inputs_ = od.var<uint32_t>(at(obj::kDigitalInputs));
  supported_modes_ = od.var<uint32_t>(at(obj::kSupportedModes));
  position_window_ = od.var<uint32_t>(at(obj::kPositionWindow));
  ferror_timeout_ = od.var<uint16_t>(at(obj::kFollowingErrorTimeout));
  probe_function_ = od.var<uint16_t>(at(obj::kTouchProbeFunction));
  probe_status_ = od.var<uint16_t>(at(obj::kTouchProbeStatus));
  max_torque_ = od.var<uint16_t>(at(obj::kMaxTorque));
  homing_method_ = od.var<int8_t>(at(obj::kHomingMethod));
  ip_index_ = od.var<int8_t>(at(obj::kInterpolationPeriodIndex));
  ip_value_ = od.var<uint8_t>(at(obj::kInterpolationPeriodValue));
  temperature_obj_ = od.var<int16_t>({0x2000, 0});
  table_position_obj_ = od.var<double>({0x2001, 0});
  velocity_gain_obj_ = od.var<uint32_t>({0x60F9, 1});
  velocity_ti_obj_ = od.var<uint16_t>({0x60F9, 2});
  position_gain_obj_ = od.var<uint32_t>({0x60FB, 1});
  velocity_ff_obj_ = od.var<uint16_t>({0x60FB, 4});
  torque_ff_obj_ = od.var<uint16_t>({0x60FB, 5});
  if (od.find({0x1001, 0})) error_register_ = od.var<uint8_t>({0x1001, 0});
  if (od.find({0x1006, 0})) comm_cycle_us_ = od.var<uint32_t>({0x1006, 0});

  auto check = [this](const canopen::OdEntry& e, const uint8_t* d, std::size_t n) { return check_write(e, d, n); };
  for (uint16_t index : {0x6007, 0x605A, 0x605B, 0x605C, 0x605D, 0x605E, 0x6060, 0x6065, 0x6066, 0x6067, 0x6068, 0x6071,
                         0x6072, 0x607A, 0x607C, 0x607D, 0x607F, 0x6080, 0x6083, 0x6084, 0x6085, 0x6098, 0x6099, 0x609A,
                         0x60B1, 0x60B2, 0x60B8, 0x60C2, 0x60F9, 0x60FB, 0x60FE, 0x60FF}) {
    od.set_write_check(index, check);
  }
  od.set_after_write(obj::kControlword.index, [this](const canopen::OdEntry&) { controlword_written(); });
}

uint32_t DriveModel::check_write(const canopen::OdEntry& e, const uint8_t* d, std::size_t n) const noexcept {
  if (refuse_writes_) return kAbortDeviceState;
  if (n < 1) return 0;
  if (e.addr.index == obj::kModes.index) {
    const auto m = static_cast<Mode>(static_cast<int8_t>(d[0]));
    const int bit = supported_mode_bit(m);
    if (m != Mode::None && (bit < 0 || !((supported_modes_.get() >> bit) & 1u))) return kAbortValueRange;
  }
  // A velocity loop without gain does not hold the axis; feed-forward
  // above 100 % is not a drive's.
  if (e.addr == ObjectAddress{0x60F9, 1} && n >= 4 && (d[0] | d[1] | d[2] | d[3]) == 0) return kAbortValueRange;
  if (e.addr.index == 0x60FB && (e.addr.sub == 4 || e.addr.sub == 5) && n >= 2 && (d[0] | (d[1] << 8)) > 1000)
    return kAbortValueRange;
  if (e.addr.index == obj::kHomingMethod.index) {
    const int m = static_cast<int8_t>(d[0]);
    if (!HomingEngine::is_supported(m)) return kAbortValueRange;
  }
  return 0;
}

int64_t DriveModel::period_ns() const noexcept {
  const int value = ip_value_.get();
  const int index = ip_index_.get();
  if (value > 0 && index <= 0 && index >= -9) {
    double s = value;
    for (int i = 0; i < -index; ++i) s /= 10.0;
    const auto ns = static_cast<int64_t>(std::llround(s * 1e9));
    if (ns >= 50'000) return ns;
  }
  if (comm_cycle_us_.valid() && comm_cycle_us_.get() >= 50) return int64_t{comm_cycle_us_.get()} * 1000;
  return cfg_.default_period_ns;
}

int64_t DriveModel::position() const noexcept { return static_cast<int64_t>(measured_); }

double DriveModel::encoder_counts() const noexcept {
  return encoder_lost_ ? frozen_counts_ : static_cast<double>(motor_sign() * plant_.encoder());
}

void DriveModel::power_on(int64_t now_ns) noexcept {
  plant_.reset(cfg_.plant);
  homing_.interrupt();
  state_ = State::NotReadyToSwitchOn;
  power_on_ns_ = now_ns;
  time_ns_ = now_ns;
  last_sync_ns_ = -1;
  last_cw_ = 0;
  error_code_ = 0;
  error_register_bits_ = 0;
  mode_ = Mode::None;
  stop_ = Stop::None;
  warning_ = halted_ = homed_ = false;
  fault_at_ns_ = -1;
  offset_ = 0;
  demand_ = measured_ = last_counts_ = 0;
  velocity_est_ = velocity_report_ = integral_ = vff_ = aff_ = 0;
  seg_start_ = seg_end_ = seg_elapsed_ = 0;
  target_valid_ = false;
  probe_[0] = probe_[1] = ProbeState{};
  temperature_ = cfg_.ambient_c;
  error_code_obj_.set(0);
  update_statusword();
}

void DriveModel::enter(State s) noexcept {
  const State prev = state_;
  state_ = s;
  if (s == State::OperationEnabled && prev != State::OperationEnabled && prev != State::QuickStopActive) {
    // Enabling: the demand starts where the motor is, whatever the target says.
    demand_ = seg_start_ = seg_end_ = measured_;
    seg_elapsed_ = seg_length_;
    seg_velocity_ = 0;
    vff_ = aff_ = integral_ = 0;
    ferror_time_ = 0;
    target_valid_ = false;
    velocity_limited_ = false;
    halted_ = false;
  }
  if (s != State::OperationEnabled && s != State::QuickStopActive && s != State::FaultReactionActive) {
    stop_ = Stop::None;
    homing_.interrupt();
  }
}

void DriveModel::begin_stop(int16_t option, State then) noexcept {
  const int o = option > 4 ? option - 4 : option;
  after_stop_ = then;
  ramp_velocity_ = vff_ != 0 ? vff_ : velocity_est_;
  if (ferror_exceeded_ || std::fabs(demand_ - measured_) > ferror_window_.get()) {
    // The axis is not where the demand is (a following error): the stop
    // starts from where the axis is and how fast it moves, or the ramp
    // would first pull it to the old demand at full torque.
    demand_ = measured_;
    ramp_velocity_ = velocity_est_;
    integral_ = 0;
  }
  settle_s_ = 0;
  homing_.interrupt();
  switch (o) {
    case 0:
      stop_ = Stop::Coast;
      break;
    case 1:
      stop_ = Stop::Ramp;
      stop_decel_ = std::max<double>(1.0, profile_decel_.get());
      break;
    case 2:
      stop_ = Stop::Ramp;
      stop_decel_ = std::max<double>(1.0, quick_stop_decel_.get());
      break;
    default:
      stop_ = Stop::CurrentLimit;
      break;
  }
  if (stop_ == Stop::Coast) {
    stop_ = Stop::None;
    if (then != state_) {
      state_ = then;  // the power stage goes off at once
      if (then == State::Fault) update_statusword();
    }
  }
}

void DriveModel::raise_fault(uint16_t code, uint8_t reg, bool coast) noexcept {
  if (state_ == State::Fault || state_ == State::FaultReactionActive) return;
  const bool powered = state_ == State::OperationEnabled || state_ == State::QuickStopActive;
  error_code_ = code;
  error_register_bits_ = static_cast<uint8_t>(error_register_bits_ | reg | 0x01);
  error_code_obj_.set(code);
  if (error_register_.valid()) error_register_.set(error_register_bits_);
  if (on_emcy) on_emcy(code, error_register_bits_);
  state_ = State::FaultReactionActive;
  if (!powered || coast) {
    stop_ = Stop::None;
    state_ = State::Fault;
    warning_ = false;
    homing_.interrupt();
  } else {
    begin_stop(fault_reaction_option_.get(), State::Fault);
  }
  update_statusword();
}

bool DriveModel::fault_cause_present() const noexcept {
  return encoder_lost_ || temperature() >= cfg_.trip_c;
}

void DriveModel::process_controlword(uint16_t cw) noexcept {
  const bool reset_edge = (cw & cw::kFaultReset) && !(last_cw_ & cw::kFaultReset);
  const bool start_edge = (cw & cw::kBit4) && !(last_cw_ & cw::kBit4);
  last_cw_ = cw;
  if (state_ == State::Fault) {
    if (reset_edge && !fault_cause_present()) {
      error_code_ = 0;
      error_code_obj_.set(0);
      error_register_bits_ = 0;
      if (error_register_.valid()) error_register_.set(0);
      overcurrent_ = false;
      warning_ = false;
      pending_fault_ = 0;
      state_ = State::SwitchOnDisabled;  // T15
      if (on_emcy) on_emcy(0, 0);
    }
    return;
  }
  if (state_ == State::FaultReactionActive || state_ == State::NotReadyToSwitchOn) return;
  const Command c = decode_command(cw);
  const int16_t qs = quick_stop_option_.get();
  const State next = next_state(state_, c, qs >= 5);
  if (next != state_) {
    if (state_ == State::OperationEnabled) {
      switch (next) {
        case State::QuickStopActive:  // T11
          state_ = State::QuickStopActive;
          begin_stop(qs, qs >= 5 ? State::QuickStopActive : State::SwitchOnDisabled);
          break;
        case State::SwitchedOn:  // T5
          begin_stop(disable_option_.get() == 0 ? 0 : 1, State::SwitchedOn);
          break;
        case State::ReadyToSwitchOn:  // T8
          begin_stop(shutdown_option_.get() == 0 ? 0 : 1, State::ReadyToSwitchOn);
          break;
        default:  // T9: disable voltage, the motor coasts
          enter(next);
          break;
      }
    } else {
      enter(next);
    }
  }
  if (state_ == State::OperationEnabled && stop_ == Stop::None) {
    const bool halt = (cw & cw::kHalt) != 0;
    if (halt && !halted_) {
      halted_ = true;
      begin_stop(std::max<int16_t>(1, halt_option_.get()), State::OperationEnabled);
    } else if (!halt) {
      halted_ = false;
    }
    if (mode_ == Mode::Homing) {
      HomingEngine::Inputs in;
      in.neg_limit = drive_neg_limit();
      in.pos_limit = drive_pos_limit();
      in.home = plant_.home_switch();
      in.counts = encoder_counts();
      if (start_edge && !halted_) {
        homing_started_ = true;
        demand_ = measured_;
        homing_.start(homing_method_.get(), homing_speed_switch_.get(), homing_speed_zero_.get(), homing_accel_.get(), in);
      } else if (!(cw & cw::kBit4)) {
        homing_.interrupt();
      }
    }
  }
}

void DriveModel::controlword_written() noexcept { process_controlword(controlword_.get()); }

void DriveModel::apply_mode() noexcept {
  const auto m = static_cast<Mode>(modes_.get());
  const int bit = supported_mode_bit(m);
  if (m != Mode::None && (bit < 0 || !((supported_modes_.get() >> bit) & 1u))) return;  // refused: display unchanged
  mode_ = m;
  modes_display_.set(static_cast<int8_t>(m));
  homing_.interrupt();
  homing_started_ = false;
  demand_ = seg_start_ = seg_end_ = measured_;
  seg_elapsed_ = seg_length_;
  seg_velocity_ = 0;
  vff_ = aff_ = 0;
  target_valid_ = false;
  velocity_limited_ = false;
}

void DriveModel::start_segment() noexcept {
  // CSP: the new target is reached at the next SYNC, linearly.
  const int32_t raw = target_position_.get();
  if (!target_valid_) {
    target_unwrapped_ = static_cast<int64_t>(demand_) + static_cast<int32_t>(static_cast<uint32_t>(raw) -
                                                                               static_cast<uint32_t>(wrap32(static_cast<int64_t>(demand_))));
    target_valid_ = true;
  } else {
    target_unwrapped_ += static_cast<int32_t>(static_cast<uint32_t>(raw) - static_cast<uint32_t>(target_raw_));
  }
  target_raw_ = raw;
  const double length = static_cast<double>(period_ns()) * 1e-9;
  // A target further than the drive may travel in one period (late
  // set-points caught up at once, a master's jump) is approached at the
  // velocity limit; the rest is left for the next periods (bit 11 meanwhile).
  const double v_max = max_velocity();
  const double v_new = std::clamp((static_cast<double>(target_unwrapped_) - demand_) / length, -v_max, v_max);
  velocity_limited_ = std::fabs(static_cast<double>(target_unwrapped_) - demand_) > v_max * length;
  const bool previous_ran_out = seg_elapsed_ > seg_length_ * 1.5;  // a late or missing SYNC: the drive held still
  aff_ = (v_new - (previous_ran_out ? 0.0 : seg_velocity_)) / length;
  seg_velocity_ = v_new;
  seg_start_ = demand_;
  seg_end_ = velocity_limited_ ? demand_ + v_new * length : static_cast<double>(target_unwrapped_);
  seg_elapsed_ = 0;
  seg_length_ = length;
}

double DriveModel::max_velocity() const noexcept {
  // 0x6080 is in motor revolutions per minute, 0x607F in increments/s
  // (factor group 1:1); 0xFFFFFFFF: no limit.
  double v = std::numeric_limits<double>::infinity();
  if (max_motor_speed_.get() != 0xFFFFFFFFu) v = max_motor_speed_.get() / 60.0 * cfg_.plant.encoder_counts;
  if (max_profile_velocity_.get() != 0xFFFFFFFFu) v = std::min(v, static_cast<double>(max_profile_velocity_.get()));
  return v;
}

void DriveModel::on_sync(int64_t now_ns) noexcept {
  ++syncs_;
  // The drive's cycle is locked to the SYNC period (as a drive's PLL does):
  // arbitration jitter of the SYNC frame moves it only a sixteenth.
  const int64_t period = period_ns();
  const int64_t expected = sync_phase_ns_ + period;
  if (last_sync_ns_ >= 0 && std::llabs(now_ns - expected) < period / 4) sync_phase_ns_ = expected + (now_ns - expected) / 16;
  else sync_phase_ns_ = now_ns;
  if (time_ns_ < sync_phase_ns_) run_until(sync_phase_ns_);
  last_sync_ns_ = now_ns;
  process_controlword(controlword_.get());
  if (modes_.get() != static_cast<int8_t>(mode_)) apply_mode();
  if (state_ == State::OperationEnabled && mode_ == Mode::CyclicSyncPosition && stop_ == Stop::None && !halted_) {
    start_segment();
  }
  run_until(sync_phase_ns_ + period);
}

void DriveModel::advance_to(int64_t now_ns) noexcept {
  if (power_on_ns_ < 0) return;
  if (now_ns - time_ns_ > 1'000'000'000) time_ns_ = now_ns - 1'000'000'000;  // a paused process: simulate 1 s at most
  if (state_ == State::OperationEnabled && is_cyclic(mode_) && last_sync_ns_ >= 0 &&
      now_ns - last_sync_ns_ > cfg_.sync_timeout_ns && fault_at_ns_ < 0) {
    connection_lost(err::kSyncLost);
  }
  if (time_ns_ < now_ns) run_until(now_ns);
}

void DriveModel::connection_lost(uint16_t code) noexcept {
  switch (abort_option_.get()) {
    case kAbortNone:
      return;
    case kAbortFault:
      if (state_ == State::Fault || state_ == State::FaultReactionActive || state_ == State::NotReadyToSwitchOn) return;
      if (fault_at_ns_ >= 0) return;  // one already pending: the first cause is the reason
      // As real drives do: a warning first, the fault reaction a cycle later.
      warning_ = true;
      pending_fault_ = code;
      fault_at_ns_ = time_ns_ + period_ns();
      update_statusword();
      return;
    case kAbortDisableVoltage:
      if (state_ != State::Fault && state_ != State::FaultReactionActive && state_ != State::NotReadyToSwitchOn) {
        enter(State::SwitchOnDisabled);
      }
      return;
    case kAbortQuickStop:
      if (state_ == State::OperationEnabled) {
        state_ = State::QuickStopActive;
        begin_stop(quick_stop_option_.get(), State::SwitchOnDisabled);
      }
      return;
    default:
      return;
  }
}

void DriveModel::inject_overcurrent() noexcept { overcurrent_ = true; }

void DriveModel::set_encoder_lost(bool lost) noexcept {
  if (lost && !encoder_lost_) frozen_counts_ = static_cast<double>(motor_sign() * plant_.encoder());
  encoder_lost_ = lost;
}

void DriveModel::clear_injections() noexcept {
  overcurrent_ = false;
  temperature_offset_ = 0;
  jam_force_ = 0;
  plant_.set_extra_friction(0);
  set_encoder_lost(false);
  refuse_writes_ = false;
}

void DriveModel::run_until(int64_t t_ns) noexcept {
  const auto step_ns = static_cast<int64_t>(std::llround(cfg_.step_s * 1e9));
  while (time_ns_ < t_ns) {
    const int64_t dt_ns = std::min(step_ns, t_ns - time_ns_);
    time_ns_ += dt_ns;
    step(static_cast<double>(dt_ns) * 1e-9);
  }
}

void DriveModel::update_probes(const StepEvents& ev) noexcept {
  const uint16_t fn = probe_function_.get();
  uint16_t status = 0;
  for (int p = 0; p < 2; ++p) {
    const int shift = 8 * p;
    const uint16_t bits = static_cast<uint16_t>((fn >> shift) & 0xFF);
    ProbeState& ps = probe_[p];
    const bool enable = (bits & tp::kEnable) != 0;
    if (enable && (!ps.enabled || ((ps.function ^ bits) & 0x3C))) {
      ps.enabled = true;  // an enable edge (or a new source/edge choice) clears what was stored
      ps.latched = false;
      ps.function = bits;
    }
    if (!enable) {
      ps = ProbeState{};
      continue;
    }
    uint16_t stored = static_cast<uint16_t>((probe_status_.get() >> shift) & 0x06);
    const bool may = !ps.latched || (bits & tp::kContinuous);
    if (may) {
      const bool zero_pulse = (bits & 0x0C) == tp::kSourceZeroPulse;
      bool rise = false, fall = false;
      double at_counts = 0;
      if (zero_pulse && ev.index) {
        rise = true;
        at_counts = motor_sign() * ev.index_counts;
      } else if (!zero_pulse && (ev.probe_rise || ev.probe_fall)) {
        rise = ev.probe_rise;
        fall = ev.probe_fall;
        at_counts = motor_sign() * ev.probe_counts;
      }
      const int32_t value = wrap32(static_cast<int64_t>(std::floor(at_counts)) + offset_);
      if (rise && (bits & tp::kRising)) {
        (p == 0 ? probe1_rise_ : probe2_rise_).set(value);
        stored |= tp::kStatusRisingStored;
        ps.latched = true;
      }
      if (fall && (bits & tp::kFalling)) {
        (p == 0 ? probe1_fall_ : probe2_fall_).set(value);
        stored |= tp::kStatusFallingStored;
        ps.latched = true;
      }
    }
    status = static_cast<uint16_t>(status | ((tp::kStatusEnabled | stored) << shift));
  }
  if (plant_.probe_input()) status |= tp::kStatusInputLevel;
  probe_status_.set(status);
}

void DriveModel::update_statusword() noexcept {
  uint16_t s = static_cast<uint16_t>(state_bits(state_) | sw::kRemote);
  if (state_ != State::NotReadyToSwitchOn) s |= sw::kVoltageEnabled;
  if (warning_ || temperature() >= cfg_.warning_c) s |= sw::kWarning;
  const bool csp_limited = velocity_limited_ && state_ == State::OperationEnabled && mode_ == Mode::CyclicSyncPosition;
  if (internal_limit_ || csp_limited || torque_limited_ || plant_.current_limited()) s |= sw::kInternalLimit;
  if (state_ == State::OperationEnabled) {
    switch (mode_) {
      case Mode::CyclicSyncPosition:
        if (!halted_ && stop_ == Stop::None) s |= sw::kBit12;
        if (ferror_exceeded_) s |= sw::kBit13;
        if (vff_ == 0 && std::fabs(seg_end_ - measured_) <= position_window_.get()) s |= sw::kTargetReached;
        break;
      case Mode::CyclicSyncVelocity:
      case Mode::CyclicSyncTorque:
        if (!halted_ && stop_ == Stop::None) s |= sw::kBit12;
        break;
      case Mode::Homing:
        switch (homing_.status()) {
          case HomingEngine::Status::Idle: s |= homing_bits(HomingStatus::Interrupted); break;
          case HomingEngine::Status::InProgress: s |= homing_bits(HomingStatus::InProgress); break;
          case HomingEngine::Status::Attained: s |= homing_bits(HomingStatus::AttainedNotReached); break;
          case HomingEngine::Status::Completed: s |= homing_bits(HomingStatus::Completed); break;
          case HomingEngine::Status::Error:
            s |= homing_bits(homing_.is_moving() ? HomingStatus::ErrorMoving : HomingStatus::ErrorStopped);
            break;
        }
        break;
      default:
        break;
    }
  }
  statusword_ = s;
  statusword_obj_.set(s);
}

void DriveModel::step(double dt) noexcept {
  // Temperature: first order towards ambient + a rise with the current squared.
  const double amps = std::fabs(plant_.torque()) / cfg_.plant.torque_constant;
  const double settle = cfg_.ambient_c + cfg_.thermal_c_per_a2 * amps * amps;
  temperature_ += (settle - temperature_) * dt / cfg_.thermal_tau_s;
  plant_.set_extra_friction(jam_force_);

  if (state_ == State::NotReadyToSwitchOn && power_on_ns_ >= 0 && time_ns_ - power_on_ns_ >= cfg_.init_ns) {
    state_ = State::SwitchOnDisabled;  // T1
  }
  if (fault_at_ns_ >= 0 && time_ns_ >= fault_at_ns_) {
    fault_at_ns_ = -1;
    raise_fault(pending_fault_, 0x10, false);  // error register: communication
  }
  if (overcurrent_ && state_ != State::Fault) {
    overcurrent_ = false;
    raise_fault(err::kOverCurrent, 0x02, true);
  }
  if (temperature() >= cfg_.trip_c) raise_fault(err::kOverTemperature, 0x08, false);
  if (encoder_lost_) raise_fault(err::kEncoder, 0x80, true);
  if (modes_.get() != static_cast<int8_t>(mode_) && state_ != State::OperationEnabled) apply_mode();

  const double cpr = plant_.counts_per_rad();
  const double counts = encoder_counts();
  const double raw_velocity = (counts - last_counts_) / dt;
  last_counts_ = counts;
  velocity_est_ += (raw_velocity - velocity_est_) * (dt / (cfg_.gains.velocity_filter_tau + dt));
  velocity_report_ += (raw_velocity - velocity_report_) * (dt / (1e-3 + dt));  // 0x606C: averaged over ~1 ms
  measured_ = counts + static_cast<double>(offset_);

  bool power = state_ == State::OperationEnabled || state_ == State::QuickStopActive ||
               state_ == State::FaultReactionActive;
  bool position_loop = true;
  double v_ref = 0, torque_cmd = 0;
  bool torque_mode = false;
  internal_limit_ = false;
  if (stop_ == Stop::Ramp) {
    const double dv = stop_decel_ * dt;
    ramp_velocity_ = ramp_velocity_ > 0 ? std::max(0.0, ramp_velocity_ - dv) : std::min(0.0, ramp_velocity_ + dv);
    aff_ = ramp_velocity_ == 0 ? 0 : (ramp_velocity_ > 0 ? -stop_decel_ : stop_decel_);
    vff_ = ramp_velocity_;
    demand_ += ramp_velocity_ * dt;
    // Done when the reference is at zero and the motor has settled (at most
    // 50 ms): only then the power stage may go off.
    if (ramp_velocity_ == 0) settle_s_ += dt;
    if (ramp_velocity_ == 0 && (std::fabs(velocity_est_) < 0.0005 * cfg_.plant.encoder_counts || settle_s_ > 0.05)) {
      stop_ = Stop::None;
      settle_s_ = 0;
      if (after_stop_ != state_) state_ = after_stop_;  // T14, T12 (option 1-4), T5, T8 after the ramp
      if (state_ == State::Fault) warning_ = false;    // the warning led to the fault: it is the fault now
    }
  } else if (stop_ == Stop::CurrentLimit) {
    position_loop = false;
    v_ref = 0;
    demand_ = measured_;
    vff_ = aff_ = 0;
    if (std::fabs(velocity_est_) < 0.001 * cfg_.plant.encoder_counts) {
      stop_ = Stop::None;
      if (after_stop_ != state_) state_ = after_stop_;
    }
  } else if (state_ == State::OperationEnabled && !halted_) {
    switch (mode_) {
      case Mode::CyclicSyncPosition: {
        seg_elapsed_ += dt;
        const double f = seg_length_ > 0 ? std::min(seg_elapsed_ / seg_length_, 1.0) : 1.0;
        demand_ = seg_start_ + (seg_end_ - seg_start_) * f;
        if (seg_elapsed_ > seg_length_ * 1.001) vff_ = aff_ = 0;  // the next set-point is late: hold
        else vff_ = seg_velocity_;
        break;
      }
      case Mode::CyclicSyncVelocity:
        position_loop = false;
        v_ref = static_cast<double>(target_velocity_.get()) + velocity_offset_.get();
        demand_ = measured_;
        vff_ = aff_ = 0;
        break;
      case Mode::CyclicSyncTorque:
        torque_mode = true;
        torque_cmd = (target_torque_.get() + torque_offset_.get()) * 0.001 * cfg_.plant.rated_torque;
        demand_ = measured_;
        break;
      case Mode::Homing: {
        HomingEngine::Inputs in;
        in.neg_limit = drive_neg_limit();
        in.pos_limit = drive_pos_limit();
        in.home = plant_.home_switch();
        in.index = last_events_.index;
        in.index_counts = last_events_.index_counts;
        in.counts = counts;
        in.velocity = velocity_est_;
        const HomingEngine::Output o = homing_.step(dt, in);
        demand_ += o.velocity * dt;
        vff_ = o.velocity;
        aff_ = o.acceleration;
        if (o.home_event) {
          // The reference reads the home offset (0x607C) from now on.
          const int64_t before = offset_;
          offset_ = static_cast<int64_t>(home_offset_.get()) - static_cast<int64_t>(std::floor(o.home_counts));
          const double shift = static_cast<double>(offset_ - before);
          demand_ += shift;
          measured_ += shift;
          seg_start_ += shift;
          seg_end_ += shift;
          homed_ = true;
        }
        break;
      }
      default:
        vff_ = aff_ = 0;
        break;
    }
  } else if (state_ == State::QuickStopActive || (state_ == State::OperationEnabled && halted_)) {
    vff_ = aff_ = 0;  // stopped: hold the position
  } else {
    demand_ = measured_;
    vff_ = aff_ = 0;
  }

  // Travel limits: never further into an active limit switch (not while
  // homing, which uses them as references); software limits clamp the demand.
  if (power && position_loop && !(mode_ == Mode::Homing && state_ == State::OperationEnabled)) {
    if (drive_pos_limit() && demand_ > measured_) {
      demand_ = measured_;
      vff_ = std::min(vff_, 0.0);
      aff_ = 0;
      internal_limit_ = true;
    }
    if (drive_neg_limit() && demand_ < measured_) {
      demand_ = measured_;
      vff_ = std::max(vff_, 0.0);
      aff_ = 0;
      internal_limit_ = true;
    }
    const double lo = sw_limit_min_.get(), hi = sw_limit_max_.get();
    if (lo < hi) {
      if (demand_ > hi) {
        demand_ = hi;
        vff_ = std::min(vff_, 0.0);
        aff_ = 0;
        internal_limit_ = true;
      } else if (demand_ < lo) {
        demand_ = lo;
        vff_ = std::max(vff_, 0.0);
        aff_ = 0;
        internal_limit_ = true;
      }
    }
  }

  // Cascaded loops: position (P + velocity feed-forward) -> velocity (PI +
  // torque feed-forward) -> current limit and lag in the plant.
  // The gains as 0x60F9 and 0x60FB hold them now.
  const double j = plant_.reflected_inertia();
  const double kv = velocity_gain_obj_.get() * 1e-4;
  const double ti = velocity_ti_obj_.get() * 1e-4;
  const double kp = position_gain_obj_.get() * 0.01;
  const double velocity_ff = velocity_ff_obj_.get() * 1e-3, torque_ff = torque_ff_obj_.get() * 1e-3;
  torque_limited_ = false;
  if (power && !torque_mode) {
    if (position_loop) v_ref = kp * (demand_ - measured_) + velocity_ff * vff_;
    const double ev = (v_ref - velocity_est_) / cpr;  // rad/s
    const double wanted = kv * ev + integral_ + torque_ff * j * aff_ / cpr;
    // The torque the drive can give: 0x6072, and never more than the power
    // stage's current limit.
    const double max_t = std::min(max_torque_.get() * 0.001 * cfg_.plant.rated_torque,
                                  cfg_.plant.torque_constant * cfg_.plant.max_current);
    torque_cmd = std::clamp(wanted, -max_t, max_t);
    torque_limited_ = wanted != torque_cmd || plant_.current_limited();
    if (ti > 0) {
      // Anti-windup (conditional integration): while the command is at the
      // torque limit the integral may only move back towards it, and it
      // never holds more than the limit. Without this a saturated loop winds
      // up and the axis swings out further with every reversal.
      const double di = kv / ti * ev * dt;
      if (!torque_limited_ || (di > 0) != (wanted > 0)) integral_ = std::clamp(integral_ + di, -max_t, max_t);
    }
  } else if (!power) {
    integral_ = 0;
    torque_cmd = 0;
  }
  last_events_ = plant_.step(dt, motor_sign() * torque_cmd, power);

  // Following error: window exceeded for longer than the time-out -> fault.
  ferror_exceeded_ = false;
  if (state_ == State::OperationEnabled && position_loop && stop_ == Stop::None) {
    const uint32_t window = ferror_window_.get();
    if (window != 0xFFFFFFFFu && std::fabs(demand_ - measured_) > window) {
      ferror_exceeded_ = true;
      ferror_time_ += dt;
      if (ferror_time_ * 1000.0 > ferror_timeout_.get()) raise_fault(err::kFollowingError, 0x20, false);
    } else {
      ferror_time_ = 0;
    }
  }
  update_probes(last_events_);

  const int64_t pos = static_cast<int64_t>(measured_);
  position_actual_.set(wrap32(pos));
  position_demand_.set(wrap32(static_cast<int64_t>(std::llround(demand_))));
  ferror_actual_.set(wrap32(static_cast<int64_t>(std::llround(demand_ - measured_))));
  velocity_actual_.set(static_cast<int32_t>(std::clamp(velocity_report_, -2.0e9, 2.0e9)));
  torque_actual_.set(static_cast<int16_t>(std::clamp(motor_sign() * plant_.torque() / cfg_.plant.rated_torque * 1000.0, -32768.0, 32767.0)));
  uint32_t din = 0;
  if (drive_neg_limit() != cfg_.switches_active_low) din |= din::kNegativeLimit;
  if (drive_pos_limit() != cfg_.switches_active_low) din |= din::kPositiveLimit;
  if (plant_.home_switch() != cfg_.switches_active_low) din |= din::kHomeSwitch;
  if (plant_.probe_input()) din |= din::kProbeInput;
  digital_inputs_.set(din);
  temperature_obj_.set(static_cast<int16_t>(std::clamp(temperature() * 10.0, -32768.0, 32767.0)));
  table_position_obj_.set(plant_.table_position() * 1000.0);
  update_statusword();
}

}  // namespace cnc::cia402::sim
