// The interpreter never stalls the task cycle: endless or long computation
// in a program, an MDI-called subroutine, run from line and its preview is
// done stepwise across task cycles (other commands, E-stop and abort are
// acted on meanwhile) and an endless one ends with an error naming the file
// and line; programs are opened only from regular files; M30 ends a
// program like M2.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include "tests/core/task/fixture.hpp"

using cnc::ipc::CommandState;
using cnc::ipc::CommandType;
using cnc::ipc::InterpState;
using cnc::ipc::TaskState;
using cnc::testing::TaskMachine;

namespace {
constexpr int kEstop = 1;
constexpr int kAuto = 2, kMdi = 3;

const char* kEndless = "G0 X10\no100 while [1]\n#1 = [#1 + 1]\no100 endwhile\nG0 X20\nM2\n";
// 400000 lines of computation, then X20 (below the default limit).
const char* kLong = "o1 repeat [200000]\n#1 = [#1 + 1]\no1 endrepeat\nG0 X[#1 / 10000]\nG0 Y10\nM2\n";

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TaskMachine::Override limit(int n) { return {"RS274NGC", "MAX_BLOCKS_WITHOUT_OUTPUT", std::to_string(n)}; }

cnc::ipc::Command mdi_command(const std::string& text) {
  cnc::ipc::Command c;
  c.type = CommandType::TaskPlanExecute;
  c.i[0] = -1;
  c.text.assign(text);
  c.serial = 90000;
  return c;
}
}  // namespace

TEST(TaskInterpBounds, AnEndlessProgramLoopLeavesTheTaskCyclingAndEstopActsAtOnce) {
  TaskMachine m;  // the default limit: the loop runs for many cycles
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("endless.ngc", kEndless), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  m.step(20);  // each cycle returns while the loop computes
  EXPECT_TRUE(m.program_running()) << m.errors();
  EXPECT_EQ(m.status().task.interp_state, InterpState::Reading);
  const auto estop = m.send(CommandType::TaskSetState, kEstop, 0);
  EXPECT_EQ(estop.first, CommandState::Done) << estop.second;
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  EXPECT_FALSE(m.program_running());
}

TEST(TaskInterpBounds, AnEndlessProgramLoopIsAnErrorNamingTheFileAndLine) {
  TaskMachine m({limit(5000)});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("endless.ngc", kEndless), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 100000));
  const std::string e = m.errors();
  EXPECT_TRUE(contains(e, "endless.ngc:3: ") || contains(e, "endless.ngc:4: ") || contains(e, "endless.ngc:2: "))
      << e;
  EXPECT_TRUE(contains(e, "5000 blocks in a row without machine output")) << e;
  EXPECT_TRUE(contains(e, "[RS274NGC]MAX_BLOCKS_WITHOUT_OUTPUT = 5000")) << e;
  EXPECT_FALSE(contains(m.log, "program finished")) << m.log;
}

TEST(TaskInterpBounds, AnEndlessLoopInAnMdiCalledSubroutineLeavesTheTaskCyclingAndCanBeAborted) {
  TaskMachine m;
  m.dir.write("nc_files/spin.ngc", "o<spin> sub\no1 while [1]\n#<x> = 1\no1 endwhile\no<spin> endsub\nM2\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  const cnc::ipc::Command call = mdi_command("o<spin> call");
  ASSERT_TRUE(m.task().handle_command(call, m.reporter));
  m.step(20);
  EXPECT_EQ(m.status().task.interp_state, InterpState::Reading) << "the call still runs";
  EXPECT_NE(m.reporter.last[call.serial].first, CommandState::Done);
  m.ok(m.send(CommandType::TaskAbort), "abort");
  EXPECT_EQ(m.reporter.last[call.serial].first, CommandState::Rejected);
  m.ok(m.mdi("G0 X5"), "the next MDI line");
  EXPECT_NEAR(m.status().motion.position[0], 5, 1e-9);
}

TEST(TaskInterpBounds, AnEndlessLoopInAnMdiCalledSubroutineIsAnErrorNamingItsFileAndLine) {
  TaskMachine m({limit(5000)});
  m.dir.write("nc_files/spin.ngc", "o<spin> sub\no1 while [1]\n#<x> = 1\no1 endwhile\no<spin> endsub\nM2\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  const auto r = m.mdi("o<spin> call");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_TRUE(contains(r.second, "spin.ngc:")) << r.second;
  EXPECT_TRUE(contains(r.second, "MAX_BLOCKS_WITHOUT_OUTPUT = 5000")) << r.second;
  m.ok(m.mdi("G0 X5"), "the next MDI line");
}

TEST(TaskInterpBounds, ALongComputationCompletesCorrectlyAcrossTaskCycles) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("long.ngc", kLong), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  int computing = 0;  // cycles after which the program still computed
  ASSERT_TRUE(m.run_until([&] {
    if (m.program_running() && m.status().task.read_line < 4) ++computing;
    return !m.program_running();
  }, 200000)) << m.errors();
  EXPECT_EQ(m.errors(), "");
  EXPECT_NEAR(m.status().motion.position[0], 20, 1e-9);
  EXPECT_NEAR(m.status().motion.position[1], 10, 1e-9);
  EXPECT_GE(computing, 2) << "400000 lines are read over several cycles, not in one";

  // The same computation in a subroutine called from MDI.
  m.dir.write("nc_files/count.ngc",
              "o<count> sub\n#<n> = 0\no1 repeat [200000]\n#<n> = [#<n> + 1]\no1 endrepeat\n"
              "G0 X[#<n> / 20000]\no<count> endsub\nM2\n");
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("o<count> call"), "call");
  EXPECT_NEAR(m.status().motion.position[0], 10, 1e-9);
}

