// Jogging from the screen as a state machine without widgets: jog buttons
// and keys become jog commands, and every rule that keeps jogging safe lives
// here where it is unit-tested: keys do nothing while a text field has the
// focus; every active jog stops on a change of task mode or machine state,
// on a change of increment, on losing the window focus; jogs go to joints
// before homing and to axes after. Never blocks: commands go to a sink.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/ipc/status.hpp"
#include "hmi/config.hpp"

namespace cnc::hmi {

class JogController {
 public:
  using Sink = std::function<void(const ipc::Command&)>;
  enum class Source : uint8_t { Key, Button };

  struct AxisInfo {
    int axis = 0;        // 0..8
    bool angular = false;
    int joint = -1;      // the joint that moves this axis alone, -1: coupled or unknown
  };

  explicit JogController(Sink sink);

  void set_axes(std::vector<AxisInfo> axes);
  void set_increments(std::vector<Increment> linear, std::vector<Increment> angular);
  // Changing the increment stops every jog (the reference's "stop on any
  // increment change").
  void select_increment(int index);
  void select_angular_increment(int index);
  int increment_index() const noexcept { return linear_index_; }
  int angular_increment_index() const noexcept { return angular_index_; }
  const Increment& increment_for(int axis) const;

  // Units (degrees) per second; clamped to the configured range by the caller.
  void set_linear_velocity(double v) noexcept { linear_velocity_ = v; }
  void set_angular_velocity(double v) noexcept { angular_velocity_ = v; }
  double linear_velocity() const noexcept { return linear_velocity_; }
  double angular_velocity() const noexcept { return angular_velocity_; }

  // Each new status: a change of task mode, machine state, interpreter
  // state or homing stops the jogs; the joint/axis choice follows homing.
  void update(const ipc::Status& s);
  void set_connected(bool connected);

  // A jog button or key went down: true when a jog command was sent.
  // `direction` is +1 or -1.
  bool press(int axis, int direction, Source source);
  // Went up: a continuous jog stops; an increment runs to its end.
  void release(int axis, Source source);
  // JogStop for every jog this controller started.
  void stop_all();
  // The window lost the focus (or the application was deactivated).
  void focus_lost() { stop_all(); }
  // A text field (MDI, a number entry) got or lost the keyboard focus.
  void set_text_input_focus(bool focused);
  bool keyboard_enabled() const noexcept { return !text_focus_; }

  // Whether jogging is possible now, and why not.
  bool can_jog() const;
  const std::string& why_not() const noexcept { return why_not_; }
  bool is_jogging(int axis) const;
  bool joint_mode() const noexcept { return !all_homed_; }

 private:
  struct Active {
    int axis;
    int target;
    bool joint_mode;
    bool continuous;
    Source source;
    int updates_seen;  // increments: status updates since the start
  };
  const AxisInfo* info(int axis) const;
  ipc::Command stop_command(const Active& a) const;

  Sink sink_;
  std::vector<AxisInfo> axes_;
  std::vector<Increment> linear_increments_{Increment{true, 0, "continuous"}};
  std::vector<Increment> angular_increments_{Increment{true, 0, "continuous"}};
  int linear_index_ = 0, angular_index_ = 0;
  double linear_velocity_ = 10, angular_velocity_ = 10;
  bool text_focus_ = false;
  bool connected_ = false;
  bool have_status_ = false;
  ipc::TaskState state_ = ipc::TaskState::Estop;
  ipc::TaskMode mode_ = ipc::TaskMode::Manual;
  ipc::InterpState interp_ = ipc::InterpState::Idle;
  bool all_homed_ = false;
  bool motion_at_rest_ = true;
  int joint_of_axis_[kNumAxes];
  std::vector<Active> active_;
  mutable std::string why_not_;
};

}  // namespace cnc::hmi
