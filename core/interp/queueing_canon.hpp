// Internal: the Canon the interpreter talks to while cutter compensation
// holds a move back. Like LinuxCNC's canon queue, feed/spindle/coolant/
// dwell/comment/tool-change-start calls made meanwhile wait behind the held
// move; every other call goes straight through. Generated from canon.hpp;
// the calls that are machine output also count themselves (outputs()).
#pragma once

#include <deque>
#include <functional>
#include <string>

#include "core/interp/canon.hpp"
#include "core/interp/state.hpp"

namespace cnc::interp {

struct QueuedCall {
  bool is_move = false;
  CompMove move;
  std::function<void()> call;
};

class QueueingCanon final : public Canon {
 public:
  explicit QueueingCanon(Canon& real) : real_(real) {}
  std::deque<QueuedCall>& queue() noexcept { return queue_; }
  Canon& real() noexcept { return real_; }
  bool holding() const noexcept { return !queue_.empty(); }
  // Calls so far that make the machine do something (motion, dwell,
  // spindle, coolant, tools, outputs, input waits, stops, user M codes),
  // counted when the interpreter makes them, held back or not. Settings,
  // offsets, comments and messages are not machine output. The interpreter
  // bounds the lines it reads between two of these
  // (Config::max_blocks_without_output).
  uint64_t outputs() const noexcept { return outputs_; }
  // For moves cutter compensation holds back or emits to real() directly.
  void count_output() noexcept { ++outputs_; }

