// The task controller's implementation of the canonical machining
// interface: it turns program coordinates and units into machine ones
// (G92, XY rotation, G5x, tool length offset, inch/mm), builds motion
// segments with their feeds, limits and blending tolerance, and appends
// everything to the execution list in program order. Queries answer from
// the machine state the task controller keeps current.
#pragma once

#include <deque>
#include <functional>
#include <vector>

#include "core/interp/canon.hpp"
#include "core/motion/config.hpp"
#include "core/motion/motion_status.hpp"
#include "core/task/item.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::task {

struct MachineView {
  Pose position;        // commanded, machine coordinates
  Pose probed_position; // machine coordinates
  bool probe_tripped = false;
  double input_value = 0;
  const tooltable::ToolTable* tools = nullptr;
  int tool_in_spindle = 0;
  // Path limits in force as motion publishes them (its status), read when a
  // move is built: the cap of every move, and the speed of rapids.
  double max_linear_velocity = 1e99;     // units/s ([TRAJ]'s, else the fastest axis's)
  double max_linear_acceleration = 1e99;  // units/s^2
  double rapid_velocity = 1;              // max_linear_velocity, or the fastest axis without one
};

struct CanonConfig {
  double machine_units_per_mm = 1;     // [TRAJ]LINEAR_UNITS
  uint32_t axis_mask = 0x7;
  bool has_tool_change_position = false;
  Pose tool_change_position;           // [EMCIO]TOOL_CHANGE_POSITION (machine)
  bool tool_change_quill_up = false;   // [EMCIO]TOOL_CHANGE_QUILL_UP
};

// The canon's configuration from the INI file ([TRAJ]LINEAR_UNITS through
// the motion configuration, [EMCIO]TOOL_CHANGE_*). Throws ConfigError.
CanonConfig canon_config(const ini::IniFile& ini, const motion::MotionConfig& m, uint32_t axis_mask);

// The path limits motion has in force (its status), into a canon's view of
// the machine: the cap of every move and the speed of rapids.
void view_limits(const motion::MotionStatus& status, MachineView& view);

class TaskCanon : public interp::Canon {
 public:
  TaskCanon(CanonConfig config, std::deque<Item>& items, const MachineView& machine);

  // Program <-> machine coordinates with the offsets active now.
  Pose to_machine(const Pose& program) const noexcept;
  Pose to_program(const Pose& machine) const noexcept;
  // Where the last queued motion ends (machine), for arcs and status.
  const Pose& end_position() const noexcept { return end_; }
  void set_end_position(const Pose& machine) noexcept { end_ = machine; }
  void reset_state();

  int g5x_index() const noexcept { return g5x_index_; }
  const Pose& g5x_offset() const noexcept { return g5x_; }
  const Pose& g92_offset() const noexcept { return g92_; }
  double rotation() const noexcept { return rotation_deg_; }
  const Pose& tool_offset() const noexcept { return tool_offset_; }
  interp::Units program_units() const noexcept { return units_; }
  double feed_rate_units_min() const noexcept { return feed_rate_; }
  // Spindle speed commanded by the program (rpm), for the status.
  double spindle_speed(int spindle) const noexcept { return spindle_rpm_[static_cast<std::size_t>(spindle)]; }
  uint32_t next_id() const noexcept { return next_id_; }
  void set_id_base(uint32_t id) noexcept { next_id_ = id; }
  // Set when a block produced an error the interpreter cannot see (an arc
  // in a plane the planner does not support); the task aborts on it.
  std::string take_error() { std::string e; e.swap(error_); return e; }

