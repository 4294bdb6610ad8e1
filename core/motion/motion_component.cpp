#include "core/motion/motion_component.hpp"

#include <cmath>

#include "core/ini/ini_file.hpp"

namespace cnc::motion {

using hal::BitPin;
using hal::FloatPin;
using hal::PinDir;
using hal::S32Pin;
using hal::U32Pin;

struct MotionComponent::JointPins {
  FloatPin motor_pos_cmd, motor_pos_fb, pos_cmd, pos_fb, coarse_pos_cmd, vel_cmd, acc_cmd, f_error, f_error_lim;
  FloatPin motor_offset, backlash_corr, backlash_filt, backlash_vel, free_pos_cmd, free_vel_lim, index_position;
  FloatPin probe_position;
  U32Pin probe_count;
  BitPin amp_enable_out, amp_fault_in, amp_ready_in, home_sw_in, pos_lim_sw_in, neg_lim_sw_in, index_enable;
  BitPin active, homed, homing, faulted, f_errored, in_position, free_tp_enable, pos_hard_limit, neg_hard_limit;
  BitPin unlock, is_unlocked, drive_home_start, drive_home_busy, drive_home_done, drive_home_error;
  BitPin jog_enable, jog_vel_mode;
  FloatPin jog_scale;
  S32Pin jog_counts, home_state;
};

struct MotionComponent::AxisPins {
  FloatPin pos_cmd, teleop_pos_cmd, teleop_vel_cmd, teleop_vel_lim, jog_scale;
  BitPin teleop_tp_enable, jog_enable, jog_vel_mode;
  S32Pin jog_counts;
};

struct MotionComponent::SpindlePins {
  FloatPin speed_out, speed_out_abs, speed_out_rps, speed_cmd_rps, orient_angle, speed_in;
  BitPin on, forward, reverse, brake, orient, at_speed, is_oriented, amp_fault_in;
  S32Pin orient_mode, orient_fault;
};

struct MotionComponent::MotionPins {
  BitPin enable, motion_enabled, in_position, coord_mode, teleop_mode, coord_error, on_soft_limit, is_all_homed;
  BitPin probe_input, feed_hold, feed_inhibit, homing_inhibit, jog_inhibit, jog_stop, jog_stop_immediate;
  BitPin jog_is_active, watchdog, watchdog_enabled;
  FloatPin adaptive_feed, current_vel, requested_vel, distance_to_go, servo_last_period;
  S32Pin program_line, motion_type;
  FloatPin tool_offset[kNumAxes];
};

MotionComponent::MotionComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args, PlannerFactory factory)
    : hal::Component(ctx.hal, "motmod"), ctx_(ctx), planner_factory_(std::move(factory)) {
  args.allow_only({"servo_period_nsec", "base_period_nsec", "traj_period_nsec", "num_joints", "num_dio", "num_aio",
                   "num_spindles"});
  const int64_t base = args.get_int("base_period_nsec", 0, 0, 1'000'000'000);
  if (base != 0) {
    throw hal::HalError("motmod: base_period_nsec=" + std::to_string(base) +
                        ": there is no base thread (no software step generation); the drives close their own loops");
  }
  int64_t default_joints = 3;
  if (ctx.ini) default_joints = ctx.ini->get_int("KINS", "JOINTS", 3, {1, kMaxJoints});
  const int joints = static_cast<int>(args.get_int("num_joints", default_joints, 1, kMaxJoints));
  if (ctx.ini) {
    config_ = load_motion_config(*ctx.ini, joints);
  } else {
    config_.num_joints = joints;
  }
  const int64_t servo = args.get_int("servo_period_nsec", 0, 0, 1'000'000'000);
  if (servo != 0) {
    const int64_t ini_ns = std::llround(config_.servo_period_s * 1e9);
    if (!config_.servo_period_key.empty() && ini_ns != servo) {
      throw hal::HalError("motmod: servo_period_nsec=" + std::to_string(servo) + " differs from " +
                          config_.servo_period_key + " = " + std::to_string(ini_ns) + " ns: give one period");
    }
    config_.servo_period_s = static_cast<double>(servo) * 1e-9;
    const int64_t traj = args.get_int("traj_period_nsec", servo, servo, servo);
    (void)traj;
    if (!ctx.hal.find_thread("servo-thread")) ctx.hal.new_thread("servo-thread", servo);
  }
  config_.num_dio = static_cast<int>(args.get_int("num_dio", 4, 1, kMaxDio));
  config_.num_aio = static_cast<int>(args.get_int("num_aio", 4, 1, kMaxAio));
  config_.spindles = static_cast<int>(args.get_int("num_spindles", config_.spindles, 0, kMaxSpindles));
  // [EMCMOT]OVERRUN_STREAK is when any thread counts as late (and reports it).
  ctx.hal.set_overrun_limit(static_cast<uint32_t>(config_.overrun_streak));
  make_pins();
  export_method<&MotionComponent::command_handler>("motion-command-handler", this);
  export_method<&MotionComponent::controller>("motion-controller", this);
}

MotionComponent::~MotionComponent() = default;

void MotionComponent::make_pins() {
  pins_ = std::make_unique<MotionPins>();
  MotionPins& m = *pins_;
  m.enable = make_pin<bool>("motion.enable", PinDir::In, true);
  m.motion_enabled = make_pin<bool>("motion.motion-enabled", PinDir::Out);
  m.in_position = make_pin<bool>("motion.in-position", PinDir::Out);
  m.coord_mode = make_pin<bool>("motion.coord-mode", PinDir::Out);
  m.teleop_mode = make_pin<bool>("motion.teleop-mode", PinDir::Out);
  m.coord_error = make_pin<bool>("motion.coord-error", PinDir::Out);
  m.on_soft_limit = make_pin<bool>("motion.on-soft-limit", PinDir::Out);
  m.is_all_homed = make_pin<bool>("motion.is-all-homed", PinDir::Out);
  m.probe_input = make_pin<bool>("motion.probe-input", PinDir::In);
  m.feed_hold = make_pin<bool>("motion.feed-hold", PinDir::In);
  m.feed_inhibit = make_pin<bool>("motion.feed-inhibit", PinDir::In);
  m.homing_inhibit = make_pin<bool>("motion.homing-inhibit", PinDir::In);
  m.jog_inhibit = make_pin<bool>("motion.jog-inhibit", PinDir::In);
  m.jog_stop = make_pin<bool>("motion.jog-stop", PinDir::In);
  m.jog_stop_immediate = make_pin<bool>("motion.jog-stop-immediate", PinDir::In);
  m.jog_is_active = make_pin<bool>("motion.jog-is-active", PinDir::Out);
  m.watchdog = make_pin<bool>("motion.watchdog", PinDir::Out);
  m.watchdog_enabled = make_pin<bool>("motion.watchdog-enabled", PinDir::Out);
  m.adaptive_feed = make_pin<double>("motion.adaptive-feed", PinDir::In, 1.0);
  m.current_vel = make_pin<double>("motion.current-vel", PinDir::Out);
  m.requested_vel = make_pin<double>("motion.requested-vel", PinDir::Out);
  m.distance_to_go = make_pin<double>("motion.distance-to-go", PinDir::Out);
  m.servo_last_period = make_pin<double>("motion.servo.last-period", PinDir::Out);
  m.program_line = make_pin<int32_t>("motion.program-line", PinDir::Out);
  m.motion_type = make_pin<int32_t>("motion.motion-type", PinDir::Out);
  for (int a = 0; a < kNumAxes; ++a) {
    const std::string l(1, static_cast<char>(kAxisLetters[a] - 'A' + 'a'));
    m.tool_offset[a] = make_pin<double>("motion.tooloffset." + l, PinDir::Out);
  }
  char name[48];
  for (int i = 0; i < config_.num_dio; ++i) {
    std::snprintf(name, sizeof name, "motion.digital-in-%02d", i);
    din_.push_back(make_pin<bool>(name, PinDir::In));
    std::snprintf(name, sizeof name, "motion.digital-out-%02d", i);
    dout_.push_back(make_pin<bool>(name, PinDir::Out));
  }
  for (int i = 0; i < config_.num_aio; ++i) {
    std::snprintf(name, sizeof name, "motion.analog-in-%02d", i);
    ain_.push_back(make_pin<double>(name, PinDir::In));
    std::snprintf(name, sizeof name, "motion.analog-out-%02d", i);
    aout_.push_back(make_pin<double>(name, PinDir::Out));
  }
  for (int j = 0; j < config_.num_joints; ++j) {
    auto p = std::make_unique<JointPins>();
    const std::string n = "joint." + std::to_string(j) + ".";
    p->motor_pos_cmd = make_pin<double>(n + "motor-pos-cmd", PinDir::Out);
    p->motor_pos_fb = make_pin<double>(n + "motor-pos-fb", PinDir::In);
    p->pos_cmd = make_pin<double>(n + "pos-cmd", PinDir::Out);
    p->pos_fb = make_pin<double>(n + "pos-fb", PinDir::Out);
    p->coarse_pos_cmd = make_pin<double>(n + "coarse-pos-cmd", PinDir::Out);
    p->vel_cmd = make_pin<double>(n + "vel-cmd", PinDir::Out);
    p->acc_cmd = make_pin<double>(n + "acc-cmd", PinDir::Out);
    p->f_error = make_pin<double>(n + "f-error", PinDir::Out);
    p->f_error_lim = make_pin<double>(n + "f-error-lim", PinDir::Out);
    p->motor_offset = make_pin<double>(n + "motor-offset", PinDir::Out);
    p->backlash_corr = make_pin<double>(n + "backlash-corr", PinDir::Out);
    p->backlash_filt = make_pin<double>(n + "backlash-filt", PinDir::Out);
    p->backlash_vel = make_pin<double>(n + "backlash-vel", PinDir::Out);
    p->free_pos_cmd = make_pin<double>(n + "free-pos-cmd", PinDir::Out);
    p->free_vel_lim = make_pin<double>(n + "free-vel-lim", PinDir::Out);
    p->index_position = make_pin<double>(n + "index-position", PinDir::In);
    p->probe_position = make_pin<double>(n + "probe-position", PinDir::In);
    p->probe_count = make_pin<uint32_t>(n + "probe-count", PinDir::In);
    p->amp_enable_out = make_pin<bool>(n + "amp-enable-out", PinDir::Out);
    p->amp_fault_in = make_pin<bool>(n + "amp-fault-in", PinDir::In);
    p->amp_ready_in = make_pin<bool>(n + "amp-ready-in", PinDir::In, true);  // unconnected: ready
    p->home_sw_in = make_pin<bool>(n + "home-sw-in", PinDir::In);
    p->pos_lim_sw_in = make_pin<bool>(n + "pos-lim-sw-in", PinDir::In);
    p->neg_lim_sw_in = make_pin<bool>(n + "neg-lim-sw-in", PinDir::In);
    p->index_enable = make_pin<bool>(n + "index-enable", PinDir::IO);
    p->active = make_pin<bool>(n + "active", PinDir::Out);
    p->homed = make_pin<bool>(n + "homed", PinDir::Out);
    p->homing = make_pin<bool>(n + "homing", PinDir::Out);
    p->faulted = make_pin<bool>(n + "faulted", PinDir::Out);
    p->f_errored = make_pin<bool>(n + "f-errored", PinDir::Out);
    p->in_position = make_pin<bool>(n + "in-position", PinDir::Out);
    p->free_tp_enable = make_pin<bool>(n + "free-tp-enable", PinDir::Out);
    p->pos_hard_limit = make_pin<bool>(n + "pos-hard-limit", PinDir::Out);
    p->neg_hard_limit = make_pin<bool>(n + "neg-hard-limit", PinDir::Out);
    p->unlock = make_pin<bool>(n + "unlock", PinDir::Out);
    p->is_unlocked = make_pin<bool>(n + "is-unlocked", PinDir::In);
    p->drive_home_start = make_pin<bool>(n + "drive-home-start", PinDir::Out);
    p->drive_home_busy = make_pin<bool>(n + "drive-home-busy", PinDir::In);
    p->drive_home_done = make_pin<bool>(n + "drive-home-done", PinDir::In);
    p->drive_home_error = make_pin<bool>(n + "drive-home-error", PinDir::In);
    p->jog_enable = make_pin<bool>(n + "jog-enable", PinDir::In);
    p->jog_vel_mode = make_pin<bool>(n + "jog-vel-mode", PinDir::In);
    p->jog_scale = make_pin<double>(n + "jog-scale", PinDir::In);
    p->jog_counts = make_pin<int32_t>(n + "jog-counts", PinDir::In);
    p->home_state = make_pin<int32_t>(n + "home-state", PinDir::Out);
    joint_pins_.push_back(std::move(p));
  }
  for (int a = 0; a < kNumAxes; ++a) {
    auto p = std::make_unique<AxisPins>();
    const std::string n = std::string("axis.") + static_cast<char>(kAxisLetters[a] - 'A' + 'a') + ".";
    p->pos_cmd = make_pin<double>(n + "pos-cmd", PinDir::Out);
    p->teleop_pos_cmd = make_pin<double>(n + "teleop-pos-cmd", PinDir::Out);
    p->teleop_vel_cmd = make_pin<double>(n + "teleop-vel-cmd", PinDir::Out);
    p->teleop_vel_lim = make_pin<double>(n + "teleop-vel-lim", PinDir::Out);
    p->teleop_tp_enable = make_pin<bool>(n + "teleop-tp-enable", PinDir::Out);
    p->jog_enable = make_pin<bool>(n + "jog-enable", PinDir::In);
    p->jog_vel_mode = make_pin<bool>(n + "jog-vel-mode", PinDir::In);
    p->jog_scale = make_pin<double>(n + "jog-scale", PinDir::In);
    p->jog_counts = make_pin<int32_t>(n + "jog-counts", PinDir::In);
    axis_pins_.push_back(std::move(p));
  }
  for (int s = 0; s < config_.spindles; ++s) {
    auto p = std::make_unique<SpindlePins>();
    const std::string n = "spindle." + std::to_string(s) + ".";
    p->speed_out = make_pin<double>(n + "speed-out", PinDir::Out);
    p->speed_out_abs = make_pin<double>(n + "speed-out-abs", PinDir::Out);
    p->speed_out_rps = make_pin<double>(n + "speed-out-rps", PinDir::Out);
    p->speed_cmd_rps = make_pin<double>(n + "speed-cmd-rps", PinDir::Out);
    p->orient_angle = make_pin<double>(n + "orient-angle", PinDir::Out);
    p->speed_in = make_pin<double>(n + "speed-in", PinDir::In);
    p->on = make_pin<bool>(n + "on", PinDir::Out);
    p->forward = make_pin<bool>(n + "forward", PinDir::Out);
    p->reverse = make_pin<bool>(n + "reverse", PinDir::Out);
    p->brake = make_pin<bool>(n + "brake", PinDir::Out, true);
    p->orient = make_pin<bool>(n + "orient", PinDir::Out);
    p->at_speed = make_pin<bool>(n + "at-speed", PinDir::In, true);
    p->is_oriented = make_pin<bool>(n + "is-oriented", PinDir::In);
    p->amp_fault_in = make_pin<bool>(n + "amp-fault-in", PinDir::In);
    p->orient_mode = make_pin<int32_t>(n + "orient-mode", PinDir::Out);
    p->orient_fault = make_pin<int32_t>(n + "orient-fault", PinDir::In);
    spindle_pins_.push_back(std::move(p));
  }
}

void MotionComponent::on_ready() {
  kin::Kinematics* kins = nullptr;
  for (hal::Component* c : hal().components()) {
    if (auto* k = dynamic_cast<kin::KinematicsComponent*>(c)) {
      if (kins) throw hal::HalError("motmod: more than one kinematics module is loaded");
      kins = &k->kinematics();
    }
  }
  if (!kins) {
    throw hal::HalError("motmod: no kinematics module is loaded (add e.g. `loadrt trivkins coordinates=XYZ` to a HAL file)");
  }
  if (kins->num_joints() != config_.num_joints) {
    throw hal::HalError("motmod: num_joints=" + std::to_string(config_.num_joints) + " but kinematics " + kins->name() +
                        " drives " + std::to_string(kins->num_joints()) + " joints");
  }
  const uint32_t mask = kins->axis_mask();
  for (int a = 0; a < kNumAxes; ++a) {
    AxisConfig& ax = config_.axes[static_cast<std::size_t>(a)];
    if ((mask & (1U << a)) && !ax.present && ctx_.ini) {
      throw hal::HalError(std::string("motmod: the kinematics use axis ") + kAxisLetters[a] + " but the INI file has no [AXIS_" +
                          kAxisLetters[a] + "] section");
    }
    if (mask & (1U << a)) ax.present = true;
  }
  // The servo period is the period of the thread that runs
  // motion-controller (the planners integrate over it); a configured
  // [EMCMOT]SERVO_PERIOD must be that period.
  for (const hal::ThreadView& t : hal().thread_views()) {
    for (const std::string& f : t.functions) {
      if (f != "motion-controller") continue;
      const int64_t configured = std::llround(config_.servo_period_s * 1e9);
      if (!config_.servo_period_key.empty() && configured != t.period_ns) {
        throw hal::HalError(config_.servo_period_key + " = " + std::to_string(configured) + " ns, but motion-controller runs in " +
                            t.name + " with a period of " + std::to_string(t.period_ns) +
                            " ns: make them equal (or leave SERVO_PERIOD out)");
      }
      config_.servo_period_s = static_cast<double>(t.period_ns) * 1e-9;
    }
  }
  // [JOINT_n]COMP_FILE is read by the screwcomp component (comp/); without
  // it the table would be ignored without a word.
  if (ctx_.ini && !hal().find_component("screwcomp")) {
    for (int j = 0; j < config_.num_joints; ++j) {
      const std::string section = "JOINT_" + std::to_string(j);
      if (config_.joints[static_cast<std::size_t>(j)].comp_file.empty()) continue;
      ctx_.ini->fail(ctx_.ini->find_entry(section, "COMP_FILE"),
                     "a compensation table needs the screwcomp component: add `loadrt screwcomp` after `loadrt "
                     "motmod` to a HAL file (docs/compensation.md)");
    }
  }
  planner_ = planner_factory_(planner_config(config_, mask));
  controller_ = std::make_unique<MotionController>(config_, *kins, *planner_, ctx_.messages);
  controller_->fill_status(scratch_status_);
  status_.write(scratch_status_);
}

void MotionComponent::set_compensation(int joint, JointCompensation* comp) {
  if (!controller_) throw hal::HalError("motmod: compensation can only be attached after on_ready");
  controller_->set_compensation(joint, comp);
}

void MotionComponent::set_estop_inputs(ipc::EstopWords* words, hal::BitPin chain) {
  if (hal().threads_running()) throw hal::HalError("motmod: E-stop inputs can only be set before the threads start");
  estop_words_ = words;
  estop_chain_ = chain;
}

void MotionComponent::update(int64_t now_ns) {
  if (!controller_) return;
  const MotionStatus s = status_.read();
  if (s.cycles != last_cycles_ || last_advance_ns_ == 0) {
    last_cycles_ = s.cycles;
    last_advance_ns_ = now_ns;
    stale_updates_ = 0;
    stalled_ = false;
    return;
  }
  // A few task cycles without progress as well as the time: after the
  // whole process was stopped (SIGSTOP, a debugger) the task cycle may run
  // once before the servo thread does.
  ++stale_updates_;
  const int64_t threshold = ipc::servo_stall_threshold_ns(static_cast<int64_t>(config_.servo_period_s * 1e9));
  if (stalled_ || stale_updates_ < 5 || now_ns - last_advance_ns_ < threshold) return;
  stalled_ = true;
  std::string thread;
  bool running = false;
  for (const hal::ThreadView& t : hal().thread_views()) {
    for (const std::string& f : t.functions) {
      if (f == "motion-controller") {
        thread = t.name;
        running = t.running;
      }
    }
  }
  const std::string age = std::to_string((now_ns - last_advance_ns_) / 1'000'000) + " ms";
  if (thread.empty()) {
    stall_reason_ = "motion-controller is in no HAL thread any more (removed with delf?): motion has not run for " + age;
  } else if (!running) {
    stall_reason_ = "thread " + thread + " (which runs motion-controller) is stopped: motion has not run for " + age;
  } else {
    stall_reason_ = "motion-controller in thread " + thread + " has not run for " + age + " (the thread stalls)";
  }
}

void MotionComponent::on_shutdown() {
  MotionCommand c;
  c.type = Cmd::Abort;
  submit(c);
  c.type = Cmd::Disable;
  submit(c);
}

bool MotionComponent::is_safe_to_stop() const {
  if (!controller_) return true;
  const MotionStatus s = status_.read();
  return !s.traj.enabled;
}

uint64_t MotionComponent::submit(MotionCommand cmd) {
  cmd.serial = next_serial_;
  if (!commands_.push(cmd)) return 0;
  return next_serial_++;
}

void MotionComponent::contribute_status(ipc::Status& st) {
  if (!controller_) return;
  const MotionStatus s = status_.read();
  st.motion = s.traj;
  for (int j = 0; j < kMaxJoints; ++j) st.joints[j] = s.joints[j];
  for (int a = 0; a < kNumAxes; ++a) st.axes[a] = s.axes[a];
  for (int i = 0; i < ipc::kMaxSpindles; ++i) st.spindles[i] = s.spindles[i];
  if (stalled_) {
    // The pins hold their last values: nothing is commanded to move.
    st.motion.servo_stalled = true;
    st.motion.current_vel = 0;
    st.motion.inpos = true;
    for (int j = 0; j < kMaxJoints; ++j) st.joints[j].velocity = 0;
  }
}

namespace {
// Commands that stop or hold: safe to carry out however late they come.
bool is_safe_late(Cmd t) noexcept {
  return t == Cmd::Abort || t == Cmd::Disable || t == Cmd::Pause || t == Cmd::JogStop || t == Cmd::DisableAmplifier;
}
}  // namespace

void MotionComponent::command_handler(const rt::CycleInfo& info) noexcept {
  if (!controller_) return;
  // After the servo thread stood still (halcmd stop, delf, a stalled host)
  // the commands queued meanwhile are stale: the task has gone to E-stop and
  // the operator has moved on. Those that would start or enable something
  // are answered "dropped", never carried out late.
  const bool resumed = handler_ran_ns_ != 0 && info.now_ns - handler_ran_ns_ > kStaleCommandGapNs;
  if (resumed) {
    const int64_t gap_ms = (info.now_ns - handler_ran_ns_) / 1'000'000;
    while (const MotionCommand* cmd = commands_.front()) {
      if (results_.size() >= kQueueDepth) break;
      MotionResult r;
      r.serial = cmd->serial;
      r.type = cmd->type;
      if (is_safe_late(cmd->type)) {
        controller_->handle(*cmd, r);
      } else {
        r.accepted = false;
        char text[160];
        std::snprintf(text, sizeof text,
                      "dropped: the servo thread did not run for %lld ms after this command was sent, and nothing "
                      "starts late",
                      static_cast<long long>(gap_ms));
        r.reason.assign(text);
      }
      commands_.pop_front();
      results_.push(r);
    }
  }
  handler_ran_ns_ = info.now_ns;
  // ESTOP_RESET judges the chain as it is now, not as the last cycle read it
  // (the task closes it and asks for the reset within one task cycle).
  controller_->in().estop_chain_closed = !estop_chain_.valid() || estop_chain_.get();
  for (int n = 0; n < 64; ++n) {
    const MotionCommand* cmd = commands_.front();
    if (!cmd) break;
    if (results_.size() >= kQueueDepth) break;  // the task side must read answers first
    MotionResult r;
    if (!controller_->handle(*cmd, r)) break;   // planner full: offer it again next cycle
    commands_.pop_front();
    results_.push(r);
  }
}

void MotionComponent::read_pins() noexcept {
  MotionInputs& in = controller_->in();
  const MotionPins& m = *pins_;
  in.enable = m.enable.get();
  in.probe_input = m.probe_input.get();
  in.feed_hold = m.feed_hold.get();
  in.feed_inhibit = m.feed_inhibit.get();
  in.homing_inhibit = m.homing_inhibit.get();
  in.jog_inhibit = m.jog_inhibit.get();
  in.jog_stop = m.jog_stop.get();
  in.jog_stop_immediate = m.jog_stop_immediate.get();
  in.adaptive_feed = m.adaptive_feed.get();
  if (estop_words_) in.estop_request = estop_words_->request.load(std::memory_order_acquire);
  in.estop_chain_closed = !estop_chain_.valid() || estop_chain_.get();
  for (std::size_t i = 0; i < din_.size(); ++i) in.digital_in[i] = din_[i].get();
  for (std::size_t i = 0; i < ain_.size(); ++i) in.analog_in[i] = ain_[i].get();
  for (std::size_t j = 0; j < joint_pins_.size(); ++j) {
    const JointPins& p = *joint_pins_[j];
    JointInputs& ji = in.joints[j];
    ji.motor_pos_fb = p.motor_pos_fb.get();
    ji.amp_fault = p.amp_fault_in.get();
    ji.amp_ready = p.amp_ready_in.get();
    ji.home_sw = p.home_sw_in.get();
    ji.pos_lim_sw = p.pos_lim_sw_in.get();
    ji.neg_lim_sw = p.neg_lim_sw_in.get();
    ji.index_enable = p.index_enable.get();
    ji.index_position = p.index_position.get();
    ji.probe_position = p.probe_position.get();
    ji.probe_count = p.probe_count.get();
    ji.probe_latch_wired = p.probe_count.linked();
    ji.is_unlocked = p.is_unlocked.get();
    ji.drive_home_busy = p.drive_home_busy.get();
    ji.drive_home_done = p.drive_home_done.get();
    ji.drive_home_error = p.drive_home_error.get();
    ji.jog_counts = p.jog_counts.get();
    ji.jog_enable = p.jog_enable.get();
    ji.jog_scale = p.jog_scale.get();
    ji.jog_vel_mode = p.jog_vel_mode.get();
  }
  for (std::size_t a = 0; a < axis_pins_.size(); ++a) {
    const AxisPins& p = *axis_pins_[a];
    AxisInputs& ai = in.axes[a];
    ai.jog_counts = p.jog_counts.get();
    ai.jog_enable = p.jog_enable.get();
    ai.jog_scale = p.jog_scale.get();
    ai.jog_vel_mode = p.jog_vel_mode.get();
  }
  for (std::size_t s = 0; s < spindle_pins_.size(); ++s) {
    const SpindlePins& p = *spindle_pins_[s];
    SpindleInputs& si = in.spindles[s];
    si.at_speed = p.at_speed.get();
    si.speed_in = p.speed_in.get();
    si.is_oriented = p.is_oriented.get();
    si.orient_fault = p.orient_fault.get();
    si.amp_fault = p.amp_fault_in.get();
  }
}

void MotionComponent::write_pins() noexcept {
  const MotionOutputs& o = controller_->out();
  const MotionPins& m = *pins_;
  m.motion_enabled.set(o.motion_enabled);
  m.in_position.set(o.in_position);
  m.coord_mode.set(o.coord_mode);
  m.teleop_mode.set(o.teleop_mode);
  m.coord_error.set(o.coord_error);
  m.on_soft_limit.set(o.on_soft_limit);
  m.is_all_homed.set(o.is_all_homed);
  m.jog_is_active.set(o.jog_is_active);
  m.watchdog.set(o.watchdog);
  m.watchdog_enabled.set(o.watchdog_enabled);
  m.current_vel.set(o.current_vel);
  m.requested_vel.set(o.requested_vel);
  m.distance_to_go.set(o.distance_to_go);
  m.servo_last_period.set(o.servo_last_period_ns);
  m.program_line.set(o.program_line);
  m.motion_type.set(o.motion_type);
  for (int a = 0; a < kNumAxes; ++a) m.tool_offset[a].set(o.tool_offset[a]);
  for (std::size_t i = 0; i < dout_.size(); ++i) dout_[i].set(o.digital_out[i]);
  for (std::size_t i = 0; i < aout_.size(); ++i) aout_[i].set(o.analog_out[i]);
  for (std::size_t j = 0; j < joint_pins_.size(); ++j) {
    const JointPins& p = *joint_pins_[j];
    const JointOutputs& jo = o.joints[j];
    p.motor_pos_cmd.set(jo.motor_pos_cmd);
    p.pos_cmd.set(jo.pos_cmd);
    p.pos_fb.set(jo.pos_fb);
    p.coarse_pos_cmd.set(jo.coarse_pos_cmd);
    p.vel_cmd.set(jo.vel_cmd);
    p.acc_cmd.set(jo.acc_cmd);
    p.f_error.set(jo.f_error);
    p.f_error_lim.set(jo.f_error_lim);
    p.motor_offset.set(jo.motor_offset);
    p.backlash_corr.set(jo.backlash_corr);
    p.backlash_filt.set(jo.backlash_filt);
    p.backlash_vel.set(jo.backlash_vel);
    p.free_pos_cmd.set(jo.free_pos_cmd);
    p.free_vel_lim.set(jo.free_vel_lim);
    p.amp_enable_out.set(jo.amp_enable);
    if (jo.index_enable_write >= 0) p.index_enable.set(jo.index_enable_write != 0);
    p.active.set(jo.active);
    p.homed.set(jo.homed);
    p.homing.set(jo.homing);
    p.faulted.set(jo.faulted);
    p.f_errored.set(jo.f_errored);
    p.in_position.set(jo.in_position);
    p.free_tp_enable.set(jo.free_tp_enable);
    p.pos_hard_limit.set(jo.pos_hard_limit);
    p.neg_hard_limit.set(jo.neg_hard_limit);
    p.unlock.set(jo.unlock);
    p.drive_home_start.set(jo.drive_home_start);
    p.home_state.set(jo.home_state);
  }
  for (std::size_t a = 0; a < axis_pins_.size(); ++a) {
    const AxisPins& p = *axis_pins_[a];
    const AxisOutputs& ao = o.axes[a];
    p.pos_cmd.set(ao.pos_cmd);
    p.teleop_pos_cmd.set(ao.teleop_pos_cmd);
    p.teleop_vel_cmd.set(ao.teleop_vel_cmd);
    p.teleop_vel_lim.set(ao.teleop_vel_lim);
    p.teleop_tp_enable.set(ao.teleop_tp_enable);
  }
  for (std::size_t s = 0; s < spindle_pins_.size(); ++s) {
    const SpindlePins& p = *spindle_pins_[s];
    const SpindleOutputs& so = o.spindles[s];
    p.speed_out.set(so.speed_out);
    p.speed_out_abs.set(so.speed_out_abs);
    p.speed_out_rps.set(so.speed_out_rps);
    p.speed_cmd_rps.set(so.speed_cmd_rps);
    p.orient_angle.set(so.orient_angle);
    p.on.set(so.on);
    p.forward.set(so.forward);
    p.reverse.set(so.reverse);
    p.brake.set(so.brake);
    p.orient.set(so.orient);
    p.orient_mode.set(so.orient_mode);
  }
}

void MotionComponent::controller(const rt::CycleInfo& info) noexcept {
  if (!controller_) return;
  read_pins();
  MotionInputs& in = controller_->in();
  in.servo_late = info.is_late;
  in.overrun_streak = info.overrun_streak;
  in.missed_cycles = info.missed_cycles;
  // Planners integrate over the nominal period; the measured one is jitter.
  controller_->update(static_cast<double>(info.period_ns) * 1e-9);
  write_pins();
  if (estop_words_) {
    // After the outputs: an acknowledged E-stop has the amplifiers off.
    estop_words_->acknowledged.store(controller_->estop_request_seen(), std::memory_order_release);
    estop_words_->servo_cycles.store(info.cycle, std::memory_order_relaxed);
    estop_words_->servo_heartbeat_ns.store(info.now_ns, std::memory_order_release);
  }
  controller_->fill_status(scratch_status_);
  scratch_status_.servo_exec_ns = 0;
  status_.write(scratch_status_);
}

}  // namespace cnc::motion
