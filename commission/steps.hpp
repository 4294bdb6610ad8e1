// Steps 2-4 of commissioning as pure functions over the state: assigning
// drives to axes, the scaling of each axis, and the analysis of a direction
// and scaling test (a jog whose commanded travel, encoder feedback and
// dial-indicator reading are given). They check their input and throw
// std::invalid_argument with a message naming the axis, node or value.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "commission/state.hpp"

namespace cnc::commission {

// Assigns node `node` (which the scan must have found, as a CiA 402 drive
// not in fault) to axis `letter` on joint `joint`; a second call for the
// same letter reassigns it. `gantry` is the second drive of a gantry pair
// (its node, joint and direction; none: one drive), checked as the first.
Axis& assign_axis(State& s, char letter, int joint, int node, std::optional<GantryDrive> gantry = std::nullopt);

// The same for an EtherCAT drive: slave `position` of the segment scan,
// which must have CoE (the CiA 402 drive profile over EtherCAT).
Axis& assign_axis_ethercat(State& s, char letter, int joint, int position,
                           std::optional<GantryDrive> gantry = std::nullopt);

// The joints of the machine in joint order: each axis' joint and, for a
// gantry pair, its second drive's joint as a copy of the axis (joint, node
// or slave, REVERSE relative to the axis', `gantry_second` true), so the
// writer and the steps treat both drives alike.
struct MachineJoint {
  Axis axis;                  // the axis as this joint's drive sees it
  bool gantry_second = false; // the second drive of a gantry pair
};
std::vector<MachineJoint> machine_joints(const State& s);
// The axis as its gantry's second drive sees it (its joint, drive,
// absolute REVERSE, scale correction, and the switches, homing and
// direction test found on its own joint where steps 4-6 ran on it; the
// axis' otherwise). `a` must have a gantry.
Axis gantry_view(const Axis& a);
// The joints steps 4-7 act on: the axis, and for a gantry pair its second
// drive's view as well.
std::vector<Axis> step_joints(const Axis& a);

// Sets the axis' scaling: encoder increments per motor revolution from the
// drive (0x608F) unless given (> 0), gear from the drive (0x6091) unless
// given (> 0), and the screw lead (mm per screw revolution, required).
// Returns the counts per mm.
double set_scaling(State& s, char letter, double screw_lead, double encoder_counts = 0, double gear_motor_revs = 0,
                   double gear_load_revs = 0);

// Largest jog a direction test makes, and its speed limit (mm, mm/s).
inline constexpr double kMaxTestTravel = 20.0;
inline constexpr double kMaxTestVelocity = 5.0;
// While no dial reading has checked the axis' scaling, the table may move
// a multiple of the command (a 3:1 gear and a 10 mm lead taken for a
// direct 5 mm screw: 6x), so the first test jogs at most kFirstTestTravel;
// its dial reading corrects the scaling, after which the command is the
// table's travel and tests go up to kMaxTestTravel.
inline constexpr double kFirstTestTravel = 2.0;
double direction_test_travel_limit(const Axis& a) noexcept;

// The analysis of a direction test on axis `letter`: the jog commanded
// `commanded_mm` at the axis' current scaling; the drive's encoder reported
// `feedback_mm` of travel (same scaling); the dial indicator, zeroed before
// the jog, showed `dial_mm` in the axis' positive direction (has_dial false:
// not measured yet). The table moving against the command flips REVERSE;
// a dial travel unlike the feedback corrects the counts per mm. The axis'
// scaling is updated and the test stored in the state.
// On a gantry pair each drive is tested on its own (`gantry_second`: the
// second drive's jog and dial, stored in Axis::gantry): either side may
// turn the other way or scale differently. Flipping the first drive's
// REVERSE leaves the second drive's direction as it was.
const DirectionTest& apply_direction_test(State& s, char letter, double commanded_mm, double feedback_mm,
                                          double dial_mm, bool has_dial, bool gantry_second = false);

// The drive's torque limit as the scan read it (0x6072, per thousand of
// rated torque) in percent of rated torque; none when the scan did not
// read it.
std::optional<double> drive_max_torque_pct(const State& s, const Axis& a);

// The travel a commissioning motion may use on axis `a` (the tuning tests,
// the compensation cycle): its soft limits when they were given (`axis L
// limits`, `limits_source` "entered") or set from the switches (step 5),
// and never beyond the limit switches the switch search found, less
// kSwitchClearance; the switches alone when no limits were given. `source`
// says which, for messages. Throws std::invalid_argument naming the axis
// and what to do when neither is known (the default limits are no
// knowledge of the machine).
struct Travel {
  double min = 0, max = 0;
  std::string source;
};
inline constexpr double kSwitchClearance = 2.0;  // mm
Travel known_travel(const Axis& a);
// `t` cut short of the limit switches the switch search found (by
// kSwitchClearance), saying so in its source.
Travel clear_of_switches(const Axis& a, Travel t);

}  // namespace cnc::commission
