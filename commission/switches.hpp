// Step 5 of commissioning: the limit and home switches of an axis. A slow,
// time-limited jog towards each end of the axis (free mode) watches the
// drive's switch inputs (0x60FD through the cia402 pins neg-lim-sw,
// pos-lim-sw, home-sw) at every poll, while a latch in the servo thread
// records where each input changed; the analysis turns the samples into
// where each switch changed and its active level, and the soft limits
// follow from the limit switches. The analysis functions are pure (unit
// tested); find_switches() moves the machine. Non-realtime.
#pragma once

#include <string>
#include <vector>

#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

// One poll during a search: the joint's position and the three inputs as
// the HAL pins read (not yet interpreted by polarity).
struct SwitchSample {
  double position = 0;
  bool neg = false, pos = false, home = false;
};

// The analysis of a switch search of axis `letter`: `towards_neg` and
// `towards_pos` are the samples of the two jogs, each starting at the
// start position. Rules (docs/commissioning.md): a limit switch is
// inactive where the search starts (the axis starts between its limits),
// so its active level is the level it changed to; a change is placed
// halfway between the last sample before it and the first after it. The
// home switch's active level is the level held over the shorter part of
// the travel searched. A switch that never changed is a problem naming
// the axis, the switch, its pin and what to check. `pin_prefix` names the
// drive's pins (e.g. "cia402.0.drive.00.").
AxisSwitches analyse_switch_search(char letter, const std::vector<SwitchSample>& towards_neg,
                                   const std::vector<SwitchSample>& towards_pos, double search_mm, double velocity,
                                   const std::string& pin_prefix);

// The first change of one input along `samples` (member selects it): the
// position halfway between the samples around it; false when none.
bool first_change(const std::vector<SwitchSample>& samples, bool SwitchSample::*input, double& position);

// Soft limits from the limit switches found: min = negative switch +
// margin, max = positive switch - margin. Throws std::invalid_argument
// naming the axis when a switch was not found or the margin leaves no
// travel.
void soft_limits_from_switches(Axis& a, double margin_mm);

// The drive pins of an axis (the writer puts axis on joint J on drive J).
std::string drive_pin_prefix(const Axis& a);

// The motion of step 5 on a running controller: machine on, free mode,
// jog at `velocity` (at most kMaxSwitchVelocity) towards minus by up to
// `search_mm`, polling position and inputs; stop at the negative limit
// switch; back to the start; the same towards plus; each edge is where the
// servo-thread latch saw it (SwitchLatches, latched_change), or, where
// the latch is missing or saw more than one edge of the kind, it is
// crossed again slowly (cross_edge, in the direction the search crossed
// it); back to the start; machine off; the latches detached again (also
// when the search fails or is aborted: SwitchLatches::detach). A limit
// switch stops the jog at once (a following-error stop of the controller
// when the drive halts at its switch is expected and handled: the machine
// is switched on again and the axis jogged off). Time-limited (each leg:
// twice its travel time + 5 s); request_abort() stops it; the machine is
// off at the end whatever happens. Prints "progress: I/N text" lines to
// `progress` (may be null), and a line for each edge crossed again slowly
// and for latches that could not be detached.
AxisSwitches find_switches(const Controller& c, const Axis& a, double search_mm, double velocity,
                           std::FILE* progress = nullptr);

// Jogs joint `a.joint` by `dist` at `vel` and samples position and inputs
// until the jog ends, `stop_on` (may be null) changes (then a jog stop),
// the machine goes off (the controller stopped it) or a time limit
// (twice the travel time + 5 s: throws). request_abort() throws.
std::vector<SwitchSample> jog_and_sample(const Controller& c, const Axis& a, double dist, double vel,
                                         bool SwitchSample::*stop_on);
// Machine on (E-stop reset first) in manual mode; `override_limits`: jog
// off an active limit switch allowed for the next jog.
void machine_on(const Controller& c, bool override_limits = false);

