// Parity with LinuxCNC 2.9's interpreter where this one moved the machine
// differently or refused programs LinuxCNC runs (issue 19). Each test runs a
// small program as `rs274 -g` does and checks the canonical calls (the
// values are what LinuxCNC 2.9's rs274 prints for the same program).
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <sstream>

#include "core/interp/rs274_run.hpp"
#include "tests/support/testing.hpp"

namespace fs = std::filesystem;
using cnc::interp::Rs274Options;

namespace {

struct Rs274Result {
  bool ok = false;
  std::string canon;  // calls without the running index, one a line
  std::string err;    // what went to stderr
};

// Runs `program` (written as test.ngc in a fresh folder, with `files`
// beside it) inside that folder; `setup` adjusts the options.
Rs274Result run(const std::string& program, const std::function<void(Rs274Options&, const cnc::testing::TempDir&)>& setup = {},
        const std::vector<std::pair<std::string, std::string>>& files = {}) {
  cnc::testing::TempDir dir;
  for (const auto& [name, text] : files) dir.write(name, text);
  dir.write("test.ngc", program);
  Rs274Options o;
  o.program = "test.ngc";
  if (setup) setup(o, dir);
  char* buf = nullptr;
  std::size_t size = 0;
  std::FILE* mem = open_memstream(&buf, &size);
  char* ebuf = nullptr;
  std::size_t esize = 0;
  std::FILE* emem = open_memstream(&ebuf, &esize);
  const fs::path back = fs::current_path();
  fs::current_path(dir.path());
  Rs274Result r;
  std::string error;
  try {
    r.ok = cnc::interp::run_rs274(o, mem, error, emem);
  } catch (const std::exception& e) {
    r.err = std::string("thrown: ") + e.what();
  }
  fs::current_path(back);
  std::fclose(mem);
  std::fclose(emem);
  std::istringstream in(std::string(buf, size));
  std::free(buf);
  r.err += std::string(ebuf, esize);
  std::free(ebuf);
  std::string line;
  while (std::getline(in, line)) {
    // "%5ld N..... CALL": drop the index as LinuxCNC's tests do
    const std::size_t n = line.find(" N");
    r.canon += (n == std::string::npos ? line : line.substr(n + 1)) + "\n";
  }
  return r;
}

bool has(const Rs274Result& r, const std::string& text) { return r.canon.find(text) != std::string::npos; }

}  // namespace

// ---------------------------------------------------------------- the tool

TEST(Rs274Tool, ContinueModeGoesOnAtTheTopLevelAfterTheOutermostCall) {
  const Rs274Result r = run("o<fail> call\no<fail> call\nM2\n",
                    [](Rs274Options& o, const cnc::testing::TempDir&) { o.on_error = 0; },
                    {{"fail.ngc", "o<fail> sub\n(debug, pre)\n#1 = [1/0]\n(debug, post)\no<fail> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  std::size_t count = 0;
  for (std::size_t p = r.canon.find("MESSAGE(\" pre\")"); p != std::string::npos; p = r.canon.find("MESSAGE(\" pre\")", p + 1)) ++count;
  EXPECT_EQ(count, 2u) << r.canon;
  EXPECT_FALSE(has(r, "post"));
  EXPECT_TRUE(has(r, "PROGRAM_END()"));
}

TEST(Rs274Tool, StopModeStopsAtTheFirstError) {
  const Rs274Result r = run("#1 = [1/0]\nG0 X1\nM2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(has(r, "STRAIGHT_TRAVERSE"));
  EXPECT_NE(r.err.find("Attempt to divide by zero"), std::string::npos) << r.err;
}

TEST(Rs274Tool, PrintStackNamesTheCallsInProgress) {
  const Rs274Result r = run("o<inner> sub\n#1 = [1/0]\no<inner> endsub\no<inner> call\nM2\n",
                    [](Rs274Options& o, const cnc::testing::TempDir&) { o.print_stack = true; });
  EXPECT_NE(r.err.find("o<inner> called at test.ngc:4"), std::string::npos) << r.err;
}

TEST(Rs274Tool, WithAnIniFileTheRunEndsWithOneResetAsLinuxCncClosesLazily) {
  const Rs274Result with_ini = run("G0 X1\nM2\n", [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.ini = d.write("t.ini", "[RS274NGC]\n");
  });
  const Rs274Result without = run("G0 X1\nM2\n");
  EXPECT_NE(with_ini.canon.find("PROGRAM_END()\nN..... ON_RESET()\n"), std::string::npos) << with_ini.canon;
  EXPECT_EQ(with_ini.canon.find("ON_RESET()\nN..... ON_RESET()"), std::string::npos) << with_ini.canon;
  EXPECT_NE(without.canon.find("PROGRAM_END()\nN..... ON_RESET()\nN..... ON_RESET()\n"), std::string::npos);
}

TEST(Rs274Tool, WithAnInchIniTheProgramStartsInMillimetresAsLinuxCncsRs274ButTheMachineIsInch) {
  // LinuxCNC's rs274 (saicanon) starts in G21 whatever [TRAJ]LINEAR_UNITS
  // says (remap/remap-reentry of its suite); #<_metric_machine> follows the INI
  const Rs274Result r = run("(debug, #<_metric> #<_metric_machine>)\nG0 X1\nM2\n",
                            [](Rs274Options& o, const cnc::testing::TempDir& d) {
                              o.ini = d.write("t.ini", "[TRAJ]\nLINEAR_UNITS = inch\n");
                            });
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "USE_LENGTH_UNITS(CANON_UNITS_MM)")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\" 1.000000 0.000000\")")) << r.canon;
}

TEST(Rs274Tool, TaskOptionMakesTheTaskParameterOne) {
  const Rs274Result preview = run("(debug, #<_task>)\nM2\n");
  const Rs274Result task = run("(debug, #<_task>)\nM2\n", [](Rs274Options& o, const cnc::testing::TempDir&) { o.task = true; });
  EXPECT_TRUE(has(preview, "MESSAGE(\" 0.000000\")")) << preview.canon;
  EXPECT_TRUE(has(task, "MESSAGE(\" 1.000000\")")) << task.canon;
}

// ---------------------------------------------------------------- expressions

TEST(InterpParity, ExistsOfANumberedParameterTellsWhetherTheNumberIsInRange) {
  const Rs274Result r = run("#<a>=999\nG0 X EXISTS[#1] Y EXISTS[#99999] Z EXISTS[#<a>] A EXISTS[#<b>]\n#1=2\n"
                            "G0 X EXISTS[##1]\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_TRAVERSE(1.0000, 0.0000, 1.0000, 0.0000, 0.0000, 0.0000)")) << r.canon;
  EXPECT_FALSE(run("G0 X EXISTS[1]\nM2\n").ok);
}

