// The canonical machining interface: every effect an RS274/NGC program has
// on the machine, as calls the interpreter makes on an object the task
// controller implements (LinuxCNC's "canon" layer). Also the queries the
// interpreter makes of the machine. Non-realtime; implementations may queue.
//
// Conventions (as LinuxCNC's emccanon): positions are in program
// coordinates and program length units (set by use_length_units); the
// active G5x/G92 offsets, XY rotation and tool length offset are announced
// by their own calls and are applied by the implementation, not by the
// interpreter. Angles are in degrees. `line` is the 1-based line of the
// source file the block came from (0 for MDI and start-up code).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/tooltable/tool_table.hpp"
#include "core/util/pose.hpp"

namespace cnc::interp {

enum class Units : uint8_t { Inch, Mm, Cm };
enum class Plane : uint8_t { XY, YZ, XZ, UV, VW, UW };
enum class FeedReference : uint8_t { Workpiece, Xyz };
// G93 / G94 / G95.
enum class FeedMode : uint8_t { UnitsPerMinute = 0, InverseTime = 1, UnitsPerRev = 2 };
// G61.1 exact stop, G61 exact path, G64 continuous (blending with tolerance).
enum class MotionMode : uint8_t { ExactStop, ExactPath, Continuous };
enum class Direction : uint8_t { Stopped, Clockwise, CounterClockwise };
enum class WaitType : uint8_t { Immediate = 0, Rise = 1, Fall = 2, High = 3, Low = 4 };
enum class ProbeKind : uint8_t { TowardStopOnContact, TowardNoError, AwayStopOnLoss, AwayNoError };

const char* to_string(Units u) noexcept;
const char* to_string(Plane p) noexcept;

// One tool as the interpreter needs it, in machine length units.
using ToolData = cnc::tooltable::Tool;

class Canon {
 public:
  virtual ~Canon() = default;

  // --- block context: source line, N word number (-1: none) and the N
  // word's digits as written ("0010"); default no-op
  virtual void begin_block(int /*line*/, int /*n_number*/, std::string_view /*n_text*/) {}

  // --- representation
  virtual void use_length_units(Units u) = 0;
  virtual void select_plane(Plane p) = 0;
  virtual void set_g5x_offset(int origin /*1=G54..9=G59.3*/, const Pose& offset) = 0;
  virtual void set_g92_offset(const Pose& offset) = 0;
  virtual void set_xy_rotation(double degrees) = 0;
  virtual void set_feed_reference(FeedReference r) = 0;
  virtual void use_tool_length_offset(const Pose& offset) = 0;

  // --- motion; each segment carries its source line
  virtual void set_feed_rate(double rate) = 0;
  virtual void set_feed_mode(int spindle, FeedMode mode) = 0;
  virtual void set_motion_control_mode(MotionMode mode, double tolerance) = 0;  // G64 P
  virtual void set_naivecam_tolerance(double tolerance) = 0;                    // G64 Q
  virtual void straight_traverse(int line, const Pose& end) = 0;
  virtual void straight_feed(int line, const Pose& end) = 0;
  // An arc (helix) in the selected plane: end and centre in the plane's
  // first/second axes, `rotation` > 0 counter-clockwise turns (+1: less
  // than a turn), < 0 clockwise; `axis_end` along the plane's normal. The
  // remaining axes move linearly to `end` (whose plane/normal entries equal
  // first_end, second_end and axis_end).
  virtual void arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis,
                        int rotation, double axis_end, const Pose& end) = 0;
  // A NURBS curve in the XY plane (G5 cubic and G5.1 quadratic splines,
  // G5.2/G5.3 NURBS blocks) of the given order: control points x, y and
  // weight, the first being the current position.
  struct ControlPoint {
    double x, y, weight;
  };
  virtual void nurbs_feed(int line, int order, const std::vector<ControlPoint>& points, const Pose& end) = 0;
  virtual void straight_probe(int line, const Pose& end, ProbeKind kind) = 0;
  virtual void turn_probe_on() {}
  virtual void turn_probe_off() {}
  virtual void rigid_tap(int line, const Pose& end, double scale) = 0;
  virtual void start_speed_feed_synch(int spindle, double feed_per_rev, bool velocity_mode) = 0;
  virtual void stop_speed_feed_synch() = 0;
  virtual void dwell(double seconds) = 0;

