// Behaviour the task controller relies on: synchronisation points, line
// numbers on segments, run-from-line, MDI, parameter persistence, tools.
#include <gtest/gtest.h>

#include <fstream>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"
#include "core/interp/recording_canon.hpp"
#include "core/util/atomic_file.hpp"
#include "tests/support/testing.hpp"

using cnc::Pose;
using cnc::interp::Config;
using cnc::interp::InterpError;
using cnc::interp::Interpreter;
using cnc::interp::RecordingCanon;
using cnc::interp::Status;
using cnc::tooltable::ChangerKind;
using cnc::tooltable::ToolTable;

namespace {

ToolTable tools(ChangerKind kind = ChangerKind::NonRandom) {
  return ToolTable::parse("T1 P1 Z10 D6\nT2 P5 Z20 D4\nT7 P3 Z7\n", "t.tbl", kind);
}

// Reads and executes until the next synch point or the end.
Status step_until_synch(Interpreter& in) {
  for (;;) {
    Status st = in.read();
    if (st != Status::Ok) return st;
    st = in.execute();
    if (st != Status::Ok) return st;
  }
}

std::string error_of(Interpreter& in) {
  try {
    in.run_to_end();
  } catch (const InterpError& e) {
    return std::to_string(e.line()) + ": " + e.message();
  }
  return "(no error)";
}

}  // namespace

TEST(Interpreter, ProbeIsASynchPointAndResultsComeFromTheMachine) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("p.ngc", "G21 F100\nG38.2 Z-10\n#1 = #5063\nG0 Z#1\nM2\n"));
  EXPECT_EQ(step_until_synch(in), Status::ExecuteFinish);
  EXPECT_TRUE(in.is_synch_pending());
  EXPECT_EQ(in.read(), Status::SynchRequired) << "read-ahead must stop until the machine caught up";
  canon.set_probe_tripped(true);
  in.synch();
  EXPECT_FALSE(in.is_synch_pending());
  EXPECT_DOUBLE_EQ(in.parameter(5063), -10.0);
  EXPECT_DOUBLE_EQ(in.parameter(5070), 1.0);
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
  ASSERT_GE(canon.segments.size(), 2u);
  EXPECT_EQ(canon.segments.back().kind, 'T');
  EXPECT_DOUBLE_EQ(canon.segments.back().end.z(), -10.0);
}

TEST(Interpreter, InputWaitToolChangeAndM61AreSynchPoints) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("p.ngc", "M66 P0 L3 Q1\n#1 = #5399\nT1 M6\nM61 Q2\nM2\n"));
  EXPECT_EQ(step_until_synch(in), Status::ExecuteFinish);
  EXPECT_EQ(in.line(), 1);
  canon.set_input_value(1.0);
  in.synch();
  EXPECT_EQ(step_until_synch(in), Status::ExecuteFinish);
  EXPECT_EQ(in.line(), 3);
  EXPECT_DOUBLE_EQ(in.parameter(1), 1.0) << "#5399 read after the synch";
  in.synch();
  EXPECT_EQ(step_until_synch(in), Status::ExecuteFinish);
  EXPECT_EQ(in.line(), 4);
  in.synch();
  EXPECT_EQ(step_until_synch(in), Status::ProgramEnd);
}

TEST(Interpreter, SegmentsCarryTheirSourceLines) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("p.ngc", "G21 F100\n\nG0 X1\n(comment)\nG1 X2\nG2 X4 I1\no1 repeat [2]\nG1 Y1\no1 endrepeat\nM2\n"));
  in.run_to_end();
  ASSERT_EQ(canon.segments.size(), 5u);
  EXPECT_EQ(canon.segments[0].line, 3);
  EXPECT_EQ(canon.segments[1].line, 5);
  EXPECT_EQ(canon.segments[2].kind, 'A');
  EXPECT_EQ(canon.segments[2].line, 6);
  EXPECT_EQ(canon.segments[3].line, 8);
  EXPECT_EQ(canon.segments[4].line, 8);
}

TEST(Interpreter, ErrorsCarryFileLineAndText) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  const auto p = dir.write("p.ngc", "G21\nG0 X1\n  G1 X2 F0\nM2\n");
  in.open(p);
  try {
    in.run_to_end();
    FAIL() << "no error";
  } catch (const InterpError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.message(), "Cannot do g1 with zero feed rate");
    EXPECT_EQ(e.block_text(), "  G1 X2 F0");
    EXPECT_EQ(e.file(), p.string());
    EXPECT_EQ(std::string(e.what()), p.string() + ":3: Cannot do g1 with zero feed rate");
  }
}

