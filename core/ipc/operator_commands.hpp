// Every operator command encoded as the command channel documents it
// (command.hpp): one place for the encoding, used by the Python module, the
// MQTT bridge and the command-line client. Plain builders: no I/O.
#pragma once

#include <string>

#include "core/ipc/command.hpp"
#include "core/ipc/status.hpp"
#include "core/util/pose.hpp"

namespace cnc::ipc::commands {

Command set_state(TaskState state);
Command set_mode(TaskMode mode);
Command abort();
Command open(const std::string& path);  // absolute path: the controller resolves nothing
Command close();
Command run(int line = 0);              // 0: from the beginning
Command pause();
Command resume();
Command step();
Command mdi(const std::string& line);
Command macro(int index);
Command optional_stop(bool on);
Command block_delete(bool on);
Command home(int joint);                // -1: all
Command unhome(int joint);              // -1: all
Command override_limits();
// Jogs: `index` is an axis (0 = X .. 8 = W, teleop) or, with `joint`, a
// joint (free mode).
Command jog_continuous(int index, bool joint, double velocity);    // signed velocity
Command jog_increment(int index, bool joint, double velocity, double distance);  // sign of either: direction
Command jog_absolute(int index, bool joint, double velocity, double position);
Command jog_stop(int index, bool joint);
Command feed_override(double ratio);    // 1.0 = 100 %
Command rapid_override(double ratio);
Command max_velocity(double units_per_s);
Command spindle_override(double ratio, int spindle = 0);
Command spindle_on(double rpm, int spindle = 0);  // negative: reverse
Command spindle_off(int spindle = 0);
Command spindle_faster(int spindle = 0);
Command spindle_slower(int spindle = 0);
Command spindle_brake(bool engage, int spindle = 0);
Command flood(bool on);
Command mist(bool on);
Command lube(bool on);
Command teleop_enable(bool on);
Command feed_override_enable(bool on);
Command tool_load_table();
Command tool_set_number(int tool);      // M61: the tool now in the spindle
Command tool_delete(int tool);
// One tool's offsets (X..W), diameter, angles, orientation and comment;
// pocket -1 keeps the tool's pocket.
Command tool_set_offset(int tool, int pocket, const Pose& offset, double diameter, double front_angle,
                        double back_angle, int orientation, const std::string& comment);
// index 1..9 = G54..G59.3 (with the XY rotation), 0 = G92.
Command set_work_offset(int index, const Pose& offsets, double rotation_deg);
Command operator_error(const std::string& text);
Command operator_text(const std::string& text);
Command operator_display(const std::string& text);
// Acknowledges an alarm of the controller's table (status `alarms`), 0: all.
Command acknowledge_alarm(uint32_t id);
Command set_digital_output(int index, bool value, bool now = true);
Command set_analog_output(int index, double value, bool now = true);

// Throws std::invalid_argument naming the argument when `text` does not fit
// a command's text field.
void check_text(const std::string& text, const char* what);

}  // namespace cnc::ipc::commands
