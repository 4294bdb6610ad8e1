// A Canon that prints every call in the text format of LinuxCNC's stand-alone
// interpreter `rs274` (its "saicanon" layer), and answers the interpreter's
// queries like that simulated machine does: it tracks the position, the
// tool table (tool table units are the machine units, inches by default as
// in saicanon), the probe end point. Used by cnc-rs274, golden tests and the
// recording Canon of unit tests. Non-realtime.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

#include "core/interp/canon.hpp"

namespace cnc::interp {

class TextCanon : public Canon {
 public:
  // `out` may be null: nothing is written (calls still reach emit()).
  explicit TextCanon(std::FILE* out, cnc::tooltable::ToolTable tools = cnc::tooltable::ToolTable(), Units machine_units = Units::Inch);
  ~TextCanon() override;

  void flush();
  // Sets the N column to "....." (as between blocks or after the end).
  void clear_block() noexcept { n_text_.clear(); }
  // Values the queries return.
  void set_probe_tripped(bool v) noexcept { probe_tripped_ = v; }
  void set_input_value(double v) noexcept { input_value_ = v; }
  // LinuxCNC's stand-alone canon does not load a tool's data into the
  // spindle on M61 (CHANGE_TOOL_NUMBER); a real I/O controller does. Default:
  // like rs274.
  void set_m61_loads_tool_data(bool v) noexcept { m61_loads_tool_data_ = v; }
  long call_count() const noexcept { return index_; }

  // Canon
  void begin_block(int line, int n_number, std::string_view n_text) override;
  void use_length_units(Units u) override;
  void select_plane(Plane p) override;
  void set_g5x_offset(int origin, const Pose& offset) override;
  void set_g92_offset(const Pose& offset) override;
  void set_xy_rotation(double degrees) override;
  void set_feed_reference(FeedReference r) override;
  void use_tool_length_offset(const Pose& offset) override;
  void set_feed_rate(double rate) override;
  void set_feed_mode(int spindle, FeedMode mode) override;
  void set_motion_control_mode(MotionMode mode, double tolerance) override;
  void set_naivecam_tolerance(double tolerance) override;
  void straight_traverse(int line, const Pose& end) override;
  void straight_feed(int line, const Pose& end) override;
  void arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis, int rotation,
                double axis_end, const Pose& end) override;
  void nurbs_feed(int line, int order, const std::vector<ControlPoint>& points, const Pose& end) override;
  void straight_probe(int line, const Pose& end, ProbeKind kind) override;
  void turn_probe_on() override;
  void turn_probe_off() override;
  void rigid_tap(int line, const Pose& end, double scale) override;
  void start_speed_feed_synch(int spindle, double feed_per_rev, bool velocity_mode) override;
  void stop_speed_feed_synch() override;
  void dwell(double seconds) override;
  void set_spindle_speed(int spindle, double rpm) override;
  void set_spindle_mode(int spindle, double css_max_rpm) override;
  void start_spindle_clockwise(int spindle) override;
  void start_spindle_counterclockwise(int spindle) override;
  void stop_spindle_turning(int spindle) override;
  void orient_spindle(int spindle, double degrees, int mode) override;
  void wait_spindle_orient_complete(int spindle, double timeout_s) override;
  void flood_on() override;
  void flood_off() override;
  void mist_on() override;
  void mist_off() override;
  void enable_feed_override() override;
  void disable_feed_override() override;
  void enable_speed_override(int spindle) override;
  void disable_speed_override(int spindle) override;
  void enable_adaptive_feed() override;
  void disable_adaptive_feed() override;
  void enable_feed_hold() override;
  void disable_feed_hold() override;
  void select_tool(int tool_number) override;
  void start_change() override;
  void change_tool(int index) override;
  void change_tool_number(int index) override;
  void set_tool_table_entry(int index, const ToolData& tool) override;
  void set_motion_output_bit(int index) override;
  void clear_motion_output_bit(int index) override;
  void set_aux_output_bit(int index) override;
  void clear_aux_output_bit(int index) override;
  void set_motion_output_value(int index, double value) override;
  void set_aux_output_value(int index, double value) override;
  void wait_input(int index, bool digital, WaitType type, double timeout_s) override;
  void comment(std::string_view text) override;
  void message(std::string_view text) override;
  void canon_error(std::string_view text) override;
  void print(std::string_view text) override;
  void log_open(std::string_view path, bool append) override;
  void log_close() override;
  void log(std::string_view text) override;
  void program_stop() override;
  void optional_program_stop() override;
  void pallet_shuttle() override;
  void program_end() override;
  void finish() override;
  void user_m_code(int code, double p, double q) override;
  void on_reset() override;

  Pose current_position() const override;
  Pose probe_position() const override { return probe_; }
  bool probe_tripped() const override { return probe_tripped_; }
  double input_value() const override { return input_value_; }
  Units machine_length_units() const override { return machine_units_; }
  // As rs274's saicanon: inches as its rounded 0.03937007874016 per mm (a
  // tool radius of 0.03125 in is 0.793749999999995 mm, not 0.79375).
  double external_length_units() const override {
    return machine_units_ == Units::Inch ? 0.03937007874016 : machine_units_ == Units::Cm ? 0.1 : 1.0;
  }
  const cnc::tooltable::ToolTable& tool_table() const override { return tools_; }
  int tool_in_spindle() const override;
  // As rs274's saicanon: index 1 until a tool change says otherwise.
  int tool_slot() const override { return slot_; }

 protected:
  // Receives each formatted call ("NAME(args)") after it is written.
  virtual void emit(std::string_view /*call*/) {}
  virtual void segment(char /*kind*/, int /*line*/, const Pose& /*end*/) {}

 private:
  void out(std::string_view call);
  void move_to(const Pose& end);

  std::FILE* file_;
  std::string buf_;
  std::string call_;
  long index_ = 0;
  std::string n_text_;  // N word as written; empty: "....."
  cnc::tooltable::ToolTable tools_;
  Units machine_units_;
  Units units_ = Units::Mm;
  Pose pos_{};  // program coordinates, current program units
  Pose g5x_{}, g92_{}, tlo_{};  // current program units
  Pose probe_{};
  bool probe_tripped_ = false;
  double input_value_ = 0;
  int selected_ = -1;
  bool m61_loads_tool_data_ = false;
  int slot_ = 1;
};

}  // namespace cnc::interp
