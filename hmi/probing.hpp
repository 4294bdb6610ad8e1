// Probing routines of the operator screen (docs/hmi.md, "Probe page"):
// tool length on a tool setter, edge, inside/outside corner, bore and boss
// centre, and touch-off into any coordinate system. A routine is a list of
// stages of MDI lines; the screen sends a stage, and once it is done gives
// the routine the probe result from the status (probe tripped, the machine
// position latched), which the later stages and the result are computed
// from. Every probe is a fast search (G38.2 over SEARCH_DISTANCE at
// SEARCH_FEED), a back-off of LATCH_DISTANCE and a slow touch at LATCH_FEED;
// the slow touch is the one measured. Positions are machine coordinates;
// an edge is the probe centre's position plus the tip radius toward the
// material. The modal state is kept as LinuxCNC's probe screens keep it:
// the first stage saves it (M70) and sets what the routine's numbers mean
// (machine units, G90, G94), the result stage restores it (M72) and drops
// the saved context (M71); after a failure, whose abort resets the
// interpreter and with it the M70 context, restore_lines() puts back what
// the status showed at the start. No Qt; the G-code is tested line by line.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/ipc/status.hpp"
#include "core/util/pose.hpp"

namespace cnc::ini {
class IniFile;
}

namespace cnc::hmi::probing {

// [PROBE] keys (docs/configuration.md). Lengths in machine units, feeds in
// machine units per minute.
struct Settings {
  double tip_diameter = 0;        // TIP_DIAMETER: the probe's stylus ball
  double search_distance = 10;    // SEARCH_DISTANCE: the fast search's length
  double latch_distance = 1;      // LATCH_DISTANCE: back-off before the slow touch
  double search_feed = 200;       // SEARCH_FEED
  double latch_feed = 20;         // LATCH_FEED
  double clearance = 5;           // CLEARANCE: boss and outside corner: beyond the part before going down
  // The tool setter (machine coordinates); `setter` is false when
  // SETTER_X/Y/Z are not all given.
  bool setter = false;
  double setter_x = 0, setter_y = 0;
  double setter_z = 0;            // SETTER_Z: where the search starts, above the setter
  double setter_safe_z = 0;       // SETTER_SAFE_Z: travel height to and from the setter
  double setter_reference_z = 0;  // SETTER_REFERENCE_Z: spindle gauge line (tool length 0) touching the setter
  double setter_search_distance = 0;  // SETTER_SEARCH_DISTANCE, default SEARCH_DISTANCE
  bool inch = false;              // machine units ([TRAJ]LINEAR_UNITS; set by HmiConfig): G20, else G21

