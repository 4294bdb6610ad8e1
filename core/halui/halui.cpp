#include "core/halui/halui.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstring>
#include <cmath>
#include <cstdio>

#include "core/ini/ini_file.hpp"
#include "core/ipc/client.hpp"
#include "core/ipc/operator_commands.hpp"
#include "core/util/messages.hpp"

namespace cnc::halui {

namespace cmd = ipc::commands;
using hal::PinDir;

namespace {
constexpr const char* kAxisLetters = "xyzabcuvw";
constexpr auto kPollPeriod = std::chrono::milliseconds(10);

std::string two_digits(std::size_t i) {
  return (i < 10 ? "0" : "") + std::to_string(i);
}
}  // namespace

Halui::Edge Halui::edge(const std::string& name) {
  Edge e;
  e.pin = make_pin<bool>("halui." + name, PinDir::In);
  return e;
}

void Halui::make_override(OverridePins& o, const std::string& p, double default_scale, bool with_reset) {
  o.increase = make_pin<bool>("halui." + p + ".increase", PinDir::In);
  o.decrease = make_pin<bool>("halui." + p + ".decrease", PinDir::In);
  if (with_reset) o.reset = make_pin<bool>("halui." + p + ".reset", PinDir::In);
  o.count_enable = make_pin<bool>("halui." + p + ".count-enable", PinDir::In, true);
  o.direct_value = make_pin<bool>("halui." + p + ".direct-value", PinDir::In);
  o.counts = make_pin<int32_t>("halui." + p + ".counts", PinDir::In);
  o.scale = make_pin<double>("halui." + p + ".scale", PinDir::In, default_scale);
  o.value = make_pin<double>("halui." + p + ".value", PinDir::Out);
}

Halui::Halui(hal::ComponentContext& ctx, const hal::LoadArgs& args) : Component(ctx.hal, "halui"), messages_(ctx.messages) {
  args.allow_only({});
  std::string coordinates = "XYZ";
  int joints = -1;
  int spindles = 1;
  if (ctx.ini) {
    mdi_commands_ = ctx.ini->find_all("HALUI", "MDI_COMMAND");
    coordinates = ctx.ini->get_string("TRAJ", "COORDINATES", "XYZ");
    joints = static_cast<int>(ctx.ini->get_int("KINS", "JOINTS", -1, {1.0, static_cast<double>(kMaxJoints)}));
    default_spindle_speed_ = ctx.ini->get_double("DISPLAY", "DEFAULT_SPINDLE_SPEED", 100.0, {0.0, 1e6});
    max_feed_override_ = ctx.ini->get_double("DISPLAY", "MAX_FEED_OVERRIDE", 2.0, {0.0, 100.0});
    max_spindle_override_ = ctx.ini->get_double("DISPLAY", "MAX_SPINDLE_OVERRIDE", 2.0, {0.0, 100.0});
    spindles = static_cast<int>(ctx.ini->get_int("TRAJ", "SPINDLES", 1, {0.0, static_cast<double>(ipc::kMaxSpindles)}));
  }
  if (mdi_commands_.size() > 64) throw hal::HalError("halui: at most 64 [HALUI]MDI_COMMAND lines");
  for (const auto& line : mdi_commands_) cmd::check_text(line, "[HALUI]MDI_COMMAND");
  machine_on_ = edge("machine.on");
  machine_off_ = edge("machine.off");
  machine_is_on_ = make_pin<bool>("halui.machine.is-on", PinDir::Out);
  estop_activate_ = edge("estop.activate");
  estop_reset_ = edge("estop.reset");
  estop_is_activated_ = make_pin<bool>("halui.estop.is-activated", PinDir::Out, true);
  mode_manual_ = edge("mode.manual");
  mode_auto_ = edge("mode.auto");
  mode_mdi_ = edge("mode.mdi");
  mode_is_manual_ = make_pin<bool>("halui.mode.is-manual", PinDir::Out);
  mode_is_auto_ = make_pin<bool>("halui.mode.is-auto", PinDir::Out);
  mode_is_mdi_ = make_pin<bool>("halui.mode.is-mdi", PinDir::Out);
  program_run_ = edge("program.run");
  program_pause_ = edge("program.pause");
  program_resume_ = edge("program.resume");
  program_step_ = edge("program.step");
  program_stop_ = edge("program.stop");
  program_is_idle_ = make_pin<bool>("halui.program.is-idle", PinDir::Out);
  program_is_running_ = make_pin<bool>("halui.program.is-running", PinDir::Out);
  program_is_paused_ = make_pin<bool>("halui.program.is-paused", PinDir::Out);
  home_all_ = edge("home-all");
  // Spindles 0 .. [TRAJ]SPINDLES-1, as LinuxCNC's halui.
  for (int n = 0; n < spindles; ++n) {
    const std::string p = "halui.spindle." + std::to_string(n);
    SpindlePins sp;
    sp.start = make_pin<bool>(p + ".start", PinDir::In);
    sp.stop = make_pin<bool>(p + ".stop", PinDir::In);
    sp.forward = make_pin<bool>(p + ".forward", PinDir::In);
    sp.reverse = make_pin<bool>(p + ".reverse", PinDir::In);
    sp.increase = make_pin<bool>(p + ".increase", PinDir::In);
    sp.decrease = make_pin<bool>(p + ".decrease", PinDir::In);
    sp.brake_on = make_pin<bool>(p + ".brake-on", PinDir::In);
    sp.brake_off = make_pin<bool>(p + ".brake-off", PinDir::In);
    sp.is_on = make_pin<bool>(p + ".is-on", PinDir::Out);
    sp.runs_forward = make_pin<bool>(p + ".runs-forward", PinDir::Out);
    sp.runs_backward = make_pin<bool>(p + ".runs-backward", PinDir::Out);
    sp.brake_is_on = make_pin<bool>(p + ".brake-is-on", PinDir::Out);
    make_override(sp.override_pins, "spindle." + std::to_string(n) + ".override", 0.1);
    spindles_.push_back(sp);
  }
  flood_on_ = edge("flood.on");
  flood_off_ = edge("flood.off");
  flood_is_on_ = make_pin<bool>("halui.flood.is-on", PinDir::Out);
  mist_on_ = edge("mist.on");
  mist_off_ = edge("mist.off");
  mist_is_on_ = make_pin<bool>("halui.mist.is-on", PinDir::Out);
  lube_on_ = edge("lube.on");
  lube_off_ = edge("lube.off");
  lube_is_on_ = make_pin<bool>("halui.lube.is-on", PinDir::Out);
  abort_ = edge("abort");
  optional_stop_on_ = edge("program.optional-stop.on");
  optional_stop_off_ = edge("program.optional-stop.off");
  optional_stop_is_on_ = make_pin<bool>("halui.program.optional-stop.is-on", PinDir::Out);
  block_delete_on_ = edge("program.block-delete.on");
  block_delete_off_ = edge("program.block-delete.off");
  block_delete_is_on_ = make_pin<bool>("halui.program.block-delete.is-on", PinDir::Out);
  mode_joint_ = edge("mode.joint");
  mode_teleop_ = edge("mode.teleop");
  mode_is_joint_ = make_pin<bool>("halui.mode.is-joint", PinDir::Out);
  mode_is_teleop_ = make_pin<bool>("halui.mode.is-teleop", PinDir::Out);
  units_per_mm_ = make_pin<double>("halui.machine.units-per-mm", PinDir::Out);
  make_override(max_velocity_, "max-velocity", 0.1, false);
  tool_number_ = make_pin<uint32_t>("halui.tool.number", PinDir::Out);
  tool_diameter_ = make_pin<double>("halui.tool.diameter", PinDir::Out);
  for (int i = 0; i < kNumAxes; ++i) {
    tool_length_offset_[static_cast<std::size_t>(i)] =
        make_pin<double>(std::string("halui.tool.length-offset.") + kAxisLetters[i], PinDir::Out);
  }
  make_override(feed_, "feed-override", 0.1);
  make_override(rapid_, "rapid-override", 0.1);
  jog_speed_ = make_pin<double>("halui.axis.jog-speed", PinDir::In);
  jog_deadband_ = make_pin<double>("halui.axis.jog-deadband", PinDir::In, 0.2);
  // Axes by letter from [TRAJ]COORDINATES, once each.
  std::string seen;
  for (char c : coordinates) {
    const char l = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const char* at = std::strchr(kAxisLetters, l);
    if (l == ' ' || l == '\t' || !at || l == '\0' || seen.find(l) != std::string::npos) continue;
    seen += l;
    AxisPins a;
    a.index = static_cast<int>(at - kAxisLetters);
    const std::string p = std::string("halui.axis.") + l;
    a.plus = make_pin<bool>(p + ".plus", PinDir::In);
    a.minus = make_pin<bool>(p + ".minus", PinDir::In);
    a.increment_plus = make_pin<bool>(p + ".increment-plus", PinDir::In);
    a.increment_minus = make_pin<bool>(p + ".increment-minus", PinDir::In);
    a.increment = make_pin<double>(p + ".increment", PinDir::In);
    a.analog = make_pin<double>(p + ".analog", PinDir::In);
    a.pos_commanded = make_pin<double>(p + ".pos-commanded", PinDir::Out);
    a.pos_feedback = make_pin<double>(p + ".pos-feedback", PinDir::Out);
    a.pos_relative = make_pin<double>(p + ".pos-relative", PinDir::Out);
    a.select = make_pin<bool>(p + ".select", PinDir::In);
    a.is_selected = make_pin<bool>(p + ".is-selected", PinDir::Out);
    axes_.push_back(a);
  }
  const auto make_selected_jog = [this](SelectedJogPins& j, const std::string& p) {
    j.plus = make_pin<bool>(p + ".plus", PinDir::In);
    j.minus = make_pin<bool>(p + ".minus", PinDir::In);
    j.increment_plus = make_pin<bool>(p + ".increment-plus", PinDir::In);
    j.increment_minus = make_pin<bool>(p + ".increment-minus", PinDir::In);
    j.increment = make_pin<double>(p + ".increment", PinDir::In);
  };
  axis_selected_ = make_pin<uint32_t>("halui.axis.selected", PinDir::Out);
  make_selected_jog(axis_selected_jog_, "halui.axis.selected");
  if (joints < 0) joints = static_cast<int>(axes_.size());
  joint_jog_speed_ = make_pin<double>("halui.joint.jog-speed", PinDir::In);
  joint_jog_deadband_ = make_pin<double>("halui.joint.jog-deadband", PinDir::In, 0.2);
  for (int j = 0; j < joints; ++j) {
    const std::string p = "halui.joint." + std::to_string(j);
    joint_home_.push_back(edge("joint." + std::to_string(j) + ".home"));
    joint_is_homed_.push_back(make_pin<bool>(p + ".is-homed", PinDir::Out));
    JointJogPins jj;
    jj.index = j;
    jj.plus = make_pin<bool>(p + ".plus", PinDir::In);
    jj.minus = make_pin<bool>(p + ".minus", PinDir::In);
    jj.increment_plus = make_pin<bool>(p + ".increment-plus", PinDir::In);
    jj.increment_minus = make_pin<bool>(p + ".increment-minus", PinDir::In);
    jj.increment = make_pin<double>(p + ".increment", PinDir::In);
    jj.analog = make_pin<double>(p + ".analog", PinDir::In);
    jj.select = make_pin<bool>(p + ".select", PinDir::In);
    jj.is_selected = make_pin<bool>(p + ".is-selected", PinDir::Out);
    joint_jogs_.push_back(jj);
    JointStatusPins js;
    js.unhome = edge("joint." + std::to_string(j) + ".unhome");
    js.has_fault = make_pin<bool>(p + ".has-fault", PinDir::Out);
    js.on_hard_max = make_pin<bool>(p + ".on-hard-max-limit", PinDir::Out);
    js.on_hard_min = make_pin<bool>(p + ".on-hard-min-limit", PinDir::Out);
    js.on_soft_max = make_pin<bool>(p + ".on-soft-max-limit", PinDir::Out);
    js.on_soft_min = make_pin<bool>(p + ".on-soft-min-limit", PinDir::Out);
    js.override_limits = make_pin<bool>(p + ".override-limits", PinDir::Out);
    joint_status_.push_back(js);
  }
  joint_selected_ = make_pin<uint32_t>("halui.joint.selected", PinDir::Out);
  make_selected_jog(joint_selected_jog_, "halui.joint.selected");
  {
    const std::string p = "halui.joint.selected";
    joint_selected_home_ = edge("joint.selected.home");
    joint_selected_status_.unhome = edge("joint.selected.unhome");
    joint_selected_is_homed_ = make_pin<bool>(p + ".is-homed", PinDir::Out);
    joint_selected_status_.has_fault = make_pin<bool>(p + ".has-fault", PinDir::Out);
    joint_selected_status_.on_hard_max = make_pin<bool>(p + ".on-hard-max-limit", PinDir::Out);
    joint_selected_status_.on_hard_min = make_pin<bool>(p + ".on-hard-min-limit", PinDir::Out);
    joint_selected_status_.on_soft_max = make_pin<bool>(p + ".on-soft-max-limit", PinDir::Out);
    joint_selected_status_.on_soft_min = make_pin<bool>(p + ".on-soft-min-limit", PinDir::Out);
    joint_selected_status_.override_limits = make_pin<bool>(p + ".override-limits", PinDir::Out);
  }
  for (std::size_t i = 0; i < mdi_commands_.size(); ++i) mdi_.push_back(edge("mdi-command-" + two_digits(i)));
}

Halui::~Halui() { on_shutdown(); }

void Halui::on_ready() {
  if (worker_.joinable()) return;
  worker_ = std::thread([this] { run_worker(); });
}

void Halui::on_shutdown() {
  stop_ = true;
  if (worker_.joinable()) worker_.join();
}

void Halui::post_error(const std::string& text) {
  if (messages_) messages_->post(MessageKind::Error, "halui", text);
  else std::fprintf(stderr, "halui: %s\n", text.c_str());
}

// Connects (once the controller's threads run: `cncd --check` never
// starts them, so a check never touches a live instance) and polls.
void Halui::run_worker() {
  std::unique_ptr<ipc::Client> client;
  while (!stop_) {
    std::this_thread::sleep_for(kPollPeriod);
    if (!client) {
      if (!hal().threads_running()) continue;
      try {
        auto c = std::make_unique<ipc::Client>();
        if (!c->controller_ready()) continue;
        client = std::move(c);
      } catch (const ipc::ClientError&) {
        continue;  // the segment is published after the threads start
      }
    }
    try {
      const ipc::Status s = client->status();
      poll(s, [&](const ipc::Command& c) {
        uint32_t serial = 0;
        if (client->try_send(c, serial)) {
          in_flight_.push_back(serial);
          return true;
        }
        post_error("command queue full: a panel command was dropped");
        return false;
      });
      for (std::size_t i = 0; i < in_flight_.size();) {
        const ipc::CommandResult r = client->wait(in_flight_[i], std::chrono::milliseconds(0));
        if (r.state == ipc::CommandState::Rejected) {
          post_error(std::string(ipc::to_string(r.type)) + " rejected: " + std::string(r.reason.view()));
        }
        if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected || in_flight_.size() > 64) {
          in_flight_.erase(in_flight_.begin() + static_cast<std::ptrdiff_t>(i));
        } else {
          ++i;
        }
      }
    } catch (const std::exception& e) {
      post_error(e.what());
      client.reset();
    }
  }
}