TEST(TaskInterpBounds, RunFromLineAndItsPreviewReadALongComputationAcrossTaskCycles) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("long.ngc", kLong), "open");
  // Both commands are answered after the cycles that read the 400000
  // lines, not within the cycle that took them.
  const auto answered_after = [&](cnc::ipc::Command c) {
    c.serial = 90000 + static_cast<uint32_t>(c.type);
    EXPECT_TRUE(m.task().handle_command(c, m.reporter));
    EXPECT_EQ(m.reporter.last[c.serial].first, CommandState::Executing);
    int cycles = 0;
    while (m.reporter.last[c.serial].first == CommandState::Executing && cycles < 100000) {
      m.step();
      ++cycles;
    }
    EXPECT_EQ(m.reporter.last[c.serial].first, CommandState::Done) << m.reporter.last[c.serial].second;
    return cycles;
  };
  cnc::ipc::Command preview;
  preview.type = CommandType::TaskPlanRunPreview;
  preview.i[0] = 5;
  EXPECT_GE(answered_after(preview), 2);
  EXPECT_NEAR(m.status().task.run_from_line_start[0], 20, 1e-9);
  cnc::ipc::Command run;
  run.type = CommandType::TaskPlanRun;
  run.i[0] = 5;
  EXPECT_GE(answered_after(run), 2);
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 200000)) << m.errors();
  EXPECT_EQ(m.errors(), "");
  EXPECT_NEAR(m.status().motion.position[0], 20, 1e-9);
  EXPECT_NEAR(m.status().motion.position[1], 10, 1e-9);
}

TEST(TaskInterpBounds, RunFromLineAfterAnEndlessLoopIsRefusedNamingTheLine) {
  TaskMachine m({limit(5000)});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("endless.ngc", kEndless), "open");
  cnc::ipc::Command preview;
  preview.type = CommandType::TaskPlanRunPreview;
  preview.i[0] = 5;
  const auto p = m.send(preview);
  EXPECT_EQ(p.first, CommandState::Rejected);
  EXPECT_TRUE(contains(p.second, "endless.ngc:")) << p.second;
  const auto r = m.send(CommandType::TaskPlanRun, 5);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_TRUE(contains(r.second, "run from line 5 failed: ")) << r.second;
  EXPECT_TRUE(contains(r.second, "MAX_BLOCKS_WITHOUT_OUTPUT")) << r.second;
  EXPECT_FALSE(m.program_running());
}

TEST(TaskProgramFiles, FifosDevicesAndFoldersAreRefusedAtOpenNamingThePath) {
  TaskMachine m;
  const auto fifo = m.dir / "nc_files/pipe.ngc";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::filesystem::create_directories(m.dir / "nc_files/folder.ngc");
  const auto open = [&](const std::string& path) {
    cnc::ipc::Command c;
    c.type = CommandType::TaskPlanOpen;
    c.text.assign(path);
    return m.send(c, 5);  // answered at once, never blocked
  };
  auto r = open(fifo.string());
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_EQ(r.second, "cannot read program " + fifo.string() + ": it is a FIFO (named pipe), not a regular file");
  r = open("/dev/zero");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_EQ(r.second, "cannot read program /dev/zero: it is a character device, not a regular file");
  r = open((m.dir / "nc_files/folder.ngc").string());
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_TRUE(contains(r.second, "it is a directory, not a regular file")) << r.second;
}

TEST(TaskProgramFiles, OverLongLinesAreErrorsNamingTheFileAndLine) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  const auto r = m.open("noline.ngc", std::string(1 << 20, 'G'));
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_TRUE(contains(r.second, "noline.ngc:1: Command too long")) << r.second;
  m.ok(m.open("long.ngc", "G0 X10\nG0 Y10\n(" + std::string(400, 'c') + ")\nG0 X20\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 100000));
  const std::string e = m.errors();
  EXPECT_TRUE(contains(e, "long.ngc:3: Command too long")) << e;
  EXPECT_FALSE(contains(m.log, "program finished")) << m.log;
}

TEST(TaskProgram, M30EndsTheProgramLikeM2) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("m30.ngc", "G0 X10\nM3 S1000\nM30\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 100000)) << "M30 paused instead of ending";
  m.errors();
  EXPECT_TRUE(contains(m.log, "program finished")) << m.log;
  EXPECT_FALSE(m.status().task.paused);
  EXPECT_FALSE(m.status().spindles[0].enabled) << "M30 stops the spindle as M2";
  EXPECT_NEAR(m.status().motion.position[0], 10, 1e-9);
}

TEST(TaskMdi, M30ThenAnotherMdiLineRuns) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.send(mdi_command("M30"), 20000), "M30");
  EXPECT_FALSE(m.status().task.paused);
  m.ok(m.mdi("G0 X5"), "the next MDI line");
  EXPECT_NEAR(m.status().motion.position[0], 5, 1e-9);
}

TEST(TaskProgram, M60StillPausesTheProgram) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("m60.ngc", "G0 X10\nM60\nG0 X20\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.task().interp_state() == InterpState::Paused; }, 100000));
  EXPECT_NEAR(m.status().motion.position[0], 10, 1e-9);
  m.ok(m.send(CommandType::TaskPlanResume), "resume");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 100000));
  EXPECT_NEAR(m.status().motion.position[0], 20, 1e-9);
}