// The edges of one input that the servo-thread latch (core/hal/latch.hpp)
// saw during one leg of a search: how many of each kind, and where the
// last of each kind was.
struct LatchedEdges {
  int rises = 0, falls = 0;
  double rise_position = 0, fall_position = 0;
  // Armed for the leg (SwitchLatches::stop_jogs_on_change): the input left
  // its level at the start of the leg, first at changed_position.
  bool changed = false;
  double changed_position = 0;
};
struct SwitchLatchReading {
  LatchedEdges neg, pos, home;
};

// Where the latch places the change of `input` that the polls of one leg
// (`samples`) place at `edge`: the latched edge of the kind the polls saw
// (rising when the input went TRUE), when the latch saw exactly one edge
// of that kind in the leg, or, for the leg's first change, where the
// armed latch saw the input first leave its level (`changed`: a drive
// halted at its limit switch chatters on the edge, a switch bounces);
// either only when it lies between the two polls around the change (give
// or take 0.05 mm). False otherwise: the caller crosses the edge again
// slowly (cross_edge).
bool latched_change(const std::vector<SwitchSample>& samples, bool SwitchSample::*input, const LatchedEdges& latch,
                    double& edge);

// The latches of the switch search on a running controller: three
// instances of the HAL component `latch` (commission-latch-neg, -pos,
// -home) added to `servo-thread`, their inputs linked to the drive's
// switch inputs of an axis and their position to joint.N.pos-fb (the
// joint position the polls read). The HAL has no unloadrt: the instances
// are loaded once per controller and reused by later searches; what
// attach() changed besides (the functions added to the thread, the links,
// the signals it made) detach() undoes, so between searches the latches
// sit unlinked outside every thread. Non-realtime (halcmd).
class SwitchLatches {
 public:
  SwitchLatches() = default;
  SwitchLatches(const SwitchLatches&) = delete;
  SwitchLatches& operator=(const SwitchLatches&) = delete;
  ~SwitchLatches() { detach(); }
  // Loads the instances if the controller has none yet, adds the functions
  // not in a thread to servo-thread, links them to the axis `a`. False
  // with `why` when the controller cannot have them (no component
  // `latch`, or one loaded by the configuration; no servo-thread); what
  // was done up to the failure is undone.
  bool attach(const Controller& c, const Axis& a, std::string& why);
  // Undoes what attach() did: takes the functions it added out of the
  // thread, unlinks the latches' pins, deletes the signals it made. ""
  // when all was undone, else what is left in the controller and why.
  // Never throws; a second call does nothing.
  std::string detach() noexcept;
  // Until release_jog_stop(): the jog stops in the servo cycle the input
  // of latch `which` (0 negative limit, 1 positive, 2 home) leaves the
  // level it has now (N.changed linked to motion.jog-stop, armed). False
  // when not attached or the configuration links motion.jog-stop itself
  // (then only the polls stop the jog).
  bool stop_jogs_on_change(int which);
  // Whether the armed latch saw its input change, and where (halcmd).
  bool armed_change(double& position) const;
  // Disarms the latch and puts motion.jog-stop back as it was (unlinked,
  // its value before). Throws when halcmd fails.
  void release_jog_stop();

 private:
  const Controller* c_ = nullptr;
  std::vector<std::string> added_functions_, linked_pins_, made_signals_;
  std::string armed_;              // the latch linked to motion.jog-stop
  std::string jog_stop_value_;     // motion.jog-stop's value before
};

// The latches' counts and last positions now (one halcmd read).
SwitchLatchReading read_switch_latches(const Controller& c);
// What happened between two readings: the counts' differences, the later
// reading's positions.
SwitchLatchReading latch_difference(const SwitchLatchReading& before, const SwitchLatchReading& after) noexcept;

// Crosses the edge of `input` (about at `edge`) again moving in `dir`:
// to 1 mm before it at `fast`, then across at `slow`, stopping at the
// change; while the polls around the change are more than `tolerance`
// apart, again at a quarter of the speed from twice that gap before it
// (three tries). Returns where it
// changed. Throws naming the switch when it does not change again.
double cross_edge(const Controller& c, const Axis& a, bool SwitchSample::*input, const char* name, double edge,
                  double dir, double fast, double slow, double tolerance = 0.02);

inline constexpr double kMaxSwitchVelocity = 20.0;  // mm/s

}  // namespace cnc::commission