// ---------------------------------------------------------------- arcs

TEST(InterpParity, CenterArcWithinLinuxCncsRadiusToleranceRuns) {
  // r1 = 5.004, r2 = 4.996: 0.008 mm apart, inside 2 * 0.01 mm * sqrt(2)
  const Rs274Result r = run("G21 G17 F100\nG2 X10 I5.004\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(10.0000, 0.0000, 5.0040, 0.0000, -1, 0.0000")) << r.canon;
}

TEST(InterpParity, ArcRadiusToleranceComesFromTheIniWithinLinuxCncsBounds) {
  const auto tight = [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.ini = d.write("t.ini", "[RS274NGC]\nCENTER_ARC_RADIUS_TOLERANCE_MM = 0.005\n");
  };
  const Rs274Result r = run("G21 G17 F100\nG2 X10 I5.004\nM2\n", tight);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("Radius to end of arc differs from radius to start"), std::string::npos) << r.err;
  // Above LinuxCNC's default (its upper bound) is a configuration error.
  const Rs274Result loose = run("M2\n", [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.ini = d.write("t.ini", "[RS274NGC]\nCENTER_ARC_RADIUS_TOLERANCE_MM = 0.5\n");
  });
  EXPECT_NE(loose.err.find("CENTER_ARC_RADIUS_TOLERANCE_MM"), std::string::npos) << loose.err;
}

// ---------------------------------------------------------------- comments

TEST(InterpParity, AbortCommentStopsTheProgramWithItsExpandedText) {
  const Rs274Result r = run("#42=20\nG0 X1\n(abort, stop here #42)\nG0 X2\nM2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find(" stop here 20.000000"), std::string::npos) << r.err;
  EXPECT_FALSE(has(r, "STRAIGHT_TRAVERSE(2.0000"));
  EXPECT_FALSE(has(r, "PROGRAM_END"));
}

TEST(InterpParity, DebugCommentsTakePrintfStyleFormats) {
  const Rs274Result r = run("#<v> = 1.123456789\n#<w> = 2.3456789\n(debug,a %d#<v>)\n(debug,b %f#<v> #<w>)\n"
                            "(debug,c %.7f#<v>)\n(debug,d #<v> %d#<w>)\n(debug,e #<nope>)\n#5599=0\n(debug,off)\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\"a 1\")")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"b 1.1235 2.3457\")")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"c 1.1234568\")")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"d 1.123457 2\")")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"e ######\")")) << r.canon;
  EXPECT_FALSE(has(r, "off")) << r.canon;
}

// ---------------------------------------------------------------- O-words

TEST(InterpParity, ValueReadsZeroBeforeAnySubroutineReturned) {
  const Rs274Result r = run("(debug,#<_value> #<_value_returned>)\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\"0.000000 0.000000\")")) << r.canon;
}

TEST(InterpParity, OWordLabelMayBeAParameterOrExpression) {
  const Rs274Result r = run("o2 sub\nG0 X2\no2 endsub\no<outer> sub\n#<sub> = 2\no#<sub> call\no<outer> endsub\n"
                            "o<outer> call\n#7 = 2\no[#7] call\no002 call\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  std::size_t count = 0;
  for (std::size_t p = r.canon.find("STRAIGHT_TRAVERSE(2.0000"); p != std::string::npos;
       p = r.canon.find("STRAIGHT_TRAVERSE(2.0000", p + 1)) {
    ++count;
  }
  EXPECT_EQ(count, 3u) << r.canon;
}

// ---------------------------------------------------------------- M19

TEST(InterpParity, SpindleOrientAddsTheIniOffsetAndQWaitsForTheSpindle) {
  const auto ini = [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.ini = d.write("t.ini", "[RS274NGC]\nORIENT_OFFSET = 42.0\n");
  };
  const Rs274Result r = run("M19 R45 Q2\nM19 P1\nM19 Q1\nM2\n", ini);
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_NE(r.canon.find("ORIENT_SPINDLE(0, 87.0000, 0)\nN..... SPINDLE.0.WAIT_ORIENT_COMPLETE(2.0000)\n"
                         "N..... ORIENT_SPINDLE(0, 42.0000, 1)\nN..... SPINDLE.0.WAIT_ORIENT_COMPLETE(1.0000)\n"),
            std::string::npos)
      << r.canon;
  EXPECT_FALSE(run("M19 R10 Q0\nM2\n").ok);
  EXPECT_FALSE(run("M19 P3\nM2\n").ok);
  EXPECT_FALSE(run("M19 R361\nM2\n").ok);
}

// ---------------------------------------------------------------- units and offsets

TEST(InterpParity, FeedParameterKeepsTheProgrammedNumberAcrossUnitChanges) {
  const Rs274Result r = run("G20\nG21 F250\n(debug,#<_feed>)\nG20 F10\n(debug,#<_feed>)\nG21\nM73\n"
                            "F33\nM72\n(debug,#<_feed>)\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\"250.000000\")")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"10.000000\")")) << r.canon;
  EXPECT_TRUE(has(r, "SET_FEED_RATE(33.0000)\nN..... SET_FEED_RATE(10.0000)\nN..... MESSAGE(\"10.000000\")")) << r.canon;
  EXPECT_FALSE(has(r, "6350")) << r.canon;
  EXPECT_FALSE(has(r, "0.3937")) << r.canon;
}

TEST(InterpParity, RotaryAxisOffsetsAreDegreesWhateverTheLengthUnits) {
  // Machine units are inches (as rs274); the program works in mm.
  const Rs274Result r = run("G21\nG10 L2 P1 X1 A10\nG92 B5\n(debug,#5221 #5224 #5215)\nG0 A0\nM2\n",
                            [](Rs274Options& o, const cnc::testing::TempDir& d) {
                              o.parameter_file = d.write("t.var", "5225\t3.000000\n");
                            });
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "SET_G5X_OFFSET(1, 0.0000, 0.0000, 0.0000, 0.0000, 3.0000, 0.0000)")) << r.canon;
  EXPECT_TRUE(has(r, "SET_G5X_OFFSET(1, 1.0000, 0.0000, 0.0000, 10.0000, 3.0000, 0.0000)")) << r.canon;
  EXPECT_TRUE(has(r, "SET_G92_OFFSET(0.0000, 0.0000, 0.0000, 0.0000, -8.0000, 0.0000)")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"0.039370 10.000000 -8.000000\")")) << r.canon;
}

