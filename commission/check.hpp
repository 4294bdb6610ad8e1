// Step 9's check: the written configuration started and a short program
// run on it. `write` writes the check program (check.ngc beside the INI):
// every axis, one at a time, to a little inside each of its soft limits
// and back to where homing leaves it, at reduced feed; its comment line
// "(cnc-commission end X0 Y0 Z-5)" declares where it ends. `cnc-commission
// check` starts cncd on the INI, resets E-stop, switches on, homes, runs
// the program (or one given) to its end, compares the end position with
// the declared one and stops cncd; the state keeps the result
// (State::check). Non-realtime.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "commission/controller.hpp"
#include "commission/state.hpp"

namespace cnc::commission {

// How far inside a soft limit the check program turns: 5 % of the travel,
// at least 0.5 mm, at most 5 mm.
double check_inset(const Axis& a) noexcept;
// Its feed on axis `a` (mm/s): a quarter of the axis' MAX_VELOCITY as
// written (step 7's recommendation, else the provisional one), at most
// kCheckMaxFeed.
inline constexpr double kCheckMaxFeed = 20.0;
double check_feed(const Axis& a) noexcept;

// The check program for the state's configuration (G-code text, the axes
// in joint order), inside each axis' soft limits and short of the limit
// switches found (clear_of_switches). Throws std::invalid_argument when the state has no axis
// or an axis whose soft limits leave no travel, naming it.
std::string check_program(const State& s);
// How long the check program's moves take at their feeds (s; the
// accelerations not counted), the least time limit it can end within.
// Throws as check_program.
double check_program_seconds(const State& s);
// The time limit of the written check program when none is given: twice
// its length and a minute, at least 600 s.
double check_default_timeout_s(double program_s) noexcept;

// The end position a program declares in a comment
// "(cnc-commission end X0 Y0 Z-5)": axis letter and position (mm);
// empty when it declares none. Throws std::invalid_argument naming
// `origin` and the line when the comment is malformed.
std::vector<std::pair<char, double>> declared_end(const std::string& program_text, const std::string& origin);

// Runs `program` on the running controller of `c`: E-stop reset (refused
// while the chain is open), machine on, every joint homed, auto mode, the
// program opened and run to its end (at most `timeout_s`), then checks that
// the machine is still on, the interpreter idle without errors, and each
// declared end position reached (within 0.001 mm); the machine is switched
// off at the end whatever happens. `progress(i, n, text)` follows the
// stages. Returns a line saying what was checked. Throws
// std::runtime_error saying what failed (or that it was aborted:
// request_abort()) and in which state the machine was left.
std::string run_check(const Controller& c, const std::filesystem::path& program, double timeout_s,
                      const std::function<void(int, int, const std::string&)>& progress = {});

}  // namespace cnc::commission