  void begin_block(int a0, int a1, std::string_view a2) override { real_.begin_block(a0, a1, a2); }
  void use_length_units(Units u) override { real_.use_length_units(u); }
  void select_plane(Plane p) override { real_.select_plane(p); }
  void set_g5x_offset(int origin, const Pose& offset) override { real_.set_g5x_offset(origin, offset); }
  void set_g92_offset(const Pose& offset) override { real_.set_g92_offset(offset); }
  void set_xy_rotation(double degrees) override { real_.set_xy_rotation(degrees); }
  void set_feed_reference(FeedReference r) override { real_.set_feed_reference(r); }
  void use_tool_length_offset(const Pose& offset) override { real_.use_tool_length_offset(offset); }
  void set_feed_rate(double rate) override {
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, rate] { real_.set_feed_rate(rate); }});
      return;
    }
    real_.set_feed_rate(rate);
  }
  void set_feed_mode(int spindle, FeedMode mode) override {
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle, mode] { real_.set_feed_mode(spindle, mode); }});
      return;
    }
    real_.set_feed_mode(spindle, mode);
  }
  void set_motion_control_mode(MotionMode mode, double tolerance) override { real_.set_motion_control_mode(mode, tolerance); }
  void set_naivecam_tolerance(double tolerance) override { real_.set_naivecam_tolerance(tolerance); }
  void straight_traverse(int line, const Pose& end) override { ++outputs_; real_.straight_traverse(line, end); }
  void straight_feed(int line, const Pose& end) override { ++outputs_; real_.straight_feed(line, end); }
  void arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis, int rotation, double axis_end, const Pose& end) override { ++outputs_; real_.arc_feed(line, first_end, second_end, first_axis, second_axis, rotation, axis_end, end); }
  void nurbs_feed(int line, int order, const std::vector<ControlPoint>& points, const Pose& end) override { ++outputs_; real_.nurbs_feed(line, order, points, end); }
  void straight_probe(int line, const Pose& end, ProbeKind kind) override { ++outputs_; real_.straight_probe(line, end, kind); }
  void turn_probe_on() override { real_.turn_probe_on(); }
  void turn_probe_off() override { real_.turn_probe_off(); }
  void rigid_tap(int line, const Pose& end, double scale) override { ++outputs_; real_.rigid_tap(line, end, scale); }
  void start_speed_feed_synch(int spindle, double feed_per_rev, bool velocity_mode) override { real_.start_speed_feed_synch(spindle, feed_per_rev, velocity_mode); }
  void stop_speed_feed_synch() override { real_.stop_speed_feed_synch(); }
  void dwell(double seconds) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, seconds] { real_.dwell(seconds); }});
      return;
    }
    real_.dwell(seconds);
  }
  void set_spindle_speed(int spindle, double rpm) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle, rpm] { real_.set_spindle_speed(spindle, rpm); }});
      return;
    }
    real_.set_spindle_speed(spindle, rpm);
  }
  void set_spindle_mode(int spindle, double css_max_rpm) override {
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle, css_max_rpm] { real_.set_spindle_mode(spindle, css_max_rpm); }});
      return;
    }
    real_.set_spindle_mode(spindle, css_max_rpm);
  }
  void start_spindle_clockwise(int spindle) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle] { real_.start_spindle_clockwise(spindle); }});
      return;
    }
    real_.start_spindle_clockwise(spindle);
  }
  void start_spindle_counterclockwise(int spindle) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle] { real_.start_spindle_counterclockwise(spindle); }});
      return;
    }
    real_.start_spindle_counterclockwise(spindle);
  }
  void stop_spindle_turning(int spindle) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle] { real_.stop_spindle_turning(spindle); }});
      return;
    }
    real_.stop_spindle_turning(spindle);
  }
  void orient_spindle(int spindle, double degrees, int mode) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle, degrees, mode] { real_.orient_spindle(spindle, degrees, mode); }});
      return;
    }
    real_.orient_spindle(spindle, degrees, mode);
  }
  void wait_spindle_orient_complete(int spindle, double timeout_s) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, spindle, timeout_s] { real_.wait_spindle_orient_complete(spindle, timeout_s); }});
      return;
    }
    real_.wait_spindle_orient_complete(spindle, timeout_s);
  }
  void flood_on() override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this] { real_.flood_on(); }});
      return;
    }
    real_.flood_on();
  }
  void flood_off() override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this] { real_.flood_off(); }});
      return;
    }
    real_.flood_off();
  }
  void mist_on() override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this] { real_.mist_on(); }});
      return;
    }
    real_.mist_on();
  }
  void mist_off() override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this] { real_.mist_off(); }});
      return;
    }
    real_.mist_off();
  }
  void enable_feed_override() override { real_.enable_feed_override(); }
  void disable_feed_override() override { real_.disable_feed_override(); }
  void enable_speed_override(int spindle) override { real_.enable_speed_override(spindle); }
  void disable_speed_override(int spindle) override { real_.disable_speed_override(spindle); }
  void enable_adaptive_feed() override { real_.enable_adaptive_feed(); }
  void disable_adaptive_feed() override { real_.disable_adaptive_feed(); }
  void enable_feed_hold() override { real_.enable_feed_hold(); }
  void disable_feed_hold() override { real_.disable_feed_hold(); }
  void select_tool(int tool_number) override { ++outputs_; real_.select_tool(tool_number); }
  void start_change() override {
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this] { real_.start_change(); }});
      return;
    }
    real_.start_change();
  }
  void change_tool(int index) override { ++outputs_; real_.change_tool(index); }
  void change_tool_number(int index) override { ++outputs_; real_.change_tool_number(index); }
  void set_tool_table_entry(int index, const ToolData& tool) override { ++outputs_; real_.set_tool_table_entry(index, tool); }
  void set_motion_output_bit(int index) override { ++outputs_; real_.set_motion_output_bit(index); }
  void clear_motion_output_bit(int index) override { ++outputs_; real_.clear_motion_output_bit(index); }
  void set_aux_output_bit(int index) override { ++outputs_; real_.set_aux_output_bit(index); }
  void clear_aux_output_bit(int index) override { ++outputs_; real_.clear_aux_output_bit(index); }
  void set_motion_output_value(int index, double value) override { ++outputs_; real_.set_motion_output_value(index, value); }
  void set_aux_output_value(int index, double value) override { ++outputs_; real_.set_aux_output_value(index, value); }
  void wait_input(int index, bool digital, WaitType type, double timeout_s) override { ++outputs_; real_.wait_input(index, digital, type, timeout_s); }
  void comment(std::string_view text) override {
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, text = std::string(text)] { real_.comment(text); }});
      return;
    }
    real_.comment(text);
  }
  void message(std::string_view text) override { real_.message(text); }
  void canon_error(std::string_view text) override { real_.canon_error(text); }
  void print(std::string_view text) override { real_.print(text); }
  void log_open(std::string_view a0, bool a1) override { real_.log_open(a0, a1); }
  void log_close() override { real_.log_close(); }
  void log(std::string_view a0) override { real_.log(a0); }
  void program_stop() override { ++outputs_; real_.program_stop(); }
  void optional_program_stop() override { ++outputs_; real_.optional_program_stop(); }
  void pallet_shuttle() override { ++outputs_; real_.pallet_shuttle(); }
  void program_end() override { ++outputs_; real_.program_end(); }
  void finish() override { real_.finish(); }
  void user_m_code(int code, double p, double q) override {
    ++outputs_;
    if (holding()) {
      queue_.push_back(QueuedCall{false, {}, [this, code, p, q] { real_.user_m_code(code, p, q); }});
      return;
    }
    real_.user_m_code(code, p, q);
  }
  void on_reset() override { real_.on_reset(); }
  Pose current_position() const override { return real_.current_position(); }
  Pose probe_position() const override { return real_.probe_position(); }
  bool probe_tripped() const override { return real_.probe_tripped(); }
  double input_value() const override { return real_.input_value(); }
  Units machine_length_units() const override { return real_.machine_length_units(); }
  double external_length_units() const override { return real_.external_length_units(); }
  const cnc::tooltable::ToolTable& tool_table() const override { return real_.tool_table(); }
  int tool_in_spindle() const override { return real_.tool_in_spindle(); }
  int tool_slot() const override { return real_.tool_slot(); }
  bool is_feed_override_enabled() const override { return real_.is_feed_override_enabled(); }

 private:
  Canon& real_;
  std::deque<QueuedCall> queue_;
  uint64_t outputs_ = 0;
};

}  // namespace cnc::interp