TEST(Interpreter, ErrorInsideSubroutineFileNamesThatFile) {
  cnc::testing::TempDir dir;
  dir.write("bad.ngc", "o<bad> sub\nG0 X1\nG0 Q\no<bad> endsub\nM2\n");
  RecordingCanon canon(tools());
  Config cfg;
  cfg.subroutine_path = {dir.path()};
  Interpreter in(canon, cfg);
  in.init();
  in.open(dir.write("main.ngc", "o<bad> call\nM2\n"));
  try {
    in.run_to_end();
    FAIL() << "no error";
  } catch (const InterpError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.file(), (dir / "bad.ngc").string());
    EXPECT_EQ(e.message(), "No characters found in reading real value");
  }
}

TEST(Interpreter, RunFromLineLearnsSubsButExecutesNothingBefore) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  const auto p = dir.write("p.ngc",
                           "G21 F100\n"
                           "o<s> sub\n"
                           "G1 X#1\n"
                           "o<s> endsub\n"
                           "G0 X100\n"
                           "G0 Y5\n"
                           "o<s> call [7]\n"
                           "M2\n");
  // The task controller restores the modal state (here the feed) itself.
  in.execute("G21 F100");
  canon.calls.clear();
  in.open_at_line(p, 6);
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
  ASSERT_EQ(canon.segments.size(), 2u);
  EXPECT_EQ(canon.segments[0].line, 6);
  EXPECT_DOUBLE_EQ(canon.segments[0].end.y(), 5);
  EXPECT_EQ(canon.segments[1].line, 3);
  EXPECT_DOUBLE_EQ(canon.segments[1].end.x(), 7);
}

TEST(Interpreter, ResetThenRestartRunsTheProgramAgain) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  const auto p = dir.write("p.ngc", "G21 G91 F100\nG1 X1\nG1 X1\nM2\n");
  in.open(p);
  ASSERT_EQ(in.read(), Status::Ok);
  in.execute();
  ASSERT_EQ(in.read(), Status::Ok);
  in.execute();
  in.reset();  // abort in the middle
  EXPECT_FALSE(in.is_open());
  in.open(p);
  canon.segments.clear();
  in.run_to_end();
  ASSERT_EQ(canon.segments.size(), 2u);
  EXPECT_EQ(canon.segments[0].line, 2);
}

TEST(Interpreter, MdiLinesExecuteAndCallSubroutinesFromThePath) {
  cnc::testing::TempDir dir;
  dir.write("twice.ngc", "o<twice> sub\no<twice> return [#1 * 2]\no<twice> endsub\nM2\n");
  RecordingCanon canon(tools());
  Config cfg;
  cfg.subroutine_path = {dir.path()};
  Interpreter in(canon, cfg);
  in.init();
  in.execute("G21 G0 X3 Y4");
  EXPECT_DOUBLE_EQ(in.position().x(), 3);
  in.execute("o<twice> call [21]");
  double v = 0;
  ASSERT_TRUE(in.named_parameter("_value", v));
  EXPECT_DOUBLE_EQ(v, 42);
  EXPECT_EQ(in.call_level(), 0);
}

TEST(Interpreter, StartupCodeRunsAtInit) {
  RecordingCanon canon(tools());
  Config cfg;
  cfg.startup_code = "G20 G91 G18";
  Interpreter in(canon, cfg);
  in.init();
  const auto g = in.active_g_codes();
  EXPECT_NE(std::find(g.begin(), g.end(), 200), g.end());
  EXPECT_NE(std::find(g.begin(), g.end(), 910), g.end());
  EXPECT_NE(std::find(g.begin(), g.end(), 180), g.end());
}