  double tip_radius() const { return tip_diameter / 2; }
  // Reads [PROBE]; throws ConfigError naming file, line and key for values
  // out of range or inconsistent (LATCH_DISTANCE not below SEARCH_DISTANCE,
  // a setter key without the others).
  static Settings from_ini(const ini::IniFile& ini);
};

enum class Kind { ToolLength, Edge, InsideCorner, OutsideCorner, Bore, Boss, TipCalibration };
const char* to_string(Kind k);

// What the operator asked for.
struct Request {
  Kind kind = Kind::Edge;
  int axis = 0;            // Edge: 0 X, 1 Y
  int direction = 1;       // Edge: +1 probes toward +axis, -1 toward -axis
  // Corners: the directions from the probe toward the material (+1/-1).
  int corner_x = 1, corner_y = 1;
  double corner_step = 0;  // OutsideCorner: how far along each face to go before probing it
  double boss_diameter = 0, boss_depth = 0;  // Boss: about how large, how far down to probe
  int tool = 0;            // ToolLength: the tool whose length is set (G10 L1)
  double gauge_diameter = 0;  // TipCalibration: the ring gauge's (known bore's) diameter
  // Set the result as the origin's value in a coordinate system:
  // 0 none, 1..9 = G54..G59.3 (G10 L2 Pn).
  int coordinate_system = 0;
  double value_x = 0, value_y = 0;  // what the edge/corner/centre is to read there
};

// The controller's state at the start (from the status).
struct Start {
  Pose position;      // machine
  Pose g92_offset;
  Pose tool_offset;
  double rotation_xy = 0;
  int tool_in_spindle = 0;
  // The modal state to put back after a failure: the status' active G
  // codes (LinuxCNC's numbering: G20 = 200, G91 = 910, G95 = 950, G18 =
  // 180) and F (active_settings[1], program units). Empty: only G90.
  std::vector<int> gcodes;
  double feed = 0;
};

// The start as the status shows it (what the Probe page hands a routine).
Start start_from(const ipc::Status& status);

struct Stage {
  std::vector<std::string> lines;  // MDI lines, sent one after the other
  int probe_axis = -1;             // the axis the stage's last probe measures, -1: no probe
  std::string what;                // for the log
};

struct Result {
  bool has_x = false, has_y = false, has_z = false;
  double x = 0, y = 0, z = 0;        // machine: the edge, corner or centre; the setter contact
  double diameter_x = 0, diameter_y = 0;  // Bore/Boss/TipCalibration
  double tip_diameter = 0;           // TipCalibration: the effective tip diameter (mean of X and Y)
  double tip_diameter_x = 0, tip_diameter_y = 0;  // TipCalibration: from the X and from the Y hits
  double tool_length = 0;            // ToolLength
  std::vector<double> hits;          // each probe's measured coordinate (probe centre), in order
  std::string summary;               // for the operator
};

// "G54".."G59.3" for 1..9.
std::string coordinate_system_name(int index);
// Numbers in G-code: fixed 4 decimals, '.' separator, no "-0".
std::string gcode_number(double v);

// Touch-off of the current position into any coordinate system:
// "G10 L20 P<system> <axis><value>" (the axis' current position becomes
// `value` in that system, active or not). Throws std::invalid_argument for
// a system outside 1..9 or an axis outside 0..8.
std::string touch_off_line(int coordinate_system, int axis, double value);

class Routine {
 public:
  // Plans a routine; throws std::invalid_argument saying what is wrong
  // (no setter configured, no tool, directions, sizes, XY rotation).
  Routine(const Settings& settings, const Request& request, const Start& start);

  bool done() const noexcept { return done_; }
  bool failed() const noexcept { return !error_.empty(); }
  const std::string& error() const noexcept { return error_; }
  // The stage to send now; only while !done().
  const Stage& stage() const { return stage_; }
  // The current stage ran to its end: for a probing stage, whether the
  // probe tripped and where (machine). Computes the next stage or the
  // result; a probe that did not trip fails the routine (error()).
  void completed(bool tripped, const Pose& probed);
  // The stage was refused or aborted: the routine fails with `why`.
  void fail(const std::string& why);
  const Result& result() const noexcept { return result_; }
  // Lines to send after a failure: the modal state of the start (units,
  // distance mode, feed mode, plane, then F), or G90 when the start did
  // not say (the probe moves are incremental).
  std::vector<std::string> cleanup_lines() const;

  // The probe stage along `axis` toward `direction` (for tests and the
  // documentation).
  static std::vector<std::string> probe_lines(const Settings& s, int axis, int direction, double search);

 private:
  enum class Op { Lines, Probe, CentreX, CentreY, Finish };
  struct Step {
    Op op = Op::Lines;
    std::vector<std::string> lines;
    int axis = 0, direction = 1;
    double search = 0;
    std::size_t hit_a = 0, hit_b = 0;  // CentreX/CentreY: the midpoint of these hits
    std::string what;
  };
  void advance();
  void advance_steps();
  void finish();
  double hit(std::size_t i) const { return result_.hits.at(i); }

  Settings s_;
  Request r_;
  Start start_;
  std::vector<Step> steps_;
  std::size_t next_ = 0;
  Stage stage_;
  Result result_;
  std::string error_;
  bool done_ = false;
  bool prologue_sent_ = false;
};

}  // namespace cnc::hmi::probing
