// Canon replay: runs a file of canonical calls, one per line, as LinuxCNC's
// `rs274 -g` prints them and as its pluggable "canterp" interpreter reads
// them, on a Canon. A program already interpreted elsewhere (a CAM post
// that writes canonical calls, or a recorded run) is replayed without the
// RS274/NGC interpreter.
//
// Line format: two leading fields that are ignored (the sequence number and
// the N word column, "xx xxxxx" or "   12 N....."), then NAME(arguments).
// Numbers are separated by commas and/or blanks; positions take the nine
// axes X Y Z A B C U V W (rs274 prints six when U V W are absent: missing
// trailing axes are 0 only when at least X Y Z are given). Blank lines are
// skipped. Calls and their arguments (see docs/interpreter.md, "Canon
// replay"): COMMENT, MESSAGE, USE_LENGTH_UNITS, SELECT_PLANE,
// SET_FEED_REFERENCE, SET_FEED_RATE, STRAIGHT_TRAVERSE, STRAIGHT_FEED,
// ARC_FEED, DWELL, SET_SPINDLE_SPEED, START_SPINDLE_CLOCKWISE,
// START_SPINDLE_COUNTERCLOCKWISE, STOP_SPINDLE_TURNING, SELECT_TOOL,
// CHANGE_TOOL, MIST_ON/OFF, FLOOD_ON/OFF, ENABLE/DISABLE_FEED_OVERRIDE,
// PROGRAM_STOP, OPTIONAL_PROGRAM_STOP, PROGRAM_END.
//
// Errors: an unknown call, a wrong number of arguments, a number that does
// not parse, a missing parenthesis: InterpError naming the file, the line
// and what was expected; the calls before it have been made.
#pragma once

#include <filesystem>
#include <istream>
#include <string>

#include "core/interp/canon.hpp"
#include "core/interp/interp.hpp"

namespace cnc::interp {

// Replays `in` (named `file` in errors) on `canon`. Returns when the input
// ends or after PROGRAM_END. Throws InterpError.
void replay_canon(std::istream& in, const std::string& file, Canon& canon);

// The same for a file; an unreadable file is an InterpError naming it.
void replay_canon_file(const std::filesystem::path& path, Canon& canon);

}  // namespace cnc::interp
