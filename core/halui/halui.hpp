// halui: LinuxCNC's HAL user interface as a component of the controller
// (`loadrt halui`). Its pins live in cncd's HAL like any component's; a
// non-realtime worker thread (never the servo thread) polls them every
// 10 ms, turns edges into operator commands sent on a command channel of
// its own (ipc::Client, the path `cnc` and the screen use) and writes the
// status pins from the shared status block. docs/hal.md lists the pins.
#pragma once

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/hal/component.hpp"
#include "core/ipc/command.hpp"
#include "core/ipc/status.hpp"

namespace cnc::halui {

// One override (feed, rapid, spindle.0): LinuxCNC's pin set.
struct OverridePins {
  hal::BitPin increase, decrease, count_enable, direct_value, reset;
  hal::S32Pin counts;
  hal::FloatPin scale, value;
  bool last_increase = false, last_decrease = false, last_reset = false, primed = false;
  int32_t last_counts = 0;
};

struct AxisPins {
  int index = 0;  // 0 = X .. 8 = W
  hal::BitPin plus, minus, increment_plus, increment_minus, select, is_selected;
  hal::FloatPin increment, analog, pos_commanded, pos_feedback, pos_relative;
  bool last_select = false;
  bool last_plus = false, last_minus = false, last_inc_plus = false, last_inc_minus = false;
  bool analog_jogging = false;
  double analog_sent = 0;
};

// One joint's jog pins (halui.joint.N.*), jogged in joint (free) mode.
struct JointJogPins {
  int index = 0;
  hal::BitPin plus, minus, increment_plus, increment_minus, select, is_selected;
  hal::FloatPin increment, analog;
  bool last_select = false;
  bool last_plus = false, last_minus = false, last_inc_plus = false, last_inc_minus = false;
  bool analog_jogging = false;
  double analog_sent = 0;
};

// The jog pins of the selected axis or joint (halui.axis.selected.*,
// halui.joint.selected.*): no analog pin (LinuxCNC has none there).
// `jogging` is the index a continuous jog was started on, so that a
// release after the selection changed stops that one.
struct SelectedJogPins {
  hal::BitPin plus, minus, increment_plus, increment_minus;
  hal::FloatPin increment, analog;  // analog: never made (invalid)
  bool last_plus = false, last_minus = false, last_inc_plus = false, last_inc_minus = false;
  bool analog_jogging = false;
  double analog_sent = 0;
  int jogging = -1;
};

// One spindle's pins (halui.spindle.N.*), N < [TRAJ]SPINDLES.
struct SpindlePins {
  hal::BitPin start, stop, forward, reverse, increase, decrease, brake_on, brake_off;
  bool last_start = false, last_stop = false, last_forward = false, last_reverse = false;
  bool last_increase = false, last_decrease = false, last_brake_on = false, last_brake_off = false;
  hal::BitPin is_on, runs_forward, runs_backward, brake_is_on;
  OverridePins override_pins;
};

class Halui : public hal::Component {
 public:
  // Sends a command; false when it could not be queued (the reason is
  // posted by the sender).
  using Sender = std::function<bool(const ipc::Command&)>;

  Halui(hal::ComponentContext& ctx, const hal::LoadArgs& args);
  ~Halui() override;

  void on_ready() override;
  void on_shutdown() override;

  // One poll: edges since the previous poll become commands through
  // `send`, status pins are written from `status`. The worker calls it
  // every 10 ms; tests call it directly.
  void poll(const ipc::Status& status, const Sender& send);

  const std::vector<std::string>& mdi_commands() const noexcept { return mdi_commands_; }

 private:
  struct Edge {
    hal::BitPin pin;
    bool last = false;
    // TRUE when the pin rose since the last call.
    bool rose() {
      const bool now = pin.get();
      const bool r = now && !last;
      last = now;
      return r;
    }
  };
  Edge edge(const std::string& name);
  // `with_reset`: LinuxCNC's max-velocity has no reset pin.
  void make_override(OverridePins& o, const std::string& prefix, double default_scale, bool with_reset = true);
  void poll_override(OverridePins& o, double current, double max, const std::function<ipc::Command(double)>& make,
                     const Sender& send);
  void run_worker();
  void post_error(const std::string& text);

  // Commands waiting for the mode halui asked for (MDI after mode MDI, a
  // jog after mode manual): the task takes a command only in its mode, so
  // each is sent once the status shows the mode, or dropped with an error
  // after 2 s.
  struct Deferred {
    ipc::TaskMode mode;
    ipc::Command command;
    int polls_left;
  };
  std::vector<Deferred> deferred_;
  // Commands sent and not yet Done or Rejected: rejections are posted as
  // errors naming the pin's command (the operator sees why nothing moved).
  std::vector<uint32_t> in_flight_;
  MessageQueue* messages_ = nullptr;
  std::vector<std::string> mdi_commands_;
  double default_spindle_speed_ = 100;
  double max_feed_override_ = 2.0, max_spindle_override_ = 2.0;

  Edge machine_on_, machine_off_, estop_activate_, estop_reset_, mode_manual_, mode_auto_, mode_mdi_;
  Edge program_run_, program_pause_, program_resume_, program_step_, program_stop_, home_all_;
  Edge flood_on_, flood_off_, mist_on_, mist_off_, lube_on_, lube_off_, abort_;
  Edge optional_stop_on_, optional_stop_off_, block_delete_on_, block_delete_off_, mode_joint_, mode_teleop_;
  hal::BitPin optional_stop_is_on_, block_delete_is_on_, mode_is_joint_, mode_is_teleop_;
  hal::FloatPin units_per_mm_;
  // Per joint: unhome, and LinuxCNC's joint status pins.
  struct JointStatusPins {
    Edge unhome;
    hal::BitPin has_fault, on_hard_max, on_hard_min, on_soft_max, on_soft_min, override_limits;
  };
  std::vector<JointStatusPins> joint_status_;
  OverridePins max_velocity_;
  std::vector<Edge> joint_home_, mdi_;
  std::vector<hal::BitPin> joint_is_homed_;
  hal::BitPin machine_is_on_, estop_is_activated_, mode_is_manual_, mode_is_auto_, mode_is_mdi_;
  hal::BitPin program_is_idle_, program_is_running_, program_is_paused_;
  hal::BitPin flood_is_on_, mist_is_on_, lube_is_on_;
  hal::U32Pin tool_number_;
  hal::FloatPin tool_diameter_;
  std::array<hal::FloatPin, kNumAxes> tool_length_offset_{};
  hal::FloatPin joint_jog_speed_, joint_jog_deadband_;
  std::vector<JointJogPins> joint_jogs_;
  hal::FloatPin jog_speed_, jog_deadband_;
  OverridePins feed_, rapid_;
  std::vector<SpindlePins> spindles_;
  std::vector<AxisPins> axes_;
  // Selection (LinuxCNC's halui: the last axis/joint whose select pin rose,
  // initially the first) and the selected one's pins.
  std::size_t selected_axis_ = 0, selected_joint_ = 0;
  hal::U32Pin axis_selected_, joint_selected_;
  SelectedJogPins axis_selected_jog_, joint_selected_jog_;
  JointStatusPins joint_selected_status_;
  Edge joint_selected_home_;
  hal::BitPin joint_selected_is_homed_;

  std::thread worker_;
  std::atomic<bool> stop_{false};
};

void register_components(hal::ComponentRegistry& registry);

}  // namespace cnc::halui