TEST(Interpreter, ParameterFileIsLoadedAndSavedAtomically) {
  cnc::testing::TempDir dir;
  const auto var = dir.write("p.var", "31\t1.500000\n5221\t2.000000\n");
  RecordingCanon canon(tools());
  Config cfg;
  cfg.parameter_file = var;
  Interpreter in(canon, cfg);
  in.init();
  EXPECT_DOUBLE_EQ(in.parameter(31), 1.5) << "parameters listed in the file persist";
  EXPECT_DOUBLE_EQ(in.parameter(5221), 2.0);
  EXPECT_DOUBLE_EQ(in.position().x(), -2.0) << "machine at its origin until the first synch";
  in.execute("G10 L2 P2 X7");
  in.execute("#31 = 9");
  in.execute("#32 = 4");
  in.save_parameters();
  const std::string text = cnc::read_file(var);
  EXPECT_NE(text.find("31\t9.000000\n"), std::string::npos);
  EXPECT_EQ(text.find("\n32\t"), std::string::npos) << "#32 was not in the file: volatile";
  EXPECT_NE(text.find("5241\t7.000000\n"), std::string::npos);
  EXPECT_NE(text.find("5161\t0.000000\n"), std::string::npos) << "required parameters are always written";
  EXPECT_FALSE(std::filesystem::exists(dir / "p.var.tmp"));
}

TEST(Interpreter, ParameterFileErrorsNameFileAndLine) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Config cfg;
  cfg.parameter_file = dir.write("p.var", "5161 0\n31 x\n");
  Interpreter bad(canon, cfg);
  try {
    bad.init();
    FAIL() << "no error";
  } catch (const InterpError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(e.message(), "Bad line in parameter file, expected '<number> <value>'");
  }
  cfg.parameter_file = dir.write("q.var", "31 0\n5161 1\n30 2\n");
  Interpreter order(canon, cfg);
  try {
    order.init();
    FAIL() << "no error";
  } catch (const InterpError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.message(), "Parameter file out of order");
  }
}

TEST(Interpreter, IniValuesAreReadable) {
  const auto ini = cnc::ini::IniFile::parse("[AXIS_X]\nMAX_VELOCITY = 12.5\n[RS274NGC]\nFEATURES=0\n", "m.ini");
  RecordingCanon canon(tools());
  Config cfg = Config::from_ini(ini);
  Interpreter in(canon, cfg);
  in.init();
  in.execute("#1 = #<_ini[axis_x]max_velocity>");
  EXPECT_DOUBLE_EQ(in.parameter(1), 12.5);
  EXPECT_THROW(in.execute("#1 = #<_ini[axis_x]nothing>"), InterpError);
}

TEST(Interpreter, NonRandomToolChangeUsesSpindleForG43AndToolNumbersForH) {
  RecordingCanon canon(tools(), cnc::interp::Units::Mm);
  Interpreter in(canon);
  in.init();
  in.execute("G21 T2 M6");
  in.synch();
  in.execute("G43");
  EXPECT_EQ(canon.calls_starting("USE_TOOL_LENGTH_OFFSET").back(),
            "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 20.0000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)");
  EXPECT_EQ(canon.calls_starting("CHANGE_TOOL(").back(), "CHANGE_TOOL(2)") << "tooldata index, not pocket 5";
  in.execute("G43 H7");
  EXPECT_EQ(canon.calls_starting("USE_TOOL_LENGTH_OFFSET").back(),
            "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 7.0000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)");
  EXPECT_DOUBLE_EQ(in.parameter(5400), 2);
}

TEST(Interpreter, RandomChangerIndexIsThePocket) {
  RecordingCanon canon(tools(ChangerKind::Random), cnc::interp::Units::Mm);
  Config cfg;
  cfg.random_toolchanger = true;
  Interpreter in(canon, cfg);
  in.init();
  in.execute("G21 T2 M6");
  in.synch();
  EXPECT_EQ(canon.calls_starting("CHANGE_TOOL(").back(), "CHANGE_TOOL(5)");
  EXPECT_EQ(canon.tool_table().spindle().number, 2);
  in.execute("T1 M6");
  in.synch();
  EXPECT_EQ(canon.tool_table().at(1).number, 2) << "tool 2 went to pocket 1";
  in.execute("G43");
  EXPECT_EQ(canon.calls_starting("USE_TOOL_LENGTH_OFFSET").back(),
            "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 10.0000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)");
}

