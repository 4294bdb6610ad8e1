#include "core/ipc/operator_commands.hpp"

#include <cmath>
#include <stdexcept>

#include "core/ipc/client.hpp"

namespace cnc::ipc::commands {

namespace {
Command with_i(CommandType t, int a, int b = 0) {
  Command c = make_command(t);
  c.i[0] = a;
  c.i[1] = b;
  return c;
}
Command with_d(CommandType t, double d, int i0 = 0) {
  Command c = make_command(t);
  c.d[0] = d;
  c.i[0] = i0;
  return c;
}
Command with_text(CommandType t, const std::string& text, const char* what) {
  check_text(text, what);
  Command c = make_command(t);
  c.text.assign(text);
  return c;
}
}  // namespace

void check_text(const std::string& text, const char* what) {
  const std::size_t cap = decltype(Command{}.text)::capacity();
  if (text.size() > cap) {
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(text.size()) + " characters, at most " +
                                std::to_string(cap));
  }
}

Command set_state(TaskState s) { return with_i(CommandType::TaskSetState, static_cast<int>(s)); }
Command set_mode(TaskMode m) { return with_i(CommandType::TaskSetMode, static_cast<int>(m)); }
Command abort() { return make_command(CommandType::TaskAbort); }
Command acknowledge_alarm(uint32_t id) { return with_i(CommandType::AlarmAcknowledge, static_cast<int>(id)); }
Command open(const std::string& path) { return with_text(CommandType::TaskPlanOpen, path, "program path"); }
Command close() { return make_command(CommandType::TaskPlanClose); }
Command run(int line) { return with_i(CommandType::TaskPlanRun, line); }
Command pause() { return make_command(CommandType::TaskPlanPause); }
Command resume() { return make_command(CommandType::TaskPlanResume); }
Command step() { return make_command(CommandType::TaskPlanStep); }
Command mdi(const std::string& line) {
  Command c = with_text(CommandType::TaskPlanExecute, line, "MDI line");
  c.i[0] = -1;
  return c;
}
Command macro(int index) { return with_i(CommandType::TaskPlanExecute, index); }
Command optional_stop(bool on) { return with_i(CommandType::TaskPlanSetOptionalStop, on ? 1 : 0); }
Command block_delete(bool on) { return with_i(CommandType::TaskPlanSetBlockDelete, on ? 1 : 0); }
Command home(int joint) { return with_i(CommandType::JointHome, joint); }
Command unhome(int joint) { return with_i(CommandType::JointUnhome, joint); }
Command override_limits() { return with_i(CommandType::JointOverrideLimits, -1); }

Command jog_continuous(int index, bool joint, double velocity) {
  Command c = with_i(CommandType::JogCont, index, joint ? 1 : 0);
  c.d[0] = velocity;
  return c;
}
Command jog_increment(int index, bool joint, double velocity, double distance) {
  Command c = with_i(CommandType::JogIncr, index, joint ? 1 : 0);
  // The channel wants a positive velocity and a signed distance.
  c.d[0] = std::fabs(velocity);
  c.d[1] = velocity < 0 ? -distance : distance;
  return c;
}
Command jog_absolute(int index, bool joint, double velocity, double position) {
  Command c = with_i(CommandType::JogAbs, index, joint ? 1 : 0);
  c.d[0] = std::fabs(velocity);
  c.d[1] = position;
  return c;
}
Command jog_stop(int index, bool joint) { return with_i(CommandType::JogStop, index, joint ? 1 : 0); }

Command feed_override(double ratio) { return with_d(CommandType::TrajSetScale, ratio); }
Command rapid_override(double ratio) { return with_d(CommandType::TrajSetRapidScale, ratio); }
Command max_velocity(double v) { return with_d(CommandType::TrajSetMaxVelocity, v); }
Command spindle_override(double ratio, int spindle) { return with_d(CommandType::SpindleOverride, ratio, spindle); }
Command spindle_on(double rpm, int spindle) { return with_d(CommandType::SpindleOn, rpm, spindle); }
Command spindle_off(int spindle) { return with_i(CommandType::SpindleOff, spindle); }
Command spindle_faster(int spindle) { return with_i(CommandType::SpindleIncrease, spindle); }
Command spindle_slower(int spindle) { return with_i(CommandType::SpindleDecrease, spindle); }
Command spindle_brake(bool engage, int spindle) {
  return with_i(engage ? CommandType::SpindleBrakeEngage : CommandType::SpindleBrakeRelease, spindle);
}
Command flood(bool on) { return make_command(on ? CommandType::CoolantFloodOn : CommandType::CoolantFloodOff); }
Command mist(bool on) { return make_command(on ? CommandType::CoolantMistOn : CommandType::CoolantMistOff); }
Command lube(bool on) { return make_command(on ? CommandType::LubeOn : CommandType::LubeOff); }
Command teleop_enable(bool on) { return with_i(CommandType::TrajSetTeleopEnable, on ? 1 : 0); }
Command feed_override_enable(bool on) { return with_i(CommandType::TrajSetFeedOverrideEnable, on ? 1 : 0); }
Command tool_load_table() { return make_command(CommandType::ToolLoadTable); }
Command tool_set_number(int tool) { return with_i(CommandType::ToolSetNumber, tool); }
Command tool_delete(int tool) { return with_i(CommandType::ToolDelete, tool); }

Command tool_set_offset(int tool, int pocket, const Pose& offset, double diameter, double front_angle,
                        double back_angle, int orientation, const std::string& comment) {
  Command c = with_text(CommandType::ToolSetOffset, comment, "tool comment");
  c.i[0] = tool;
  c.i[1] = pocket;
  c.i[2] = orientation;
  for (int a = 0; a < kNumAxes; ++a) c.d[a] = offset[a];
  c.d[9] = diameter;
  c.d[10] = front_angle;
  c.d[11] = back_angle;
  return c;
}

Command set_work_offset(int index, const Pose& offsets, double rotation_deg) {
  Command c = make_command(CommandType::SetWorkOffset);
  c.i[0] = index;
  for (int a = 0; a < kNumAxes; ++a) c.d[a] = offsets[a];
  c.d[9] = rotation_deg;
  return c;
}

Command operator_error(const std::string& t) { return with_text(CommandType::OperatorError, t, "error text"); }
Command operator_text(const std::string& t) { return with_text(CommandType::OperatorText, t, "text"); }
Command operator_display(const std::string& t) { return with_text(CommandType::OperatorDisplay, t, "display text"); }

Command set_digital_output(int index, bool value, bool now) {
  Command c = with_i(CommandType::MotionSetDigitalOutput, index, value ? 1 : 0);
  c.i[2] = now ? 1 : 0;
  return c;
}
Command set_analog_output(int index, double value, bool now) {
  Command c = with_d(CommandType::MotionSetAnalogOutput, value, index);
  c.i[2] = now ? 1 : 0;
  return c;
}

}  // namespace cnc::ipc::commands