  // --- spindle
  virtual void set_spindle_speed(int spindle, double rpm) = 0;
  virtual void set_spindle_mode(int spindle, double css_max_rpm) = 0;  // 0: RPM mode (G97)
  virtual void start_spindle_clockwise(int spindle) = 0;
  virtual void start_spindle_counterclockwise(int spindle) = 0;
  virtual void stop_spindle_turning(int spindle) = 0;
  virtual void orient_spindle(int spindle, double degrees, int mode) = 0;
  // M19 Q: wait until the spindle reports it is oriented; not within
  // `timeout_s` seconds is an error of the machine.
  virtual void wait_spindle_orient_complete(int spindle, double timeout_s) = 0;

  // --- coolant
  virtual void flood_on() = 0;
  virtual void flood_off() = 0;
  virtual void mist_on() = 0;
  virtual void mist_off() = 0;

  // --- overrides (M48-M53)
  virtual void enable_feed_override() = 0;
  virtual void disable_feed_override() = 0;
  virtual void enable_speed_override(int spindle) = 0;
  virtual void disable_speed_override(int spindle) = 0;
  virtual void enable_adaptive_feed() = 0;
  virtual void disable_adaptive_feed() = 0;
  virtual void enable_feed_hold() = 0;
  virtual void disable_feed_hold() = 0;

  // --- tools (indices are tooldata indices, see ToolTable)
  virtual void select_tool(int tool_number) = 0;
  virtual void start_change() = 0;
  virtual void change_tool(int index) = 0;
  virtual void change_tool_number(int index) = 0;  // M61
  virtual void set_tool_table_entry(int index, const ToolData& tool) = 0;  // G10 L1/L10/L11

  // --- digital/analog I/O (M62-M68)
  virtual void set_motion_output_bit(int index) = 0;
  virtual void clear_motion_output_bit(int index) = 0;
  virtual void set_aux_output_bit(int index) = 0;
  virtual void clear_aux_output_bit(int index) = 0;
  virtual void set_motion_output_value(int index, double value) = 0;
  virtual void set_aux_output_value(int index, double value) = 0;
  // M66: the machine waits; the result is read with input_value() after
  // synchronisation. timeout in seconds.
  virtual void wait_input(int index, bool digital, WaitType type, double timeout_s) = 0;

  // --- messages and program flow
  virtual void comment(std::string_view text) = 0;
  virtual void message(std::string_view text) = 0;
  virtual void print(std::string_view text) = 0;  // (PRINT,...): log only
  // An error a script reports through the canon (LinuxCNC's CANON_ERROR):
  // by default shown to the operator like a message, in order.
  virtual void canon_error(std::string_view text) { message(text); }
  // (LOGOPEN,file) (LOGAPPEND,file) (LOG,text) (LOGCLOSE)
  virtual void log_open(std::string_view /*path*/, bool /*append*/) {}
  virtual void log_close() {}
  virtual void log(std::string_view /*text*/) {}
  virtual void program_stop() = 0;           // M0
  virtual void optional_program_stop() = 0;  // M1
  virtual void pallet_shuttle() = 0;         // M60
  virtual void program_end() = 0;            // M2 / M30
  virtual void finish() {}                   // closing '%' reached
  virtual void user_m_code(int code, double p, double q) = 0;  // M100-M199
  virtual void on_reset() {}

  // --- queries (after a synch point the interpreter re-reads these)
  virtual Pose current_position() const = 0;  // program coordinates and units
  virtual Pose probe_position() const = 0;    // program coordinates and units
  virtual bool probe_tripped() const = 0;
  virtual double input_value() const = 0;     // result of the last M66 (-1 on timeout)
  virtual Units machine_length_units() const = 0;  // units of the tool table
  // The machine's length units per millimetre (LinuxCNC's
  // GET_EXTERNAL_LENGTH_UNITS), when lengths from the machine (tool table)
  // are to be converted to program units through millimetres as LinuxCNC
  // does: (value / this) / program units in mm. 0 (the default): convert
  // by the exact ratio of the two units (same units: the value unchanged).
  virtual double external_length_units() const { return 0.0; }
  virtual const cnc::tooltable::ToolTable& tool_table() const = 0;
  virtual int tool_in_spindle() const = 0;         // tool number, 0 none
  // Tooldata index the spindle's tool came from, as the machine reports it
  // (LinuxCNC's GET_EXTERNAL_TOOL_SLOT); a G10 L1/L10/L11 of the tool at
  // that index also rewrites the spindle's entry (index 0). Default: the
  // index of tool_in_spindle() in tool_table(), 0 when none.
  virtual int tool_slot() const {
    const int n = tool_in_spindle();
    const auto i = n > 0 ? tool_table().find_tool(n) : std::nullopt;
    return i ? *i : 0;
  }
  virtual bool is_feed_override_enabled() const { return true; }
};

}  // namespace cnc::interp