TEST(Interpreter, M61TakesTheSpindleToolFromTheMachineAfterSynch) {
  RecordingCanon canon(tools(), cnc::interp::Units::Mm);
  canon.set_m61_loads_tool_data(true);  // as a real I/O controller
  Interpreter in(canon);
  in.init();
  EXPECT_EQ(in.execute("G21 M61 Q7"), Status::Ok) << "MDI synchronises by itself";
  in.execute("G43");
  EXPECT_EQ(canon.calls_starting("CHANGE_TOOL_NUMBER").back(), "CHANGE_TOOL_NUMBER(3)");
  EXPECT_EQ(canon.calls_starting("USE_TOOL_LENGTH_OFFSET").back(),
            "USE_TOOL_LENGTH_OFFSET(0.0000 0.0000 7.0000, 0.0000 0.0000 0.0000, 0.0000 0.0000 0.0000)");
  EXPECT_DOUBLE_EQ(in.parameter(5400), 7);
  in.execute("M61 Q0");
  EXPECT_DOUBLE_EQ(in.parameter(5400), 0) << "M61 Q0 empties the spindle";
}

TEST(Interpreter, G10L1OfAnotherToolLeavesTheLoadedToolsParametersAlone) {
  // Manual 3.24.3.4 buglet, fixed: only the loaded tool's update touches
  // the spindle and #5400-#5413.
  RecordingCanon canon(tools(), cnc::interp::Units::Mm);
  Interpreter in(canon);
  in.init();
  in.execute("G21 T1 M6");
  in.synch();
  in.execute("G10 L1 P2 Z99");
  EXPECT_DOUBLE_EQ(in.parameter(5403), 10);
  EXPECT_EQ(canon.calls_starting("SET_TOOL_TABLE_ENTRY").size(), 1u);
  in.execute("G10 L1 P1 Z11");
  EXPECT_DOUBLE_EQ(in.parameter(5403), 11);
  EXPECT_EQ(canon.calls_starting("SET_TOOL_TABLE_ENTRY").back(),
            "SET_TOOL_TABLE_ENTRY(0, 1, 0.0000 0.0000 11.0000 0.0000 0.0000 0.0000 0.0000 0.0000 0.0000, 0.0000, 0.0000, 0)");
}

TEST(Interpreter, StreamsLongProgramsAndCountsEveryLine) {
  cnc::testing::TempDir dir;
  std::string text = "G21 G90 F1000\n";
  for (int i = 0; i < 20000; ++i) text += "G1 X" + std::to_string(i % 100) + " Y" + std::to_string(i % 7) + "\n";
  text += "M2\n";
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("long.ngc", text));
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
  EXPECT_EQ(canon.segments.size(), 20000u);
  EXPECT_EQ(canon.segments.back().line, 20001);
  EXPECT_EQ(in.line(), 20002);
}

TEST(Interpreter, UserMCodesAreOffUnlessConfigured) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter plain(canon);
  plain.init();
  EXPECT_THROW(plain.execute("M101 P1"), InterpError);
  dir.write("M101", "#!/bin/sh\n");
  Config cfg;
  cfg.user_m_path = {dir.path()};
  Interpreter configured(canon, cfg);
  configured.init();
  configured.execute("M101 P2 Q3");
  EXPECT_EQ(canon.calls.back(), "USER_M_CODE(101, 2.0000, 3.0000)");
}

TEST(Interpreter, FileWithoutEndIsAnErrorWithTheLastLine) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("p.ngc", "G0 X1\nG0 X2\n"));
  EXPECT_EQ(error_of(in), "2: File ended with no percent sign or program end");
}

TEST(Interpreter, LongestLinesAndLoopsAcrossBufferBoundaries) {
  // A line of the longest length (256), and a loop whose start is far
  // behind the reader's 64 KiB buffer when it jumps back.
  cnc::testing::TempDir dir;
  std::string text = "G21 G90 F100\n(" + std::string(254, 'x') + ")\n#1 = 0\no1 while [#1 LT 3]\n";
  for (int i = 0; i < 3000; ++i) text += "(filler " + std::to_string(i) + " " + std::string(40, 'y') + ")\n";
  text += "G1 X#1\n#1 = [#1 + 1]\no1 endwhile\nM2\n";
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  in.open(dir.write("long.ngc", text));
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
  ASSERT_EQ(canon.segments.size(), 3u);
  EXPECT_DOUBLE_EQ(canon.segments[2].end.x(), 2);
  EXPECT_EQ(canon.segments[0].line, 3005);
  EXPECT_EQ(canon.calls_starting("COMMENT(\"xxxx").size(), 1u);
}