  // --- interp::Canon ---
  void use_length_units(interp::Units u) override;
  void select_plane(interp::Plane p) override { plane_ = p; }
  void set_g5x_offset(int origin, const Pose& offset) override;
  void set_g92_offset(const Pose& offset) override { g92_ = offset; }
  void set_xy_rotation(double degrees) override { rotation_deg_ = degrees; }
  void set_feed_reference(interp::FeedReference) override {}
  void use_tool_length_offset(const Pose& offset) override;
  void set_feed_rate(double rate) override { feed_rate_ = rate; }
  void set_feed_mode(int spindle, interp::FeedMode mode) override;
  void set_motion_control_mode(interp::MotionMode mode, double tolerance) override;
  void set_naivecam_tolerance(double tolerance) override { naive_tolerance_ = tolerance; }
  void straight_traverse(int line, const Pose& end) override;
  void straight_feed(int line, const Pose& end) override;
  void arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis, int rotation,
                double axis_end, const Pose& end) override;
  // Sampled into line segments within a chord tolerance (G64 P, or 1 um).
  void nurbs_feed(int line, int order, const std::vector<ControlPoint>& points, const Pose& end) override;
  void straight_probe(int line, const Pose& end, interp::ProbeKind kind) override;
  void rigid_tap(int line, const Pose& end, double scale) override;
  void start_speed_feed_synch(int spindle, double feed_per_rev, bool velocity_mode) override;
  void stop_speed_feed_synch() override {}
  void dwell(double seconds) override;
  void set_spindle_speed(int spindle, double rpm) override;
  void set_spindle_mode(int spindle, double css_max_rpm) override;
  void start_spindle_clockwise(int spindle) override;
  void start_spindle_counterclockwise(int spindle) override;
  void stop_spindle_turning(int spindle) override;
  void orient_spindle(int spindle, double degrees, int mode) override;
  void wait_spindle_orient_complete(int spindle, double timeout_s) override;
  void flood_on() override { simple(Item::Kind::Flood, 1); }
  void flood_off() override { simple(Item::Kind::Flood, 0); }
  void mist_on() override { simple(Item::Kind::Mist, 1); }
  void mist_off() override { simple(Item::Kind::Mist, 0); }
  void enable_feed_override() override { motion_flag(motion::Cmd::FeedOverrideEnable, 1); }
  void disable_feed_override() override { motion_flag(motion::Cmd::FeedOverrideEnable, 0); }
  void enable_speed_override(int) override {}
  void disable_speed_override(int) override {}
  void enable_adaptive_feed() override { motion_flag(motion::Cmd::AdaptiveFeedEnable, 1); }
  void disable_adaptive_feed() override { motion_flag(motion::Cmd::AdaptiveFeedEnable, 0); }
  void enable_feed_hold() override { motion_flag(motion::Cmd::FeedHoldEnable, 1); }
  void disable_feed_hold() override { motion_flag(motion::Cmd::FeedHoldEnable, 0); }
  void select_tool(int tool_number) override;
  void start_change() override {}
  void change_tool(int index) override;
  void change_tool_number(int index) override;
  void set_tool_table_entry(int index, const interp::ToolData& tool) override;
  void set_motion_output_bit(int index) override { output(index, 1, true, true); }
  void clear_motion_output_bit(int index) override { output(index, 0, true, true); }
  void set_aux_output_bit(int index) override { output(index, 1, true, false); }
  void clear_aux_output_bit(int index) override { output(index, 0, true, false); }
  void set_motion_output_value(int index, double value) override { output(index, value, false, true); }
  void set_aux_output_value(int index, double value) override { output(index, value, false, false); }
  void wait_input(int index, bool digital, interp::WaitType type, double timeout_s) override;
  void comment(std::string_view) override {}
  void message(std::string_view text) override;
  void print(std::string_view text) override;
  void program_stop() override { simple(Item::Kind::ProgramStop, 0); }
  void optional_program_stop() override { simple(Item::Kind::OptionalStop, 0); }
  // No pallet changer: nothing to do, as LinuxCNC's emccanon. M60's pause
  // is the program_stop() the interpreter calls after it; M30 ends the
  // program like M2.
  void pallet_shuttle() override {}
  void program_end() override { simple(Item::Kind::ProgramEnd, 0); }
  void user_m_code(int code, double p, double q) override;

  Pose current_position() const override { return to_program(machine_.position); }
  Pose probe_position() const override { return to_program(machine_.probed_position); }
  bool probe_tripped() const override { return machine_.probe_tripped; }
  double input_value() const override { return machine_.input_value; }
  interp::Units machine_length_units() const override;
  const tooltable::ToolTable& tool_table() const override { return *machine_.tools; }
  int tool_in_spindle() const override { return machine_.tool_in_spindle; }

  // Hook for (PRINT,...) text (the task posts it to the message channel).
  std::function<void(std::string_view)> on_print;

 private:
  double length_factor() const noexcept;  // program length unit -> machine unit
  tp::SegmentParams segment(tp::MotionType type, int line, double length) noexcept;
  void queue_motion(int line, const motion::MotionCommand& c, bool at_rest = false);
  void simple(Item::Kind kind, int i0);
  void motion_flag(motion::Cmd c, double v);
  void output(int index, double value, bool digital, bool with_motion);
  void spindle_command(int spindle);
  double path_length(const Pose& a, const Pose& b) const noexcept;

  CanonConfig cfg_;
  std::deque<Item>& items_;
  const MachineView& machine_;
  interp::Units units_ = interp::Units::Mm;
  interp::Plane plane_ = interp::Plane::XY;
  int g5x_index_ = 1;
  Pose g5x_, g92_, tool_offset_;
  double rotation_deg_ = 0;
  double feed_rate_ = 0;  // program units per minute (G94), or inverse time (G93), or per rev (G95)
  interp::FeedMode feed_mode_ = interp::FeedMode::UnitsPerMinute;
  int feed_spindle_ = 0;  // the spindle G95 feeds per revolution of
  tp::TermCond term_ = tp::TermCond::Blend;
  double tolerance_ = 0, naive_tolerance_ = 0;
  double spindle_rpm_[8] = {};
  int spindle_dir_[8] = {};
  Pose end_;
  uint32_t next_id_ = 1;
  std::string error_;
};

}  // namespace cnc::task
