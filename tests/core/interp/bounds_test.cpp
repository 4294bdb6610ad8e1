// The interpreter never takes its caller's cycle: read() does a bounded
// amount of work and yields, an endless loop without machine output is an
// error naming the file and line, and programs, subroutines and the
// parameter file are read only from regular files with a line length limit.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"
#include "core/interp/line_reader.hpp"
#include "core/interp/recording_canon.hpp"
#include "tests/support/testing.hpp"

using cnc::interp::Config;
using cnc::interp::InterpError;
using cnc::interp::Interpreter;
using cnc::interp::RecordingCanon;
using cnc::interp::Status;

namespace {

cnc::tooltable::ToolTable tools() { return cnc::tooltable::ToolTable::parse("T1 P1 Z10 D6\n", "t.tbl", cnc::tooltable::ChangerKind::NonRandom); }

// The InterpError `f` throws, or a failure.
template <class F>
InterpError error_of(F f) {
  try {
    f();
  } catch (const InterpError& e) {
    return e;
  }
  ADD_FAILURE() << "no InterpError";
  return InterpError("(none)", "", 0, "");
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST(InterpBounds, ReadYieldsBetweenLinesAndALongComputationCompletes) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Config cfg;
  cfg.lines_per_read = 100;
  Interpreter in(canon, cfg);
  in.init();
  // 20000 lines of computation (body and endrepeat, 10000 times) before the
  // first move, below the limit.
  in.open(dir.write("count.ngc", "#1 = 0\no1 repeat [10000]\n#1 = [#1 + 1]\no1 endrepeat\nG0 X#1\nM2\n"));
  int yields = 0;
  Status st;
  while ((st = in.read()) == Status::Yield) ++yields;
  ASSERT_EQ(st, Status::Ok);
  EXPECT_GE(yields, 199) << "every read() returns after at most 100 lines";
  in.execute();
  ASSERT_EQ(canon.segments.size(), 1u);
  EXPECT_DOUBLE_EQ(canon.segments[0].end.x(), 10000);
  EXPECT_EQ(canon.segments[0].line, 5);
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
}

TEST(InterpBounds, AnEndlessWhileLoopIsAnErrorNamingTheFileAndLine) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Config cfg;
  cfg.max_blocks_without_output = 1000;
  Interpreter in(canon, cfg);
  in.init();
  const auto path = dir.write("endless.ngc", "G0 X1\no100 while [1]\n#1 = [#1 + 1]\no100 endwhile\nM2\n");
  in.open(path);
  int reads = 0;
  const InterpError e = error_of([&] {
    for (;; ++reads) {
      const Status st = in.read();
      ASSERT_NE(st, Status::ProgramEnd);
      if (st == Status::Ok) in.execute();
    }
  });
  EXPECT_EQ(e.file(), path.string());
  EXPECT_GE(e.line(), 2);
  EXPECT_LE(e.line(), 4);
  EXPECT_TRUE(contains(e.message(), "1000 blocks in a row without machine output")) << e.message();
  EXPECT_TRUE(contains(e.message(), "[RS274NGC]MAX_BLOCKS_WITHOUT_OUTPUT = 1000")) << e.message();
  EXPECT_GE(reads, 3) << "the loop was read in several calls, each returning";
}

TEST(InterpBounds, AnEndlessLoopInASubroutineCalledFromMdiIsAnErrorAndYields) {
  cnc::testing::TempDir dir;
  const auto sub = dir.write("spin.ngc", "o<spin> sub\no1 while [1]\n#<x> = 1\no1 endwhile\no<spin> endsub\n");
  RecordingCanon canon(tools());
  Config cfg;
  cfg.subroutine_path = {dir.path()};
  cfg.max_blocks_without_output = 5000;
  cfg.lines_per_read = 50;
  Interpreter in(canon, cfg);
  in.init();
  // Stepwise, as the task controller does: the MDI line's first read()
  // returns after 50 lines, and so does every later one.
  EXPECT_EQ(in.read("o<spin> call"), Status::Yield);
  EXPECT_EQ(in.read(), Status::Yield);
  const InterpError e = error_of([&] {
    for (;;) in.read();
  });
  EXPECT_EQ(e.file(), sub.string());
  EXPECT_GE(e.line(), 2);
  EXPECT_LE(e.line(), 4);
  // The run-to-completion form ends with the same error.
  in.reset();
  const InterpError e2 = error_of([&] { in.execute("o<spin> call"); });
  EXPECT_EQ(e2.file(), sub.string());
  EXPECT_TRUE(contains(e2.message(), "MAX_BLOCKS_WITHOUT_OUTPUT")) << e2.message();
}

TEST(InterpBounds, MachineOutputAndSynchPointsRestartTheCount) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Config cfg;
  cfg.max_blocks_without_output = 100;
  Interpreter in(canon, cfg);
  in.init();
  // 3000 loop lines with a move in each pass, then 3000 with an input wait
  // (a synch point, as a loop polling an input): far over 100 lines, but
  // never 100 in a row without output.
  in.open(dir.write("moves.ngc",
                    "G21 F100\no1 repeat [1000]\nG1 X[#<_x> + 1]\no1 endrepeat\n"
                    "o2 repeat [1000]\nM66 P0 L0\no2 endrepeat\nM2\n"));
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd);
  EXPECT_EQ(canon.segments.size(), 1000u);
  EXPECT_DOUBLE_EQ(canon.segments.back().end.x(), 1000);
}