void Halui::poll_override(OverridePins& o, double current, double max,
                          const std::function<ipc::Command(double)>& make, const Sender& send) {
  o.value.set(current);
  const double scale = o.scale.get();
  const int32_t counts = o.counts.get();
  const bool inc = o.increase.get(), dec = o.decrease.get(), rst = o.reset.valid() && o.reset.get();
  double target = std::nan("");
  if (!o.primed) {
    // The first poll takes the inputs as they are: no jump at start.
    o.primed = true;
  } else if (o.direct_value.get()) {
    if (counts != o.last_counts) target = counts * scale;
  } else if (o.count_enable.get() && counts != o.last_counts) {
    target = current + static_cast<double>(counts - o.last_counts) * scale;
  }
  if (inc && !o.last_increase) target = (std::isnan(target) ? current : target) + scale;
  if (dec && !o.last_decrease) target = (std::isnan(target) ? current : target) - scale;
  if (rst && !o.last_reset) target = 1.0;
  o.last_counts = counts;
  o.last_increase = inc;
  o.last_decrease = dec;
  o.last_reset = rst;
  if (!std::isnan(target)) send(make(std::clamp(target, 0.0, max)));
}

// Continuous, incremental and analog jog pins of one axis or joint.
template <typename Pins, typename InMode>
void poll_jog(Pins& a, int index, bool joint, double speed, double deadband, InMode& in_mode,
              const Halui::Sender& send) {
  const bool plus = a.plus.get(), minus = a.minus.get();
  const bool ip = a.increment_plus.get(), im = a.increment_minus.get();
  if ((plus && !a.last_plus) || (minus && !a.last_minus)) {
    in_mode(ipc::TaskMode::Manual, cmd::jog_continuous(index, joint, plus ? speed : -speed));
  } else if ((!plus && a.last_plus) || (!minus && a.last_minus)) {
    send(cmd::jog_stop(index, joint));
  }
  if ((ip && !a.last_inc_plus) || (im && !a.last_inc_minus)) {
    const double inc = std::fabs(a.increment.get());
    in_mode(ipc::TaskMode::Manual, cmd::jog_increment(index, joint, speed, ip ? inc : -inc));
  }
  a.last_plus = plus;
  a.last_minus = minus;
  a.last_inc_plus = ip;
  a.last_inc_minus = im;
  // Analog (a joystick, -1..1): a jog at analog x jog-speed outside the
  // deadband, re-sent when it changes by more than 5 % of full speed.
  const double v = a.analog.valid() ? a.analog.get() : 0.0;
  if (std::fabs(v) > deadband) {
    const double vel = std::clamp(v, -1.0, 1.0) * speed;
    if (!a.analog_jogging || std::fabs(vel - a.analog_sent) > 0.05 * speed) {
      in_mode(ipc::TaskMode::Manual, cmd::jog_continuous(index, joint, vel));
      a.analog_jogging = true;
      a.analog_sent = vel;
    }
  } else if (a.analog_jogging) {
    send(cmd::jog_stop(index, joint));
    a.analog_jogging = false;
  }
}

