#include <gtest/gtest.h>

#include <fstream>

#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::hal;

namespace {
struct Fixture {
  Hal hal;
  ComponentRegistry registry;
  cnc::ini::IniFile ini = cnc::ini::IniFile::parse(
      "[EMCMOT]\nSERVO_PERIOD = 1000000\n[KINS]\nLOGIC = and2 count=2\n[SCALE]\nGAIN = 2.5\n", "mill.ini");
  CommandInterpreter interp{hal, registry, &ini, nullptr};
  Fixture() { register_core_components(registry); }
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(HalFile, TokenizerHandlesQuotesAndComments) {
  EXPECT_EQ(tokenize_hal_line("net a  b => c # comment"), (std::vector<std::string>{"net", "a", "b", "=>", "c"}));
  EXPECT_EQ(tokenize_hal_line("loadusr prog \"two words\""), (std::vector<std::string>{"loadusr", "prog", "two words"}));
  EXPECT_TRUE(tokenize_hal_line("   # only a comment").empty());
  EXPECT_THROW(tokenize_hal_line("echo \"open"), HalError);
}

TEST(HalFile, IniAndEnvironmentSubstitution) {
  Fixture f;
  ::setenv("CNC_TEST_VALUE", "7", 1);
  EXPECT_EQ(f.interp.substitute("setp x [SCALE]GAIN"), "setp x 2.5");
  EXPECT_EQ(f.interp.substitute("setp x [SCALE](GAIN)"), "setp x 2.5");
  EXPECT_EQ(f.interp.substitute("a $CNC_TEST_VALUE $(CNC_TEST_VALUE)b"), "a 7 7b");
  EXPECT_EQ(f.interp.substitute("x # [NOT]SUBSTITUTED"), "x # [NOT]SUBSTITUTED");
  EXPECT_EQ(error_of([&] { f.interp.substitute("[SCALE]MISSING"); }), "[SCALE]MISSING is not in mill.ini");
}

TEST(HalFile, RunsAFileWithEveryCommonCommand) {
  Fixture f;
  f.interp.run_text(
      "# a small machine\n"
      "loadrt threads name1=servo-thread period1=[EMCMOT]SERVO_PERIOD\n"
      "loadrt [KINS]LOGIC\n"
      "loadrt scale names=gain-x\n"
      "addf and2.0 servo-thread\n"
      "addf gain-x servo-thread\n"
      "addf and2.1 servo-thread 1\n"
      "net enable and2.0.out => and2.1.in0\n"
      "net  go  and2.1.out \\\n"
      "     and2.0.in1\n"
      "setp gain-x.gain [SCALE]GAIN\n"
      "gain-x.offset = 1\n"
      "net spare and2.1.in1\n"
      "sets spare TRUE\n",
      "mill.hal");
  EXPECT_EQ(f.hal.get_value("gain-x.gain"), "2.5");
  EXPECT_EQ(f.hal.get_value("gain-x.offset"), "1");
  EXPECT_EQ(f.hal.get_signal("spare"), "TRUE");
  EXPECT_EQ(f.hal.get_value("and2.1.in1"), "TRUE");
  const auto threads = f.hal.thread_views();
  ASSERT_EQ(threads.size(), 1u);
  EXPECT_EQ(threads[0].period_ns, 1'000'000);
  EXPECT_EQ(threads[0].functions, (std::vector<std::string>{"and2.1", "and2.0", "gain-x"}));
}

TEST(HalFile, ErrorsNameFileAndLine) {
  Fixture f;
  EXPECT_EQ(error_of([&] { f.interp.run_text("loadrt and2\n\nnet s and2.0.out and2.0.nope\n", "x.hal"); }),
            "x.hal:3: pin \"and2.0.nope\" does not exist");
  Fixture g;
  EXPECT_EQ(error_of([&] { g.interp.run_text("frobnicate\n", "y.hal"); }), "y.hal:1: unknown command \"frobnicate\"");
  Fixture h;
  EXPECT_EQ(error_of([&] { h.interp.run_text("loadrt and2 count=abc\n", "z.hal"); }),
            "z.hal:1: and2: count=abc: expected an integer from 1 to 64");
  Fixture i;
  EXPECT_EQ(error_of([&] { i.interp.run_text("loadrt and2 colour=red\n", "w.hal"); }),
            "w.hal:1: and2: unknown argument \"colour\"; it takes count, names");
  Fixture j;
  EXPECT_NE(error_of([&] { j.interp.run_text("loadrt nosuchcomp\n", "v.hal"); }).find("v.hal:1: loadrt: no component named \"nosuchcomp\""),
            std::string::npos);
  Fixture k;
  EXPECT_EQ(error_of([&] { k.interp.run_text("setp\n", "u.hal"); }), "u.hal:1: usage: setp <pin|param> <value>");
}

TEST(HalFile, SourceIncludesRelativeFiles) {
  cnc::testing::TempDir dir;
  dir.write("sub/io.hal", "loadrt not\nnet n not.0.out\n");
  const auto main = dir.write("main.hal", "loadrt and2\nsource sub/io.hal\n");
  Fixture f;
  f.interp.run_file(main);
  EXPECT_EQ(f.hal.get_signal("n"), "FALSE") << "not.0.out before its function runs (LinuxCNC's initial value)";
  const auto bad = dir.write("bad.hal", "source sub/missing.hal\n");
  Fixture g;
  EXPECT_NE(error_of([&] { g.interp.run_file(bad); }).find("missing.hal: cannot read HAL file"), std::string::npos);
}

TEST(HalFile, ShowAndListOutput) {
  Fixture f;
  f.interp.run_text("loadrt threads name1=servo-thread period1=1000000\nloadrt and2\naddf and2.0 servo-thread\n"
                    "net go and2.0.out\n", "m.hal");
  const std::string pins = f.interp.execute("show pin and2");
  EXPECT_NE(pins.find("and2          bit   OUT         FALSE  and2.0.out ==> go"), std::string::npos) << pins;
  EXPECT_NE(pins.find("and2.0.in0"), std::string::npos);
  const std::string threads = f.interp.execute("show thread");
  EXPECT_NE(threads.find("1000000"), std::string::npos);
  EXPECT_NE(threads.find("servo-thread"), std::string::npos);
  EXPECT_NE(threads.find("1 and2.0"), std::string::npos) << threads;
  EXPECT_EQ(f.interp.execute("list pin and2.0.in*"), "and2.0.in0 and2.0.in1\n");
  EXPECT_EQ(f.interp.execute("getp and2.0.out"), "FALSE\n");
  EXPECT_EQ(f.interp.execute("ptype and2.0.out"), "bit\n");
  const std::string params = f.interp.execute("show param");
  EXPECT_NE(params.find("and2.0.tmax"), std::string::npos);
  const std::string save = f.interp.execute("save");
  EXPECT_NE(save.find("net go <= and2.0.out"), std::string::npos) << save;
  EXPECT_NE(save.find("addf and2.0 servo-thread"), std::string::npos);
}

TEST(HalFile, ThreadsComponentValidatesArguments) {
  Fixture f;
  EXPECT_NE(error_of([&] { f.interp.execute("loadrt threads name1=fast"); }).find("needs period1"), std::string::npos);
  Fixture g;
  EXPECT_NE(error_of([&] { g.interp.execute("loadrt threads name1=fast period1=5000"); }).find("below 10000 ns"),
            std::string::npos);
}

TEST(HalFile, LoadusrRunsAProgramFromTheAllowedFolders) {
  cnc::testing::TempDir dir;
  const auto tools = dir / "tools";
  std::filesystem::create_directories(tools);
  const auto script = tools / "mark";
  { std::ofstream(script) << "#!/bin/sh\ntouch \"$1\"\n"; }
  std::filesystem::permissions(script, std::filesystem::perms::owner_all);
  { std::ofstream(tools / "fail") << "#!/bin/sh\nexit 1\n"; }
  std::filesystem::permissions(tools / "fail", std::filesystem::perms::owner_all);
  { std::ofstream(tools / "data.txt") << "not a program\n"; }
  const auto ini_path = dir.write("mill.ini", "[HAL]\nLOADUSR_PATH = tools\n");
  auto ini = cnc::ini::IniFile::load(ini_path);
  Hal hal;
  ComponentRegistry registry;
  CommandInterpreter interp{hal, registry, &ini, nullptr};
  const auto marker = dir / "ran";
  interp.execute("loadusr -w mark " + marker.string());
  EXPECT_TRUE(std::filesystem::exists(marker));
  EXPECT_NE(error_of([&] { interp.execute("loadusr -w fail"); }).find("exited with status 1"), std::string::npos);
  EXPECT_NE(error_of([&] { interp.execute("loadusr -W halui"); }).find("not supported"), std::string::npos);
  // Never a shell or anything else outside those folders (a halcmd client
  // used to get a root shell with `loadusr -w /bin/sh -c id`).
  EXPECT_NE(error_of([&] { interp.execute("loadusr -w /bin/sh -c id"); }).find("/bin/sh") , std::string::npos);
  EXPECT_NE(error_of([&] { interp.execute("loadusr -w /bin/sh -c id"); }).find("is outside the allowed folders"),
            std::string::npos);
  EXPECT_NE(error_of([&] { interp.execute("loadusr -w sh -c id"); }).find("no such program in the allowed folders"),
            std::string::npos);
  EXPECT_NE(error_of([&] { interp.execute("loadusr -w tools/../../../bin/sh"); }).find("outside"), std::string::npos);
  // A program that does not exist is an error now, not a child that fails.
  EXPECT_NE(error_of([&] { interp.execute("loadusr /nonexistent"); }).find("outside"), std::string::npos);
  EXPECT_NE(error_of([&] { interp.execute("loadusr data.txt"); }).find("is not an executable file"), std::string::npos);
}

TEST(HalFile, AClientMayNotMakeTheControllerReadAFile) {
  Fixture f;
  EXPECT_NE(error_of([&] { f.interp.execute("source /etc/shadow", CommandInterpreter::Origin::Client); })
                .find("the controller reads only its configuration's files"),
            std::string::npos);
}

TEST(HalFile, RemoteComponentsOwnPinsWrittenWithSetr) {
  Fixture f;
  f.interp.run_text("loadrt not\nnewcomp panel\nnewpin panel panel.button bit out\nnewpin panel panel.lamp bit in\n"
                    "net b panel.button => not.0.in\nnet l not.0.out => panel.lamp\n", "p.hal");
  f.interp.execute("setr panel.button TRUE");
  EXPECT_EQ(f.hal.get_signal("b"), "TRUE");
  EXPECT_THROW(f.interp.execute("setr not.0.in TRUE"), HalError) << "only newcomp pins";
  EXPECT_THROW(f.interp.execute("setr panel.lamp TRUE"), HalError) << "a connected input belongs to its writer";
  EXPECT_THROW(f.interp.execute("newpin panel other.x bit in"), HalError);
  EXPECT_THROW(f.interp.execute("newpin nosuch nosuch.x bit in"), HalError);
  EXPECT_THROW(f.interp.execute("newpin panel panel.y colour in"), HalError);
}

// A file that sources itself (directly or through another) is an error
// naming the loop, not a stack overflow; special files are refused.
TEST(HalFile, SourceLoopsAndSpecialFilesAreErrors) {
  cnc::testing::TempDir dir;
  dir.write("a.hal", "echo a\nsource b.hal\n");
  dir.write("b.hal", "\n\nsource a.hal\n");
  Fixture f;
  EXPECT_EQ(error_of([&] { f.interp.run_file(dir / "a.hal"); }),
            (dir / "b.hal").string() + ":3: source " + (dir / "a.hal").string() + ": a source loop (a.hal -> b.hal -> a.hal)");
  dir.write("self.hal", "source self.hal\n");
  EXPECT_NE(error_of([&] { f.interp.run_file(dir / "self.hal"); }).find("a source loop (self.hal -> self.hal)"),
            std::string::npos);
  EXPECT_EQ(error_of([&] { f.interp.run_file("/dev/zero"); }),
            "/dev/zero: cannot read HAL file: is a character device, not a regular file");
  EXPECT_EQ(error_of([&] { f.interp.execute("source " + dir.path().string()); }),
            dir.path().string() + ": cannot read HAL file: is a directory, not a regular file");
  // The interpreter is usable afterwards (its file stack unwound).
  EXPECT_EQ(error_of([&] { f.interp.execute("echo still here"); }), "(no error)");
}

// Found by fuzzing (tests/core/hal/fuzz/corpus/hal/failed-loadrt-left-pins):
// a component that failed to load (its name taken, or a pin name taken
// half-way through its constructor) left its pins in the HAL, owned by the
// destroyed object, and `show` read freed memory.
TEST(HalFile, AComponentThatFailsToLoadLeavesNothingBehind) {
  Fixture f;
  f.interp.execute("loadrt and2 names=a");
  f.interp.execute("loadrt threads name1=servo-thread period1=1000000");
  EXPECT_NE(error_of([&] { f.interp.execute("loadrt and2 names=b"); }).find("already loaded"), std::string::npos);
  EXPECT_FALSE(f.hal.has_pin("b.in0"));
  EXPECT_FALSE(f.hal.has_param("b.time"));
  EXPECT_NE(error_of([&] { f.interp.execute("addf b servo-thread"); }), "(no error)") << "no function b either";
  EXPECT_TRUE(f.hal.has_pin("a.in0")) << "the loaded one keeps its pins";
  const std::string shown = f.interp.execute("show pin");
  EXPECT_NE(shown.find("a.in0"), std::string::npos);
  EXPECT_EQ(shown.find("b.in0"), std::string::npos);
  f.interp.execute("loadrt or2 names=b");  // the names are free again
  EXPECT_TRUE(f.hal.has_pin("b.in0"));
  // A constructor that fails half-way (c's pins made, then a's taken).
  EXPECT_NE(error_of([&] { f.interp.execute("loadrt xor2 names=c,a"); }), "(no error)");
  EXPECT_FALSE(f.hal.has_pin("c.in0"));
  EXPECT_FALSE(f.hal.has_param("c.time"));
}