TEST(InterpParity, DisabledG92PersistenceClearsTheG92ParametersAtStartAndEnd) {
  const auto ini = [](bool disable) {
    return [disable](Rs274Options& o, const cnc::testing::TempDir& d) {
      o.parameter_file = d.write("t.var", "5210\t1.000000\n5211\t1.000000\n");
      o.ini = d.write("t.ini", std::string("[RS274NGC]\nDISABLE_G92_PERSISTENCE = ") + (disable ? "1" : "0") + "\n");
    };
  };
  const Rs274Result kept = run("(debug,#5210 #5211)\nM2\n", ini(false));
  const Rs274Result cleared = run("(debug,#5210 #5211)\nG92 X1\nM2\n", ini(true));
  EXPECT_TRUE(has(kept, "SET_G92_OFFSET(25.4000,")) << kept.canon;
  EXPECT_TRUE(has(kept, "MESSAGE(\"1.000000 1.000000\")")) << kept.canon;
  EXPECT_TRUE(has(cleared, "SET_G92_OFFSET(0.0000, 0.0000")) << cleared.canon;
  EXPECT_TRUE(has(cleared, "MESSAGE(\"0.000000 0.000000\")")) << cleared.canon;
}

// ---------------------------------------------------------------- rotated systems

TEST(InterpParity, G10L20InARotatedSystemMovesTheOriginAlongTheRotatedAxis) {
  const Rs274Result r = run("G20\nG10 L2 P1 R45\nG0 X0 Y0\nG10 L20 P1 X-1\n(debug,#5420 #5421)\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "SET_G5X_OFFSET(1, 0.7071, 0.7071, 0.0000")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\"-1.000000 0.000000\")")) << r.canon;
}

TEST(InterpParity, LeavingARotatedSystemWithG92KeepsTheMachinePoint) {
  // G55 turned 45 degrees, a G92 offset, then G56: "G0 A1" moves only A.
  const Rs274Result r = run("g10 l2 p2 x0 y0 z0 r45\ng10 l2 p3 x0 y0 z0 r0\ng55\ng53 g0 x1 y1\ng92 x0 y0\ng56\ng0 a1\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_TRAVERSE(-0.4142, 1.0000, 0.0000, 1.0000, 0.0000, 0.0000)")) << r.canon;
}

TEST(InterpParity, ToolOffsetChangeInARotatedSystemKeepsTheMachinePoint) {
  const Rs274Result r = run("G20\nG10 L2 P1 R45\nG0 X1 Y0\nG43.1 X-0.7071068 Y-0.7071068\n(debug,#5420 #5421)\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\"2.000000 0.000000\")")) << r.canon;
}

TEST(InterpParity, G10L1OfTheSpindlesToolIndexAlsoWritesTheSpindleEntry) {
  // rs274's simulated machine reports tooldata index 1 in the spindle at start.
  const Rs274Result r = run("G20 G10 L1 P1 Z1\nM2\n", [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.tool_table = d.write("t.tbl", "T1 P1 Z0\nT2 P2 Z0\n");
  });
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "SET_TOOL_TABLE_ENTRY(1, 1, 0.0000 0.0000 1.0000")) << r.canon;
  EXPECT_TRUE(has(r, "SET_TOOL_TABLE_ENTRY(0, 1, 0.0000 0.0000 1.0000")) << r.canon;
  EXPECT_FALSE(run("G10 L1 P1\nM2\n", [](Rs274Options& o, const cnc::testing::TempDir& d) {
                 o.tool_table = d.write("t.tbl", "T1 P1 Z0\n");
               }).ok);
}

// ---------------------------------------------------------------- REMAP

namespace {
std::function<void(Rs274Options&, const cnc::testing::TempDir&)> with_ini(std::string text) {
  return [text](Rs274Options& o, const cnc::testing::TempDir& d) { o.ini = d.write("t.ini", text); };
}
}  // namespace

TEST(InterpRemap, RemappedMCodeCallsItsSubroutineWithTheArgspecWordsAsNamedParameters) {
  const Rs274Result r = run("M400 P2.5\nM2\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\nREMAP=M400 modalgroup=10 argspec=Pq ngc=rm400\n"),
                            {{"rm400.ngc", "o<rm400> sub\n#<e> = EXISTS[#<q>]\n(debug, p=#<p> q=#<e> level=#<_remap_level>)\n"
                                           "o<rm400> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\" p=2.500000 q=0.000000 level=1.000000\")")) << r.canon;
}

TEST(InterpRemap, TheBlockGoesOnAfterTheProcedureFromTheRemappedCodesStep) {
  // M400 (group 10) runs after F and before the motion; the move and M30 follow it.
  const Rs274Result r = run("G0 X1 F50 M400 M30\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\nREMAP=M400 ngc=rm400\n"),
                            {{"rm400.ngc", "o<rm400> sub\n(debug, in rm400)\no<rm400> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  const std::size_t feed = r.canon.find("SET_FEED_RATE(50.0000)");
  const std::size_t msg = r.canon.find("MESSAGE(\" in rm400\")");
  const std::size_t move = r.canon.find("STRAIGHT_TRAVERSE(1.0000");
  const std::size_t end = r.canon.find("PROGRAM_END()");
  ASSERT_NE(msg, std::string::npos) << r.canon;
  EXPECT_LT(feed, msg);
  EXPECT_LT(msg, move);
  EXPECT_NE(move, std::string::npos) << r.canon;
  EXPECT_LT(move, end);
  EXPECT_NE(end, std::string::npos);
}

TEST(InterpRemap, AMissingRequiredWordIsAnErrorNamingTheCodeAndTheWords) {
  const Rs274Result r = run("M400 P1\nM2\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\nREMAP=M400 modalgroup=5 argspec=PQR ngc=rm400\n"),
                            {{"rm400.ngc", "o<rm400> sub\no<rm400> endsub\nM2\n"}});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("user-defined M400: missing: Q,R"), std::string::npos) << r.err;
}

TEST(InterpRemap, RemappedGCodeWithAtGetsItsWordsPositionallyAndConsumesTheAxisWords) {
  const Rs274Result r = run("G88.1 X1 Z3 Q5\nM2\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\nOWORD_NARGS = 1\n"
                                     "REMAP=G88.1 argspec=@xyzpq ngc=rg881\n"),
                            {{"rg881.ngc", "o<rg881> sub\n(debug, n=#<n_args> #1 #2 #3)\no<rg881> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\" n=3.000000 1.000000 3.000000 5.000000\")")) << r.canon;
  EXPECT_FALSE(has(r, "STRAIGHT_"));
}