void Halui::poll(const ipc::Status& s, const Sender& send) {
  const ipc::TaskStatus& t = s.task;
  // Status pins.
  machine_is_on_.set(t.state == ipc::TaskState::On);
  estop_is_activated_.set(t.state == ipc::TaskState::Estop);
  mode_is_manual_.set(t.mode == ipc::TaskMode::Manual);
  mode_is_auto_.set(t.mode == ipc::TaskMode::Auto);
  mode_is_mdi_.set(t.mode == ipc::TaskMode::Mdi);
  program_is_idle_.set(t.interp_state == ipc::InterpState::Idle);
  program_is_paused_.set(t.mode == ipc::TaskMode::Auto && t.paused);
  program_is_running_.set(t.mode == ipc::TaskMode::Auto && t.interp_state != ipc::InterpState::Idle && !t.paused);
  for (std::size_t n = 0; n < spindles_.size(); ++n) {
    const ipc::SpindleStatus& sp = s.spindles[n];
    spindles_[n].is_on.set(sp.enabled);
    spindles_[n].runs_forward.set(sp.enabled && sp.direction > 0);
    spindles_[n].runs_backward.set(sp.enabled && sp.direction < 0);
    spindles_[n].brake_is_on.set(sp.brake);
  }
  flood_is_on_.set(s.io.flood);
  mist_is_on_.set(s.io.mist);
  lube_is_on_.set(s.io.lube);
  tool_number_.set(static_cast<uint32_t>(std::max(0, s.io.tool_in_spindle)));
  tool_diameter_.set(s.io.tool_diameter);
  for (int i = 0; i < kNumAxes; ++i) tool_length_offset_[static_cast<std::size_t>(i)].set(t.tool_offset[i]);
  optional_stop_is_on_.set(t.optional_stop);
  block_delete_is_on_.set(t.block_delete);
  mode_is_teleop_.set(s.motion.teleop_enabled);
  mode_is_joint_.set(!s.motion.teleop_enabled);
  units_per_mm_.set(s.motion.linear_units);
  for (std::size_t j = 0; j < joint_status_.size(); ++j) {
    const ipc::JointStatus& js = s.joints[j];
    JointStatusPins& p = joint_status_[j];
    p.has_fault.set(js.fault);
    p.on_hard_max.set(js.max_hard_limit);
    p.on_hard_min.set(js.min_hard_limit);
    p.on_soft_max.set(js.max_soft_limit);
    p.on_soft_min.set(js.min_soft_limit);
    p.override_limits.set(js.override_limits);
  }
  for (std::size_t j = 0; j < joint_is_homed_.size(); ++j) joint_is_homed_[j].set(s.joints[j].homed);
  for (auto& a : axes_) {
    a.pos_commanded.set(s.motion.position[a.index]);
    a.pos_feedback.set(s.motion.actual_position[a.index]);
    // As LinuxCNC's halui: commanded, less the G5x, G92 and tool offsets
    // (no XY rotation).
    a.pos_relative.set(s.motion.position[a.index] - t.g5x_offset[a.index] - t.g92_offset[a.index] -
                       t.tool_offset[a.index]);
  }
  // Selection: the last select pin that rose.
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const bool sel = axes_[i].select.get();
    if (sel && !axes_[i].last_select) selected_axis_ = i;
    axes_[i].last_select = sel;
  }
  for (std::size_t j = 0; j < joint_jogs_.size(); ++j) {
    const bool sel = joint_jogs_[j].select.get();
    if (sel && !joint_jogs_[j].last_select) selected_joint_ = j;
    joint_jogs_[j].last_select = sel;
  }
  for (std::size_t i = 0; i < axes_.size(); ++i) axes_[i].is_selected.set(i == selected_axis_);
  for (std::size_t j = 0; j < joint_jogs_.size(); ++j) joint_jogs_[j].is_selected.set(j == selected_joint_);
  if (!axes_.empty()) axis_selected_.set(static_cast<uint32_t>(axes_[selected_axis_].index));
  joint_selected_.set(static_cast<uint32_t>(selected_joint_));
  if (selected_joint_ < joint_status_.size()) {
    const ipc::JointStatus& js = s.joints[selected_joint_];
    joint_selected_is_homed_.set(js.homed);
    joint_selected_status_.has_fault.set(js.fault);
    joint_selected_status_.on_hard_max.set(js.max_hard_limit);
    joint_selected_status_.on_hard_min.set(js.min_hard_limit);
    joint_selected_status_.on_soft_max.set(js.max_soft_limit);
    joint_selected_status_.on_soft_min.set(js.min_soft_limit);
    joint_selected_status_.override_limits.set(js.override_limits);
  }

  // Commands waiting for a mode change halui asked for.
  for (std::size_t i = 0; i < deferred_.size();) {
    Deferred& d = deferred_[i];
    if (t.mode == d.mode) {
      send(d.command);
    } else if (--d.polls_left > 0) {
      ++i;
      continue;
    } else {
      post_error(std::string(ipc::to_string(d.command.type)) + " dropped: the mode did not change to " +
                 ipc::to_string(d.mode));
    }
    deferred_.erase(deferred_.begin() + static_cast<std::ptrdiff_t>(i));
  }
  // Commands, in the order a panel means them. `in_mode` sends a command
  // now when the task is in mode m, else asks for m and sends it after.
  auto in_mode = [&](ipc::TaskMode m, const ipc::Command& c) {
    if (t.mode == m && deferred_.empty()) {
      send(c);
      return;
    }
    if (t.mode != m && (deferred_.empty() || deferred_.back().mode != m)) send(cmd::set_mode(m));
    deferred_.push_back(Deferred{m, c, 200});
  };
  if (estop_activate_.rose()) send(cmd::set_state(ipc::TaskState::Estop));
  if (estop_reset_.rose()) send(cmd::set_state(ipc::TaskState::EstopReset));
  if (machine_off_.rose()) send(cmd::set_state(ipc::TaskState::Off));
  if (machine_on_.rose()) send(cmd::set_state(ipc::TaskState::On));
  if (mode_manual_.rose()) send(cmd::set_mode(ipc::TaskMode::Manual));
  if (mode_auto_.rose()) send(cmd::set_mode(ipc::TaskMode::Auto));
  if (mode_mdi_.rose()) send(cmd::set_mode(ipc::TaskMode::Mdi));
  if (program_stop_.rose()) send(cmd::abort());
  if (abort_.rose()) send(cmd::abort());
  if (optional_stop_on_.rose()) send(cmd::optional_stop(true));
  if (optional_stop_off_.rose()) send(cmd::optional_stop(false));
  if (block_delete_on_.rose()) send(cmd::block_delete(true));
  if (block_delete_off_.rose()) send(cmd::block_delete(false));
  if (mode_joint_.rose()) send(cmd::teleop_enable(false));
  if (mode_teleop_.rose()) send(cmd::teleop_enable(true));
  if (program_pause_.rose()) send(cmd::pause());
  if (program_resume_.rose()) send(cmd::resume());
  if (program_step_.rose()) in_mode(ipc::TaskMode::Auto, cmd::step());
  if (program_run_.rose()) in_mode(ipc::TaskMode::Auto, cmd::run(0));
  if (home_all_.rose()) in_mode(ipc::TaskMode::Manual, cmd::home(-1));
  for (std::size_t j = 0; j < joint_home_.size(); ++j) {
    if (joint_home_[j].rose()) in_mode(ipc::TaskMode::Manual, cmd::home(static_cast<int>(j)));
    if (joint_status_[j].unhome.rose()) in_mode(ipc::TaskMode::Manual, cmd::unhome(static_cast<int>(j)));
  }
  const int sj = static_cast<int>(selected_joint_);
  if (joint_selected_home_.rose() && !joint_home_.empty()) in_mode(ipc::TaskMode::Manual, cmd::home(sj));
  if (joint_selected_status_.unhome.rose() && !joint_home_.empty()) in_mode(ipc::TaskMode::Manual, cmd::unhome(sj));
  const auto rose = [](hal::BitPin& pin, bool& last) {
    const bool now = pin.get();
    const bool r = now && !last;
    last = now;
    return r;
  };
  for (std::size_t n = 0; n < spindles_.size(); ++n) {
    SpindlePins& p = spindles_[n];
    const int k = static_cast<int>(n);
    const ipc::SpindleStatus& sp = s.spindles[n];
    const double rpm = sp.speed != 0 ? std::fabs(sp.speed) : default_spindle_speed_;
    if (rose(p.stop, p.last_stop)) send(cmd::spindle_off(k));
    if (rose(p.forward, p.last_forward)) send(cmd::spindle_on(rpm, k));
    if (rose(p.reverse, p.last_reverse)) send(cmd::spindle_on(-rpm, k));
    if (rose(p.start, p.last_start)) send(cmd::spindle_on(sp.direction < 0 ? -rpm : rpm, k));
    if (rose(p.increase, p.last_increase)) send(cmd::spindle_faster(k));
    if (rose(p.decrease, p.last_decrease)) send(cmd::spindle_slower(k));
    if (rose(p.brake_on, p.last_brake_on)) send(cmd::spindle_brake(true, k));
    if (rose(p.brake_off, p.last_brake_off)) send(cmd::spindle_brake(false, k));
  }
  if (flood_on_.rose()) send(cmd::flood(true));
  if (flood_off_.rose()) send(cmd::flood(false));
  if (mist_on_.rose()) send(cmd::mist(true));
  if (mist_off_.rose()) send(cmd::mist(false));
  if (lube_on_.rose()) send(cmd::lube(true));
  if (lube_off_.rose()) send(cmd::lube(false));
  for (std::size_t i = 0; i < mdi_.size(); ++i) {
    if (mdi_[i].rose()) in_mode(ipc::TaskMode::Mdi, cmd::mdi(mdi_commands_[i]));
  }

  // Jogs: jog-speed is in units per minute (LinuxCNC's), commands take
  // units per second. Axes jog in world (teleop) mode, joints in joint
  // (free) mode; the controller refuses what the machine's state does not
  // allow (an axis jog before homing on a non-trivial machine) and the
  // rejection is posted.
  const double speed = std::fabs(jog_speed_.get()) / 60.0;
  for (auto& a : axes_) poll_jog(a, a.index, false, speed, std::fabs(jog_deadband_.get()), in_mode, send);
  const double joint_speed = std::fabs(joint_jog_speed_.get()) / 60.0;
  for (auto& j : joint_jogs_) poll_jog(j, j.index, true, joint_speed, std::fabs(joint_jog_deadband_.get()), in_mode, send);
  // The selected axis and joint: a selection changed while one jogs stops
  // that one (the newly selected one jogs at the next press).
  const auto poll_selected = [&](SelectedJogPins& p, int index, bool joint, double v, double deadband) {
    if (p.jogging >= 0 && p.jogging != index && (p.last_plus || p.last_minus)) send(cmd::jog_stop(p.jogging, joint));
    poll_jog(p, index, joint, v, deadband, in_mode, send);
    p.jogging = p.last_plus || p.last_minus ? index : -1;
  };
  if (!axes_.empty()) {
    poll_selected(axis_selected_jog_, axes_[selected_axis_].index, false, speed, std::fabs(jog_deadband_.get()));
  }
  if (!joint_jogs_.empty()) {
    poll_selected(joint_selected_jog_, static_cast<int>(selected_joint_), true, joint_speed,
                  std::fabs(joint_jog_deadband_.get()));
  }

  poll_override(feed_, s.motion.feed_scale, max_feed_override_, [](double v) { return cmd::feed_override(v); }, send);
  poll_override(rapid_, s.motion.rapid_scale, 1.0, [](double v) { return cmd::rapid_override(v); }, send);
  // Max velocity in machine units per second (the controller limits it to
  // the machine's).
  poll_override(max_velocity_, s.motion.max_velocity, 1e9, [](double v) { return cmd::max_velocity(v); }, send);
  for (std::size_t n = 0; n < spindles_.size(); ++n) {
    const int k = static_cast<int>(n);
    poll_override(spindles_[n].override_pins, s.spindles[n].override_scale, max_spindle_override_,
                  [k](double v) { return cmd::spindle_override(v, k); }, send);
  }
}

void register_components(hal::ComponentRegistry& r) {
  r.add("halui",
        "halui: LinuxCNC's HAL user interface pins (machine, E-stop, modes, program, overrides, jog, home, "
        "[HALUI]MDI_COMMAND); a non-realtime thread sends their commands",
        [](hal::ComponentContext& ctx, const hal::LoadArgs& args) -> std::unique_ptr<hal::Component> {
          return std::make_unique<Halui>(ctx, args);
        });
}

}  // namespace cnc::halui