TEST(InterpBounds, TheLimitComesFromTheIni) {
  const auto ini = cnc::ini::IniFile::parse("[RS274NGC]\nMAX_BLOCKS_WITHOUT_OUTPUT = 12345\n", "m.ini");
  EXPECT_EQ(Config::from_ini(ini).max_blocks_without_output, 12345);
  EXPECT_EQ(Config::from_ini(cnc::ini::IniFile::parse("", "e.ini")).max_blocks_without_output, 10'000'000);
  EXPECT_THROW(Config::from_ini(cnc::ini::IniFile::parse("[RS274NGC]\nMAX_BLOCKS_WITHOUT_OUTPUT = 0\n", "z.ini")),
               cnc::ConfigError);
}

TEST(InterpFiles, FifosDirectoriesAndDevicesAreRefusedAtOpen) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  // A FIFO with a writer and a program in it (so that a reader that does
  // not check fails here instead of blocking).
  const auto fifo = dir / "pipe.ngc";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const int writer = ::open(fifo.c_str(), O_RDWR | O_NONBLOCK);
  ASSERT_GE(writer, 0);
  ASSERT_EQ(::write(writer, "%\n%\n", 4), 4);
  const InterpError e1 = error_of([&] { in.open(fifo); });
  ::close(writer);
  EXPECT_TRUE(contains(e1.message(), "<" + fifo.string() + ">")) << e1.message();
  EXPECT_TRUE(contains(e1.message(), "it is a FIFO (named pipe), not a regular file")) << e1.message();

  std::filesystem::create_directories(dir / "folder.ngc");
  const InterpError e2 = error_of([&] { in.open(dir / "folder.ngc"); });
  EXPECT_TRUE(contains(e2.message(), "it is a directory, not a regular file")) << e2.message();

  const InterpError e3 = error_of([&] { in.open("/dev/null"); });
  EXPECT_TRUE(contains(e3.message(), "</dev/null>: it is a character device, not a regular file")) << e3.message();
}

TEST(InterpFiles, DevZeroIsRefusedAtOpen) {
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  const InterpError e = error_of([&] { in.open("/dev/zero"); });
  EXPECT_TRUE(contains(e.message(), "</dev/zero>: it is a character device, not a regular file")) << e.message();
}

TEST(InterpFiles, SubroutineFilesAndTheParameterFileMustBeRegularFiles) {
  cnc::testing::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "spin.ngc").c_str(), 0600), 0);
  RecordingCanon canon(tools());
  Config cfg;
  cfg.subroutine_path = {dir.path()};
  Interpreter in(canon, cfg);
  in.init();
  const InterpError e = error_of([&] { in.execute("o<spin> call"); });
  EXPECT_TRUE(contains(e.message(), "Unable to open file <" + (dir / "spin.ngc").string() + ">: it is a FIFO"))
      << e.message();

  std::filesystem::create_directories(dir / "params.var");
  Config pc;
  pc.parameter_file = dir / "params.var";
  Interpreter with_params(canon, pc);
  const InterpError pe = error_of([&] { with_params.init(); });
  EXPECT_EQ(pe.file(), (dir / "params.var").string());
  EXPECT_TRUE(contains(pe.message(), "it is a directory, not a regular file")) << pe.message();
}

TEST(InterpFiles, OverLongLinesAreRefusedNamingTheFileAndLine) {
  cnc::testing::TempDir dir;
  RecordingCanon canon(tools());
  Interpreter in(canon);
  in.init();
  const std::string longest = "(" + std::string(cnc::interp::kMaxLineLength - 2, 'x') + ")";
  ASSERT_EQ(longest.size(), 256u);
  in.open(dir.write("ok.ngc", "G0 X1\n" + longest + "\r\nG0 X2\nM2\n"));
  EXPECT_EQ(in.run_to_end(), Status::ProgramEnd) << "256 characters (and a CR) are a line";

  const auto path = dir.write("long.ngc", "G0 X1\nG0 X2\n(" + std::string(300, 'x') + ")\nM2\n");
  in.open(path);
  const InterpError e = error_of([&] { in.run_to_end(); });
  EXPECT_EQ(e.file(), path.string());
  EXPECT_EQ(e.line(), 3);
  EXPECT_TRUE(contains(e.message(), "Command too long")) << e.message();

  // A file without any line end stops at the limit, not at the end of memory.
  const auto one = dir.write("one.ngc", std::string(1 << 20, 'G'));
  const InterpError e2 = error_of([&] { in.open(one); });
  EXPECT_EQ(e2.file(), one.string());
  EXPECT_EQ(e2.line(), 1);
  EXPECT_TRUE(contains(e2.message(), "Command too long")) << e2.message();

  const InterpError e3 = error_of([&] { in.execute("G0 X1 (" + std::string(300, 'y') + ")"); });
  EXPECT_TRUE(contains(e3.message(), "Command too long")) << e3.message();
}
