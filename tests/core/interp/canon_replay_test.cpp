// The canon replay (core/interp/canon_replay.hpp): a file of canonical
// calls as rs274 -g prints them runs on a Canon, as LinuxCNC's canterp
// plugin does, and bad lines are refused naming file and line.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/interp/canon_replay.hpp"
#include "core/interp/recording_canon.hpp"
#include "core/interp/rs274_run.hpp"
#include "tests/support/testing.hpp"

namespace fs = std::filesystem;
using cnc::interp::InterpError;
using cnc::interp::RecordingCanon;
using cnc::interp::replay_canon;

namespace {

std::vector<std::string> replay(const std::string& text) {
  RecordingCanon canon;
  std::istringstream in(text);
  replay_canon(in, "prog.can", canon);
  return canon.calls;
}

// The error message of replaying `text`, and the calls made before it.
std::string replay_error(const std::string& text, std::vector<std::string>* made = nullptr) {
  RecordingCanon canon;
  std::istringstream in(text);
  try {
    replay_canon(in, "prog.can", canon);
  } catch (const InterpError& e) {
    if (made != nullptr) *made = canon.calls;
    return e.file() + ":" + std::to_string(e.line()) + ": " + e.message();
  }
  return "no error";
}

// rs274 -g of `program` (the RS274/NGC interpreter), the index column
// dropped.
std::string rs274_output(const cnc::testing::TempDir& dir, const fs::path& program, const std::string& plugin = {}) {
  cnc::interp::Rs274Options o;
  o.program = program;
  o.plugin = plugin;
  o.machine_units = cnc::interp::Units::Mm;
  const fs::path out_path = dir / (program.filename().string() + ".out");
  std::FILE* out = std::fopen(out_path.c_str(), "w");
  std::string error;
  const bool ok = cnc::interp::run_rs274(o, out, error);
  std::fclose(out);
  EXPECT_TRUE(ok) << error;
  std::ifstream in(out_path);
  std::string line, text;
  while (std::getline(in, line)) text += line + "\n";
  return text;
}

}  // namespace

TEST(CanonReplay, LinuxCncsCanterpExampleLinesRunWithBlankOrCommaSeparatedNumbers) {
  const auto calls = replay(
      "xx xxxxx COMMENT(first two columns are ignored)\n"
      "\n"
      "00 N____ USE_LENGTH_UNITS(CANON_UNITS_MM)\n"
      "00 N____ SET_FEED_RATE(50.0)\n"
      "00 N____ SET_SPINDLE_SPEED(0, 3000)\n"
      "00 N____ START_SPINDLE_CLOCKWISE(0)\n"
      "00 N____ STRAIGHT_TRAVERSE( 5 5 5   0 0 0  0 0 0)\n"
      "00 N____ STRAIGHT_FEED(10, 0, -1.5, 0, 0, 0)\n"
      "00 N____ MIST_ON()\n"
      "00 N____ PROGRAM_END()\n"
      "00 N____ STRAIGHT_FEED(99 99 99 0 0 0)\n");
  const std::vector<std::string> expected = {
      "COMMENT(\"first two columns are ignored\")",
      "USE_LENGTH_UNITS(CANON_UNITS_MM)",
      "SET_FEED_RATE(50.0000)",
      "SET_SPINDLE_SPEED(0, 3000.0000)",
      "START_SPINDLE_CLOCKWISE(0)",
      "STRAIGHT_TRAVERSE(5.0000, 5.0000, 5.0000, 0.0000, 0.0000, 0.0000)",
      "STRAIGHT_FEED(10.0000, 0.0000, -1.5000, 0.0000, 0.0000, 0.0000)",
      "MIST_ON()",
      "PROGRAM_END()",
  };
  EXPECT_EQ(calls, expected);  // nothing after PROGRAM_END
}