TEST(InterpRemap, TheRemappedCodeInsideItsOwnProcedureIsTheBuiltIn) {
  const Rs274Result r = run("T0 M6\nM2\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\nREMAP=M6 ngc=change\n"),
                            {{"change.ngc", "o<change> sub\n(debug, changing)\nM6\no<change> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\" changing\")")) << r.canon;
  std::size_t count = 0;
  for (std::size_t p = r.canon.find("CHANGE_TOOL("); p != std::string::npos; p = r.canon.find("CHANGE_TOOL(", p + 1)) ++count;
  EXPECT_EQ(count, 1u) << r.canon;
}

TEST(InterpRemap, PrologAndEpilogSubroutinesRunAroundTheBodyWithTheSameArguments) {
  const Rs274Result r = run("M401 P7\nM2\n",
                            with_ini("[RS274NGC]\nSUBROUTINE_PATH = .\n"
                                     "REMAP=M401 argspec=P prolog=pre ngc=body epilog=post\n"),
                            {{"pre.ngc", "o<pre> sub\n(debug, pre #<p>)\n#<_shared> = 1\no<pre> endsub\nM2\n"},
                             {"body.ngc", "o<body> sub\n(debug, body #<p> #<_shared>)\no<body> endsub\nM2\n"},
                             {"post.ngc", "o<post> sub\n(debug, post #<p>)\no<post> endsub\nM2\n"}});
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "MESSAGE(\" pre 7.000000\")\nN..... MESSAGE(\" body 7.000000 1.000000\")\n"
                     "N..... MESSAGE(\" post 7.000000\")")) << r.canon;
}

TEST(InterpRemap, PythonProceduresWithoutAPythonSectionAreRefusedAtLoadNamingTheIniFileAndLine) {
  const Rs274Result py = run("M2\n", with_ini("[RS274NGC]\n\nREMAP=M500 py=m500\n"));
  EXPECT_FALSE(py.ok);
  EXPECT_NE(py.err.find("t.ini:3"), std::string::npos) << py.err;
  EXPECT_NE(py.err.find("a Python remap procedure needs [PYTHON]"), std::string::npos) << py.err;
  const Rs274Result prolog = run("M2\n", with_ini("[RS274NGC]\nREMAP=M500 prolog=setup ngc=x\n"));
  EXPECT_FALSE(prolog.ok);
  EXPECT_NE(prolog.err.find("t.ini:2"), std::string::npos) << prolog.err;
  EXPECT_NE(prolog.err.find("without [PYTHON] it cannot be a Python function"), std::string::npos) << prolog.err;
  const Rs274Result builtin = run("M2\n", with_ini("[RS274NGC]\nREMAP=M3 ngc=x\n"));
  EXPECT_FALSE(builtin.ok);
  EXPECT_NE(builtin.err.find("built-in M code"), std::string::npos) << builtin.err;
}

// ---------------------------------------------------------------- M98/M99

TEST(InterpFanucSubs, M98RunsTheSubprogramLTimesSharingTheNumberedParameters) {
  const Rs274Result r = run("#1 = 0\nM98 P0100 L3\n(debug, main #1)\nM98 P100 L0\nM30\n"
                            "O100 (numbered subprogram)\n#1 = [#1 + 1]\nG0 X#1\nM99\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_TRAVERSE(3.0000")) << r.canon;
  EXPECT_TRUE(has(r, "MESSAGE(\" main 3.000000\")")) << r.canon;
  EXPECT_FALSE(has(r, "STRAIGHT_TRAVERSE(4.0000")) << r.canon;
}

TEST(InterpFanucSubs, M99InTheMainProgramEndsItAndInTheTaskStartsItAgain) {
  const std::string prog = "#100 = [#100 + 1]\no1 if [#100 GT 2]\nM30\no1 endif\nG0 X#100\nM99\n";
  const Rs274Result preview = run(prog);
  EXPECT_TRUE(preview.ok) << preview.err;
  EXPECT_TRUE(has(preview, "STRAIGHT_TRAVERSE(1.0000")) << preview.canon;
  EXPECT_FALSE(has(preview, "STRAIGHT_TRAVERSE(2.0000")) << preview.canon;
  EXPECT_TRUE(has(preview, "PROGRAM_END()"));
  const Rs274Result task = run(prog, [](Rs274Options& o, const cnc::testing::TempDir&) { o.task = true; });
  EXPECT_TRUE(task.ok) << task.err;
  EXPECT_TRUE(has(task, "STRAIGHT_TRAVERSE(2.0000")) << task.canon;
  EXPECT_TRUE(has(task, "PALLET_SHUTTLE()")) << task.canon;  // the M30 of the third pass
}

TEST(InterpFanucSubs, TheTwoSubroutineStylesAreNotMixed) {
  const Rs274Result call_fanuc = run("O1 call\nM30\nO1\nM99\n");
  EXPECT_NE(call_fanuc.err.find("Fanuc 'O....' subroutine must be called with 'M98'"), std::string::npos) << call_fanuc.err;
  const Rs274Result m98_sub = run("M98 P1\nM30\nO1 sub\nO1 endsub\n");
  EXPECT_NE(m98_sub.err.find("'O.... sub' subroutine must be called with 'O.... call'"), std::string::npos) << m98_sub.err;
  const Rs274Result endsub = run("M98 P1\nM30\nO1\nO1 endsub\n");
  EXPECT_NE(endsub.err.find("Fanuc 'O....' subroutine definition must end with 'M99'"), std::string::npos) << endsub.err;
  const Rs274Result m99 = run("O1 call\nM30\nO1 sub\nM99\n");
  EXPECT_NE(m99.err.find("'O.... endsub' or 'O.... return' must follow"), std::string::npos) << m99.err;
  const Rs274Result no_p = run("M98\nM30\n");
  EXPECT_NE(no_p.err.find("Found 'm98' code with no P-word"), std::string::npos) << no_p.err;
}

TEST(InterpFanucSubs, DisableFanucStyleSubRefusesM98) {
  const Rs274Result r = run("M98 P1\nM30\nO1\nM99\n", with_ini("[RS274NGC]\nDISABLE_FANUC_STYLE_SUB = 1\n"));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("DISABLE_FANUC_STYLE_SUB set in INI file, but found m98"), std::string::npos) << r.err;
}

