// Step 6 of commissioning: homing. The methods there are (the controller's
// own homing sequence on the home switch, and the CiA 402 methods of the
// drives), the HOME_* keys a chosen method needs (the configuration
// writer writes them from Axis::homing), and the repeatability run: home
// N times, moving away between runs, recording the reference position of
// each run and its spread. Non-realtime.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

struct HomingMethod {
  std::string id;     // "controller", "drive:17"
  std::string text;   // one line
};

// The methods, in the order shown: the controller's sequence, then the
// CiA 402 methods the drives of this project support (docs/cia402.md).
const std::vector<HomingMethod>& homing_methods();

// Checks `method` ("controller" or "drive:N" with N one of the list) for
// axis `a`, and fills Axis::homing's method and speeds from the switch
// search (the controller's sequence needs the home switch found; drive
// methods on a switch need that switch). Throws std::invalid_argument
// naming the axis and what is missing.
AxisHoming plan_homing(const Axis& a, const std::string& method);

// The CiA 402 method number of "drive:N" (0 for "controller").
int drive_method(const std::string& method);

// The joint position of the home switch edge the controller latches (the
// edge nearer the start of the switch search), which becomes HOME_OFFSET.
double home_switch_reference(const AxisSwitches& s, double search_velocity);

// A gantry pair (LinuxCNC's way: both joints in one synchronised homing
// group, a negative HOME_SEQUENCE; each joint homes on its own home
// switch, and the per-joint HOME_OFFSET squares the gantry): the second
// drive's homing for `method`, planned on the switches the search found on
// its own joint (gantry_view), with the first joint's HOME so the pair
// ends side by side, and `squaring_mm` added to its HOME_OFFSET: how far
// the second side stood ahead of the first (in the axis' + direction)
// after homing on the switch edges alone. Throws as plan_homing, naming
// the second drive.
AxisHoming plan_gantry_homing(const Axis& a, const AxisHoming& first, const std::string& method, double squaring_mm);

// The racking of a gantry pair after homing: machine on, the pair homed
// (`cnc home` of the first joint homes the synchronised group), at rest,
// the two HAL pins read (each side's position in mm: linear scales, or
// the simulated drives' table positions); returns second - first. The
// machine is off at the end whatever happens.
double measure_racking(const Controller& c, const Axis& a, const std::string& first_pin, const std::string& second_pin);

// Spread (max - min) of the references; 0 for fewer than two.
double spread(const std::vector<double>& v) noexcept;

// The repeatability run on a controller configured with Axis::homing
// (written by the writer): machine on, `repeat` times: home the joint,
// record the reference, move away by `away_mm` (towards the start of the
// switch search); machine off at the end whatever happens; time-limited
// (each homing 120 s); request_abort() stops it. What is recorded:
//   controller: the motor position of the latched switch edge (motor
//     position feedback - joint position + HOME_OFFSET, read at rest
//     after homing): exact, the position frame of the motor does not move;
//   drive:N: the drive sets its own position at the reference, so the
//     reference is measured against the switch: the joint position (in the
//     frame the drive just set) where the home switch changes while the
//     axis moves towards it at 1 mm/s, as the servo-thread latch saw it
//     (SwitchLatches: 1 mm/s x a servo cycle, 1 um at 1 ms); where
//     the latch is missing, the edge crossed again slowly (cross_edge,
//     until two polls are within 0.01 mm).
std::vector<double> run_homing(const Controller& c, const Axis& a, int repeat, double away_mm, std::FILE* progress);

}  // namespace cnc::commission

namespace cnc::commission {
// The configuration writer's part of steps 5 and 6 (each "" when the step
// was not done): the HOME_* keys of [JOINT_n] (controller or drive homing;
// without homing: the joint homes where it stands), the drive-homing keys
// of [CIA402_DRIVE_n], and the HAL nets of the switches found (each drive
// input to its joint pin, through a `not` when it is active low).
std::string joint_homing_keys(const Axis& a);
// The joint's HOME as the writer writes it (where homing leaves it): the
// planned HOME within the soft limits, 0 when homing is not commissioned.
double written_home(const Axis& a) noexcept;
std::string drive_homing_keys(const Axis& a);
std::string switch_nets(const std::vector<const Axis*>& axes);
}  // namespace cnc::commission