TEST(CanonReplay, ReplayingRs274OutputGivesTheSameCallsUpToTheProgramEnd) {
  cnc::testing::TempDir dir;
  const fs::path ngc = dir.write("part.ngc",
                                 "G21 G17 G90 F300 S1200 M3 M8\n"
                                 "G0 X1 Y2 Z5\n"
                                 "G1 Z-1\n"
                                 "G2 X11 Y2 I5 J0\n"
                                 "G18 G3 X1 Z-1 I-5 K0\n"
                                 "G17 G64 P0.02\n"
                                 "G61\n"
                                 "G4 P0.5\n"
                                 "G55 G0 X0 Y0\n"
                                 "G92 X3\n"
                                 "G1 X4 A10\n"
                                 "M9 M5\n"
                                 "M2\n");
  const std::string direct = rs274_output(dir, ngc);
  // the interpreter's output up to PROGRAM_END, as a canon file
  const std::size_t end = direct.find("PROGRAM_END()");
  ASSERT_NE(end, std::string::npos) << direct;
  const std::string upto = direct.substr(0, direct.find('\n', end) + 1);
  const fs::path can = dir.write("part.can", upto);
  const std::string replayed = rs274_output(dir, can, "canterp.so");
  EXPECT_EQ(replayed, upto);
  EXPECT_NE(upto.find("ARC_FEED"), std::string::npos);
  EXPECT_NE(upto.find("SET_G5X_OFFSET(2"), std::string::npos);
}

TEST(CanonReplay, AnArcInTheXzPlaneKeepsYAndEndsWhereTheCallSays) {
  RecordingCanon canon;
  std::istringstream in(
      "1 N STRAIGHT_TRAVERSE(0 7 0 0 0 0)\n"
      "2 N SELECT_PLANE(CANON_PLANE_XZ)\n"
      "3 N ARC_FEED(-2, 4, -1, 2, 1, 7, 0, 0, 0)\n");
  replay_canon(in, "prog.can", canon);
  ASSERT_EQ(canon.segments.size(), 2u);
  const cnc::Pose end = canon.segments[1].end;
  EXPECT_DOUBLE_EQ(end.x(), 4.0);   // XZ: first axis Z, second X
  EXPECT_DOUBLE_EQ(end.z(), -2.0);
  EXPECT_DOUBLE_EQ(end.y(), 7.0);   // the normal's end
}

TEST(CanonReplay, BadLinesAreRefusedNamingFileLineAndWhatWasExpected) {
  std::vector<std::string> made;
  EXPECT_EQ(replay_error("0 N MIST_ON()\n0 N SET_TRAVERSE_RATE(3)\n", &made),
            "prog.can:2: unknown canonical call 'SET_TRAVERSE_RATE' (docs/interpreter.md, \"Canon replay\", lists the "
            "calls replayed)");
  EXPECT_EQ(made, std::vector<std::string>{"MIST_ON()"});  // the calls before the error were made
  EXPECT_EQ(replay_error("0 N STRAIGHT_FEED(1 2)\n"), "prog.can:1: STRAIGHT_FEED: expected 6 or 9 numbers, found 2");
  EXPECT_EQ(replay_error("0 N STRAIGHT_FEED(1 x 3 0 0 0)\n"),
            "prog.can:1: STRAIGHT_FEED: argument 2 'x' is not a number");
  EXPECT_EQ(replay_error("0 N SET_FEED_RATE(50\n"),
            "prog.can:1: expected two leading fields and then NAME(arguments), as rs274 -g prints a canonical call");
  EXPECT_EQ(replay_error("STRAIGHT_FEED(1 2 3 0 0 0)\n"),
            "prog.can:1: expected two leading fields and then NAME(arguments), as rs274 -g prints a canonical call");
  EXPECT_EQ(replay_error("0 N USE_LENGTH_UNITS(CANON_UNITS_FEET)\n"),
            "prog.can:1: USE_LENGTH_UNITS: expected CANON_UNITS_INCHES, CANON_UNITS_MM or CANON_UNITS_CM");
  EXPECT_EQ(replay_error("0 N SELECT_TOOL(2.5)\n"), "prog.can:1: SELECT_TOOL: the tool number must be a whole number");
  EXPECT_EQ(replay_error("0 N SET_G5X_OFFSET(10, 0 0 0 0 0 0)\n"),
            "prog.can:1: SET_G5X_OFFSET: the coordinate system must be 1 (G54) to 9 (G59.3)");
}

TEST(CanonReplay, Rs274RefusesPluginsOtherThanCanterp) {
  EXPECT_TRUE(cnc::interp::is_canon_replay_plugin("canterp.so"));
  EXPECT_TRUE(cnc::interp::is_canon_replay_plugin("./canterp.so"));
  EXPECT_TRUE(cnc::interp::is_canon_replay_plugin("/usr/lib/linuxcnc/canterp.so"));
  EXPECT_FALSE(cnc::interp::is_canon_replay_plugin("libmyinterp.so"));
  cnc::interp::Rs274Options o;
  o.program = "x.ngc";
  o.plugin = "libmyinterp.so";
  std::string error;
  EXPECT_THROW(cnc::interp::run_rs274(o, nullptr, error), std::runtime_error);
}