TEST(InterpFanucSubs, TheSearchStopsAtTheClosingPercentButGoesOnInTheSubroutineFiles) {
  const Rs274Result after_percent = run("%\nM98 P7\nM30\n%\nO7\nM99\n");
  EXPECT_FALSE(after_percent.ok);
  EXPECT_NE(after_percent.err.find("Failed to find sub 'O7' before EOF"), std::string::npos) << after_percent.err;
  EXPECT_TRUE(has(after_percent, "FINISH()")) << after_percent.canon;
  const Rs274Result in_file = run("%\no<lib> call\nM30\n%\n", {}, {{"lib.ngc", "o<lib> sub\n(debug, lib)\no<lib> endsub\nM2\n"}});
  EXPECT_TRUE(in_file.ok) << in_file.err;
  EXPECT_TRUE(has(in_file, "MESSAGE(\" lib\")")) << in_file.canon;
}

// ---------------------------------------------------------------- cutter compensation

TEST(InterpCutterComp, InverseTimeFeedsOfCompensatedMovesComeFromTheProgrammedMove) {
  // G93 with compensation on: the rate is F times the programmed length,
  // set before each move, as with compensation off.
  const auto r = run("g20 g0 x0 y0 z0\ng42.1 d0.4\ng93 g1 x1 f30\ny1 f20\nx-1 f20\ng94 g40 g1 x-2 f25\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "SET_FEED_RATE(30.0000)\nN..... STRAIGHT_FEED(1.0000, -0.2000,")) << r.canon;
  EXPECT_TRUE(has(r, "SET_FEED_RATE(20.0000)\nN..... ARC_FEED(")) << r.canon;
  EXPECT_TRUE(has(r, "SET_FEED_RATE(40.0000)\nN..... ARC_FEED(")) << r.canon;
}

TEST(InterpCutterComp, ArcAsTheMoveRightAfterG40IsRefused) {
  const auto r = run("g0 x0 y0 z0\ng41.1 d.5\ng1 x1 f1\ng1 x2\ng40\ng2 i1\nm2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("The move just after exiting cutter compensation mode must be straight, not an arc"), std::string::npos)
      << r.err;
  // a straight move in between (even Z only) ends the exit
  const auto ok = run("g0 x0 y0 z0\ng41.1 d.5\ng1 x1 f1\ng1 x2\ng40\ng0 z1\ng2 i1\nm2\n");
  EXPECT_TRUE(ok.ok) << ok.err;
}

TEST(InterpCutterComp, ConcaveCornerAfterAMoveShorterThanTheToolRadiusIsAGouge) {
  // The Y move is 0.1 long with a 0.25 radius tool: its offset would have
  // to run backwards to meet the next move.
  const auto r = run("g0 x0 y0 z0\ng41.1 d.5\ng1 x1 f1\ng1 x2\ng1 y.1\ng1 x1\ng40\ng1 x2\nm2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("Straight feed in concave corner cannot be reached by the tool without gouging"), std::string::npos)
      << r.err;
}

TEST(InterpCutterComp, EntryArcEndsOffsetAboutACentreAsFarFromTheToolAsFromItsEnd) {
  // From the tool at (0.25, 0.5) a CW arc about (0.5, 0.5) to (0.5, 0.75),
  // tool radius 0.1 on the left (outside): the tool ends at (0.5, 0.85)
  // about (0.5, 0.5857), as LinuxCNC 2.9 cuts it.
  const auto r = run("g20 f60\ng0 x0 y.5 z.25\ng1 x.25\ng41.1 d.2 g2 x.5 y.75 i.25\ng1 x.75\ng40 x1\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(0.5000, 0.8500, 0.5000, 0.5857, -1, 0.2500,")) << r.canon;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(0.7500, 0.8500, 0.2500,")) << r.canon;
  // inside the arc (right side)
  const auto in = run("g20 f60\ng0 x0 y.5 z.25\ng1 x.25\ng42.1 d.2 g2 x.5 y.75 i.25\ng1 x.75\ng40 x1\nm2\n");
  ASSERT_TRUE(in.ok) << in.err;
  EXPECT_TRUE(has(in, "ARC_FEED(0.5000, 0.6500, 0.5000, 0.3667, -1, 0.2500,")) << in.canon;
  // the tool must start farther than its radius from the arc's end
  const auto near = run("g20 f60\ng0 x0 y.5 z.25\ng1 x.25\ng41.1 d1.2 g2 x.5 y.75 i.25\nm2\n");
  EXPECT_FALSE(near.ok);
  EXPECT_NE(near.err.find("Radius of cutter compensation entry arc is not greater than the tool radius"), std::string::npos)
      << near.err;
}

TEST(InterpCutterComp, ExitMoveKeepsTheProgrammedPositionOfAxesItDoesNotName) {
  // G40 X1 after a move along Y 0.75 (tool offset to Y 0.85): the exit
  // move ends at the programmed Y 0.75, not at the tool's Y.
  const auto r = run("g20 f60\ng0 x0 y.75 z0\ng41.1 d.2 g1 x.5\ng1 x.75\ng40 x1\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(1.0000, 0.7500, 0.0000,")) << r.canon;
}

TEST(InterpCutterComp, ConvexCornerTurningLessThanFiftyMilliradiansGetsNoArc) {
  // X10 Y1 to X20 Y0.51: a 0.049 rad right turn with the tool on the left.
  const auto r = run("g21 g0 x-10 y0 z0\ng41.1 d2 g1 x0 y1 f100\ng1 x10\ng1 x20 y0.51\ng40 g1 x30\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(10.0000, 2.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(20.0489, 1.5088,")) << r.canon;
}

TEST(InterpCutterComp, LineLeavingAnArcsEndBackwardsAwayFromTheToolIsAConcaveCorner) {
  // The CCW arc ends going -Y at its left end; the line goes back +Y with
  // the tool on its right, between the line and the arc: the two offset
  // paths meet (LinuxCNC's inside-corners), no turn around the corner.
  const auto r = run("g20 g0 x3 y2.845 z0\ng42.1 d.15 g1 x2.2708 f8\ng3 x1.8296 i-.2206\ng1 y3.56\ng40 g1 x1\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(1.9046, 3.1023, 2.0502, 2.8450, 1, 0.0000,")) << r.canon;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(1.9046, 3.5600,")) << r.canon;
}

TEST(InterpCutterComp, ArcWithSlightlyDifferentEndRadiusEndsBesideItsProgrammedEnd) {
  // Centre-format arcs whose end radius differs within the tolerance: with
  // a zero radius tool the tool path is the program, no corner arcs.
  const auto r = run("g20 g0 x1.2281 y1.3456 z0\ng41.1 d0 g1 x1.2281 y1.3457 f8\n"
                     "g2 x0.1253 y0.9881 i-0.6093 j-0.0001\ng3 x0.7669 y1.4548 i0.2437 j0.3394\ng40 g1 x1\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(0.1253, 0.9881, 0.6188, 1.3456, -1, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(0.7669, 1.4548, 0.3690, 1.3275, 1,")) << r.canon;
}

TEST(InterpCutterComp, SharpCornerIntoAnArcWhoseOffsetsDoNotMeetTurnsAroundTheCorner) {
  // A line then a tight CW arc leaving it almost backwards, tool on the
  // right: the tangents call it concave but the offset paths never meet;
  // LinuxCNC turns around the corner (its crazy-paths) instead of an error.
  const auto r = run("g21 g0 x-42 y-104.657107 z0\ng42.1 d.5 g1 x-39.500873 f100\ng1 x-54.500873 y-94.657107\n"
                     "g2 i-1.575966 j-2.552711 x-57.872219 y-99.613276\ng40 g1 x-62.872219 y-114.613276\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(-54.3622, -94.4491, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(-54.6322, -94.8698, -54.5009, -94.6571, 1,")) << r.canon;
}

