// What the screen's readouts say, computed from the status alone (no Qt):
// every value with its unit, and nothing left over from an earlier state
// (a feed after E-stop, an MDI line that was rejected, errors before any
// program). The widgets show these strings; the logic tests check them.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/ipc/status.hpp"
#include "hmi/numbers.hpp"

namespace cnc::hmi {

// "F 200 mm/min × 100% = 200 mm/min · now 180 mm/min". F is the executing
// line's (task.active_settings[1], program units); "now" is the path
// velocity, 0 while motion is disabled; with the machine not on, the
// programmed feed is not shown as if it were in force.
std::string feed_readout(const ipc::Status& s, bool machine_inch, const NumberFormat& f = NumberFormat());

// "S 3000 rpm × 100% = 3000 rpm FWD · actual 500 rpm · NOT AT SPEED": the
// commanded speed of the executing line, what motion sends, and the
// spindle's feedback (spindle.0.speed-in) apart from it.
std::string spindle_readout(const ipc::Status& s, const NumberFormat& f = NumberFormat());

// "running: G0 X10" while an MDI line runs, "" otherwise.
std::string mdi_running_readout(const ipc::Status& s);

// Program progress from lines: the executing line against the program's
// length (the planner has no remaining-time estimate); the time left is
// extrapolated from the time the lines so far took. percent -1: unknown.
struct ProgramProgress {
  int percent = -1;
  double elapsed_s = 0;
  double remaining_s = -1;  // -1: not estimated yet (too early) or not running
};
ProgramProgress program_progress(const ipc::Status& s);
// "line 120 of 400 · 30% · 0:01:10 · about 0:02:43 left · errors: 1".
// With the planner's estimate of the program's motion time (`estimate_s`
// >= 0, cnc-estimate): "planned 0:03:53 of motion" before and after a run,
// "about 0:02:43 left (planner)" while it runs (the estimate less the time
// run so far; tool changes and waits are not in the estimate).
std::string progress_readout(const ipc::Status& s, double estimate_s = -1);
// The motion time from cnc-estimate's output ("PROG: 66.319 s of motion
// (1:06.319), ..."), if it has one.
std::optional<double> parse_estimate_output(std::string_view output);
std::string format_duration(double seconds);  // "1:02:03"

// CiA 402 statusword (0x6041) bits that are set, by name ("ready to switch
// on", "operation enabled", "fault", ..., "following error").
std::vector<std::string> statusword_bits(uint16_t statusword);
// "0x1237: ready to switch on, switched on, ..."
std::string statusword_readout(uint16_t statusword);
// The same in CiA 402's short names, for a table cell: "0x1637 RTSO SO OE
// VE RM TR SPF" (QS! when a quick stop is active).
std::string statusword_short(uint16_t statusword);
// Units of the drive panel's values (DriveStatus velocity, following error
// in machine units; the spindle's drive in rpm).
std::string drive_velocity_unit(bool spindle, bool angular, bool machine_inch);
std::string drive_position_unit(bool angular, bool machine_inch);
// A drive's velocity in the unit above: the spindle's drive reports
// revolutions per second (what spindle.N.speed-in takes), shown in rpm.
double drive_velocity_value(const ipc::DriveStatus& d);

}  // namespace cnc::hmi