// Cutter compensation computed step by step as LinuxCNC 2.9 computes it:
// the printed output rounds to 4 decimals, so another (equally exact) way
// of computing lands on the other side of a rounding tie or 1e-4 away.

namespace {
auto tool_table(const std::string& text) {
  return [text](Rs274Options& o, const cnc::testing::TempDir& d) { o.tool_table = d.write("t.tbl", text); };
}
}  // namespace

TEST(InterpCutterComp, ArcEndOnARoundingTieRoundsAsInLinuxCnc) {
  // LinuxCNC's cam-nisley: a 0.0625 in tool in a G21 program has the radius
  // (0.0625 / 0.03937007874016) / 2 (saicanon's inch), the G91 arc's end
  // moves out by it along the radius's angle: -11.28125 prints -11.2813.
  const auto r = run("g21 g90 f100\nt1 m6\ng0 x-1.6 y-13.675 z0\ng42 d1\ng1 x-1.6 y-10.475\ng2 x0 y-8.875 i1.6 j0\n"
                     "g3 y-8.875 j8.875\ng91 g2 y-3.2 j-1.6\ng90 g40 g1 x-5\nm2\n",
                     tool_table("T1 P1 Z0.5 D0.0625\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(-0.8063, -10.4750, 0.0000,")) << r.canon;
  EXPECT_TRUE(has(r, "ARC_FEED(0.0000, -9.6687, 0.0000, -10.4750, -1,")) << r.canon;
  EXPECT_TRUE(has(r, "ARC_FEED(0.0000, -11.2813, 0.0000, -10.4750, -1,")) << r.canon;
}

TEST(InterpCutterComp, EntryArcCentreOnARoundingTieRoundsAsInLinuxCnc) {
  // LinuxCNC's ccomp/mill-zchanges: the entry arc's centre 0.55625 prints
  // 0.5562 (LinuxCNC finds it along the new end's radius by the half chord
  // over the cosine of the angle between them).
  const auto r = run("g20 f60\ng0 x0 y.5 z.25\ng1 x.25 z0\ng41 g2 d2 x.5 y.75 i.25\ng1 x.75\ng40 x1\nm2\n",
                     tool_table("T1 P1 Z0.5 D0.0625\nT2 P2 Z0.7 D0.125\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(0.5000, 0.8125, 0.5000, 0.5562, -1,")) << r.canon;
}

TEST(InterpCutterComp, ConcaveCornerIntoAnArcWithDifferentEndRadiusMeetsItsEndCircle) {
  // LinuxCNC's interp/inside-corners: a concave arc-to-arc corner where the
  // next arc's start and end radii differ within the tolerance; LinuxCNC
  // offsets the circle through the arc's end, not through its start.
  const auto r = run("g20 g0 x0 y0 z0\ng41.1 d-.15 g1 x0.6767 y0.2334 f8\ng1 x0.3359 y0.4419\n"
                     "g3 x1.2281 y1.3456 i0.2921 j0.6039\ng2 x0.1253 y0.9881 i-0.6093 j0\n"
                     "g3 x0.7669 y1.4548 i0.2437 j0.3394\ng40 g1 x0 y2\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(1.1531, 1.3456, 1.2281, 1.3456, 1, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(0.4443, 0.8405, 0.6188, 1.3456, -1,")) << r.canon;
  EXPECT_TRUE(has(r, "ARC_FEED(0.8383, 1.4777, 0.3690, 1.3275, 1,")) << r.canon;
}

TEST(InterpCutterComp, NearReversalFromATightArcIntoALineMeetsTheOffsetPaths) {
  // LinuxCNC's interp/crazy-paths: a line leaving a tight CW arc almost
  // backwards, tool on the left: a concave corner where the arc's offset
  // circle meets the line's offset, no arc around the corner.
  const auto r = run("g21 f100\ng0 x-50 y-100 z0\ng41.1 d.5\ng1 y-102\n"
                     "g2 i4.980439 j-0.441843 x-40.097651 y-103.322073\ng2 i-0.682919 j-1.106175 x-39.500873 y-104.657107\n"
                     "g1 x-54.500873 y-94.657107\ng2 i-1.575966 j-2.552711 x-57.872219 y-99.613276\n"
                     "g40 g1 x-62.872219 y-114.613276\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(-39.6395, -104.8651, -39.5009, -104.6571, -1, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(-53.1089, -95.8856, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(-58.0218, -99.8136, -56.0768, -97.2098, -1,")) << r.canon;
}

TEST(InterpCutterComp, LatheToolOrientationMovesTheToolOriginOffTheNoseCentre) {
  // LinuxCNC's ccomp/lathe-comp: orientation 2 (front, tip toward -X -Z):
  // what the machine positions is the nose centre less the radius in X and Z.
  const auto r = run("g20 g18 f30\ng0 x.3 z0\nt2 m6\ng43 h2\ng41\ng1 x.1\ng3 x0 z.1 r.1\ng1 z1\ng40\ng0 x.3\nm2\n",
                     tool_table("T2 P2 Z0 X0 D0.1 Q2\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(0.0500, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(0.0500, 0.0000, 0.0500, 0.0500, 1, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(0.0000, 0.0000, 0.9500,")) << r.canon;
}

TEST(InterpCutterComp, LatheToolOutsideTheLathePlaneIsRefused) {
  const auto r = run("g17 g41 d2\nm2\n", tool_table("T2 P2 Z0 X0 D0.1 Q2\n"));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("G41 with lathe tool, but plane is not G18"), std::string::npos) << r.err;
}

TEST(InterpCutterComp, HeldBackArcWhoseEndAConcaveCornerMovesPastItsStartIsAGouge) {
  // A short CW arc with the tool outside it, then a line turning back
  // sharply: the corner would move the arc's end back past its start, so
  // the arc would sweep almost a full turn (LinuxCNC refuses it).
  const auto r = run("g21 g0 x-20 y0 z0\ng41.1 d2 g1 x0 y0 f100\ng2 x1 y-0.1 r10\ng1 x-10 y5\ng40 g1 x-20 y20\nm2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("Arc move in concave corner cannot be reached by the tool without gouging"), std::string::npos) << r.err;
  EXPECT_FALSE(has(r, "ARC_FEED(")) << r.canon;
}

TEST(InterpCutterComp, ZeroRadiusCompensatesNothingAndAllowsAnArcAfterG40) {
  const auto r = run("g21 g0 x0 y0 z0\ng41.1 d0 g1 x10 y0 f100\ng1 x10 y10\ng3 x0 y10 r5\ng40\ng2 x0 y0 r5\nm2\n");
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(10.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(10.0000, 10.0000, 0.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... ARC_FEED(0.0000, 10.0000, 5.0000, 10.0000, 1,")) << r.canon;
  EXPECT_TRUE(has(r, "ARC_FEED(0.0000, 0.0000, -0.0000, 5.0000, -1,")) << r.canon;
}

TEST(InterpCutterComp, AfterG40TheProgrammedPositionFollowsAToolLengthOffsetChange) {
  // LinuxCNC's gmoccapy demo: after G40 the current point is the programmed
  // one, so a new tool length offset (50.8 to 20.32 mm) and the re-read
  // after M1 move it: Z30 becomes Z60.48 for the next move.
  const auto r = run("g17 g21 g90\nt3 m6\ng43\ng0 x50 y50 z30\ng41\ng3 x70 y50 z-1 i10 j0 f100\ng0 z30\ng40\n"
                     "t1 m6\ng43\nm1\ng0 x50 y50\nm2\n",
                     tool_table("T1 P3 Z0.8 D0.5\nT3 P2 Z2 D0.375\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "ARC_FEED(65.2375, 50.0000, 57.6188, 50.0000, 1, -1.0000,")) << r.canon;
  EXPECT_TRUE(has(r, "STRAIGHT_TRAVERSE(50.0000, 50.0000, 60.4800,")) << r.canon;
}

TEST(InterpCutterComp, ProgramEndSendsTheHeldBackMoveBeforeTheResets) {
  const auto r = run("g21 g17 g90\nt3 m6\ng0 x50 y50 z30\nm8\ng41 g1 x60 y50 f100\ng1 x60 y60\nm2\n",
                     tool_table("T3 P3 Z2 D0.375\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(55.2375, 60.0000, 30.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... SET_G5X_OFFSET(1,")) << r.canon;
}

TEST(Rs274Tool, TextCanonTracksItsPositionWithSaicanonsArithmetic) {
  // rs274's saicanon divides by 25.4 at G20 and adds the old offset before
  // subtracting the new one; after a probe the interpreter reads that
  // position back, so its residue shows as -0.0000 (LinuxCNC's x-trim.ngc).
  const auto r = run("g20\ng92 x0 y0\nf10\ng38.2 z-1.75\ng1 z0.1\nm2\n", [](Rs274Options& o, const cnc::testing::TempDir& d) {
    o.parameter_file = d.write("p.var", "5210\t1.000000\n5211\t0.125000\n5212\t-0.250000\n5213\t0.500000\n"
                                        "5220\t1.000000\n5221\t2.000000\n5222\t1.000000\n5223\t-0.500000\n");
  });
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(0.0000, -0.0000, 0.1000, 0.0000, 0.0000, 0.0000)")) << r.canon;
}

// ---------------------------------------------------------------- spindles ($)

TEST(InterpSpindles, TheDollarWordChoosesTheSpindleOfSAndM3M4M5AndMinusOneMeansAll) {
  // LinuxCNC 2.9's rs274 with [TRAJ]SPINDLES=3 prints these calls; before,
  // every $ went to spindle 0 (S2000 $1 changed the first spindle's speed)
  const Rs274Result r = run("S100 $-1\nM3 $-1\nS7 $2\nM5 $1\nS2000 $1\nM4 $1\nM2\n", with_ini("[TRAJ]\nSPINDLES=3\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "N..... SET_SPINDLE_SPEED(0, 100.0000)\nN..... SET_SPINDLE_SPEED(1, 100.0000)\n"
                     "N..... SET_SPINDLE_SPEED(2, 100.0000)\nN..... START_SPINDLE_CLOCKWISE(0)\n"
                     "N..... START_SPINDLE_CLOCKWISE(1)\nN..... START_SPINDLE_CLOCKWISE(2)\n"
                     "N..... SET_SPINDLE_SPEED(2, 7.0000)\nN..... STOP_SPINDLE_TURNING(1)\n"
                     "N..... SET_SPINDLE_SPEED(1, 2000.0000)\nN..... START_SPINDLE_COUNTERCLOCKWISE(1)\n"))
      << r.canon;
  // the program end stops every spindle and sets it back to RPM mode
  EXPECT_TRUE(has(r, "N..... STOP_SPINDLE_TURNING(0)\nN..... SET_SPINDLE_MODE(0 0.0000)\nN..... STOP_SPINDLE_TURNING(1)\n"
                     "N..... SET_SPINDLE_MODE(1 0.0000)\nN..... STOP_SPINDLE_TURNING(2)\nN..... SET_SPINDLE_MODE(2 0.0000)\n"
                     "N..... PROGRAM_END()"))
      << r.canon;
}

TEST(InterpSpindles, ASpindleTheMachineDoesNotHaveOrADollarNothingUsesIsAnError) {
  const auto ini = with_ini("[TRAJ]\nSPINDLES=3\n");
  const Rs274Result high = run("M3 $5\nM2\n", ini);
  EXPECT_FALSE(high.ok);
  EXPECT_NE(high.err.find("Invalid spindle ($) number 5 in M3"), std::string::npos) << high.err;
  const Rs274Result one = run("S100 $1\nM2\n");  // one spindle without [TRAJ]SPINDLES
  EXPECT_FALSE(one.ok);
  EXPECT_NE(one.err.find("Invalid spindle ($) number 1 in Spindle speed command"), std::string::npos) << one.err;
  const Rs274Result unused = run("G1 X1 F1 $1\nM2\n", ini);
  EXPECT_FALSE(unused.ok);
  EXPECT_NE(unused.err.find("$ (spindle selection) word with no M3"), std::string::npos) << unused.err;
  // G33 $1 needs spindle 1 turning, whatever spindle 0 does
  const Rs274Result stopped = run("S100 $0\nM3 $0\nG33 Z-1 K1 $1\nM2\n", ini);
  EXPECT_FALSE(stopped.ok);
  EXPECT_NE(stopped.err.find("Spindle not turning in G33"), std::string::npos) << stopped.err;
}

TEST(InterpSpindles, DollarChoosesTheSpindleThatThreadingFeedPerRevolutionAndM51Follow) {
  // LinuxCNC 2.9's rs274 with [TRAJ]SPINDLES=3 prints these calls; before,
  // a $ other than $0 with G33, G95 or M51 was refused
  const Rs274Result r = run("G20 G0 X0 Z0\nS100 $1 M3\nG33 X1 Z-1 K0.1 $1\nG95 $1 S200 F0.1\nG1 X2\nM51 P0 $2\nM2\n",
                            with_ini("[TRAJ]\nSPINDLES=3\n"));
  ASSERT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "N..... START_SPINDLE_CLOCKWISE(1)\nN..... START_SPEED_FEED_SYNC(0.100000,0)\n"
                     "N..... STRAIGHT_FEED(1.0000, 0.0000, -1.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STOP_SPEED_FEED_SYNCH()\n"
                     "N..... COMMENT(\"interpreter: feed mode set to units per revolution\")\n"
                     "N..... SET_FEED_MODE(1, 1)\nN..... SET_FEED_RATE(0.0000)\nN..... SET_FEED_RATE(0.1000)\n"
                     "N..... SET_SPINDLE_SPEED(1, 200.0000)\n"
                     "N..... STRAIGHT_FEED(2.0000, 0.0000, -1.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... DISABLE_SPEED_OVERRIDE(2)\n"))
      << r.canon;
  // feed per revolution of spindle 1: spindle 0 standing still is no error,
  // spindle 1 standing still is
  EXPECT_TRUE(run("S100 $1 M3\nG95 $1 S100 F0.1\nG1 X1\nM2\n", with_ini("[TRAJ]\nSPINDLES=3\n")).ok);
  const Rs274Result zero = run("S100 M3\nG95 $1 F0.1\nG1 X1\nM2\n", with_ini("[TRAJ]\nSPINDLES=3\n"));
  EXPECT_FALSE(zero.ok);
  EXPECT_NE(zero.err.find("Cannot feed with zero spindle speed in feed per rev mode"), std::string::npos) << zero.err;
}

// ---------------------------------------------------------------- G70-G72

TEST(InterpLatheCycles, AnErrorAfterTheContourWasReadNamesTheCycleBlockNotTheSubroutinesEnd) {
  // LinuxCNC 2.9 shows "o10 endsub" (the last block its reader parsed);
  // the I word at fault is on the cycle's line.
  const Rs274Result r = run("G18 G21 F300\no10 sub\n  G0 X2 Z1\n  G1 Z0\n  X6 Z-3\no10 endsub\nG0 X12 Z2\n"
                            "G71 Q10 X12 Z2 I0\nM2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("G7X error: I must be greater than zero.\nG71 Q10 X12 Z2 I0\n"), std::string::npos) << r.err;
}

TEST(InterpLatheCycles, InG91TheCycleAndItsContourAreRelativeAndTheLastMovesModeStays) {
  // values from LinuxCNC 2.9's rs274: X12 Z2 of the cycle and the contour's
  // words are relative; the last move of the G70 pass was a G1, so the
  // following "X2" feeds 2 further (G91 is still on)
  const Rs274Result r = run("G18 G21 F300\no10 sub\n  G0 X2 Z1\n  G1 Z0\n  X6 Z-3\n  Z-7\no10 endsub\nG0 X12 Z2\n"
                            "G91\nG70 Q10 X12 Z2\nX2\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_TRAVERSE(24.0000, 0.0000, 5.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_TRAVERSE(26.0000, 0.0000, 5.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(32.0000, 0.0000, 2.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(32.0000, 0.0000, -5.0000, 0.0000, 0.0000, 0.0000)\n"
                     "N..... STRAIGHT_FEED(34.0000, 0.0000, -5.0000, 0.0000, 0.0000, 0.0000)\n")) << r.canon;
}

TEST(InterpLatheCycles, AG71Point2ThatMakesNoProgressStopsWithAnErrorInsteadOfLoopingForEver) {
  // LinuxCNC 2.9 repeats STRAIGHT_FEED(3.0647, 0, -14.04, ...) for ever on
  // this contour (its own test interp/g71-endless-loop is an expected
  // failure); here it is an error after 1000 identical moves
  const Rs274Result r = run("G21 G18 G90 G8 G91.1 F225\no200 sub\n  G1 X10 Z0\n  G1 X10 Z-14\n  G1 X3\n  G1 X7 Z-22\n"
                            "o200 endsub\nG71.2 Q200 X15 Z0 D0.04 I0.5 R1\nM2\n");
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.err.find("G7X error: the cycle makes no progress: the same move more than 1000 times in a row"),
            std::string::npos)
      << r.err;
}

TEST(InterpLatheCycles, AStopOnTheCyclesLineRunsAfterTheCycle) {
  // LinuxCNC 2.9 drops the M0 (it goes on with the subroutine's last block)
  const Rs274Result r = run("G18 G21 F300\no10 sub\n  G0 X2 Z1\n  G1 Z0\n  X6 Z-3\n  Z-7\no10 endsub\nG0 X12 Z2\n"
                            "G70 Q10 X12 Z2 M0\nG0 X20\nM2\n");
  EXPECT_TRUE(r.ok) << r.err;
  EXPECT_TRUE(has(r, "STRAIGHT_FEED(6.0000, 0.0000, -7.0000, 0.0000, 0.0000, 0.0000)\nN..... PROGRAM_STOP()\n"
                     "N..... STRAIGHT_TRAVERSE(20.0000, 0.0000, -7.0000")) << r.canon;
}
