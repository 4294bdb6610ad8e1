// The I/O controller's tool changer: both kinds through the HAL handshake,
// timeouts, abort during a change, and a tool table that survives a crash
// in the middle of a save.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/tooltable/tool_table.hpp"
#include "tests/core/task/fixture.hpp"

using cnc::ipc::CommandState;
using cnc::ipc::CommandType;
using cnc::testing::TaskMachine;

namespace {
void auto_mode(TaskMachine& m) {
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, 3), "mdi");
}
}  // namespace

TEST(ToolChanger, NonRandomCopiesToolDataToTheSpindle) {
  TaskMachine m;
  auto_mode(m);
  int prepares = 0;
  m.ok(m.mdi("T3 M6"), "T3 M6");
  EXPECT_EQ(m.status().io.tool_in_spindle, 3);
  EXPECT_DOUBLE_EQ(m.status().io.tool_diameter, 5.0);  // its D (halui.tool.diameter)
  EXPECT_EQ(m.hal().get_value("iocontrol.0.tool-number"), "3");
  EXPECT_EQ(m.hal().get_value("sim-toolchanger.changes"), "1");
  m.ok(m.mdi("T1 M6"), "T1 M6");
  EXPECT_EQ(m.status().io.tool_in_spindle, 1);
  EXPECT_DOUBLE_EQ(m.status().io.tool_diameter, 6.0);
  // Pockets never move on a non-random changer.
  const auto t = cnc::tooltable::ToolTable::load(m.dir / "tool.tbl", cnc::tooltable::ChangerKind::NonRandom);
  EXPECT_EQ(t.at(*t.find_tool(3)).pocket, 3);
  (void)prepares;
}

TEST(ToolChanger, RandomChangerSwapsPocketsAndSavesTheTable) {
  TaskMachine m({}, "", "T1 P1 Z10\nT2 P2 Z20\nT3 P3 Z30\n", "[EMCIO]\nRANDOM_TOOLCHANGER = 1\n");
  auto_mode(m);
  m.ok(m.mdi("T2 M6"), "T2 M6");
  m.ok(m.mdi("T3 M6"), "T3 M6");
  // T2 went back into pocket 3, where T3 came from.
  const auto t = cnc::tooltable::ToolTable::load(m.dir / "tool.tbl", cnc::tooltable::ChangerKind::Random);
  ASSERT_TRUE(t.find_pocket(3));
  EXPECT_EQ(t.at(*t.find_pocket(3)).number, 2);
  EXPECT_EQ(t.spindle().number, 3);
}

TEST(ToolChanger, AHungChangerIsAnErrorNotAHang) {
  TaskMachine m({{"EMCIO", "TOOL_CHANGE_TIMEOUT", "0.05"}, {"EMCIO", "TOOL_PREPARE_TIMEOUT", "0.05"}},
                "setp sim-toolchanger.hang TRUE\n");
  auto_mode(m);
  const auto r = m.mdi("T2 M6");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("did not"), std::string::npos) << r.second;
  EXPECT_FALSE(m.hal().get_value("iocontrol.0.tool-prepare") == "TRUE");
  EXPECT_FALSE(m.hal().get_value("iocontrol.0.tool-change") == "TRUE");
}

TEST(ToolChanger, AbortDuringAChangeDropsTheHandshake) {
  TaskMachine m({}, "setp sim-toolchanger.change-time 5\n");
  auto_mode(m);
  cnc::ipc::Command c;
  c.type = CommandType::TaskPlanExecute;
  c.i[0] = -1;
  c.text.assign("T4 M6");
  c.serial = 900;
  ASSERT_TRUE(m.task().handle_command(c, m.reporter));
  ASSERT_TRUE(m.run_until([&] { return m.hal().get_value("iocontrol.0.tool-change") == "TRUE"; }, 20000));
  m.ok(m.send(CommandType::TaskAbort), "abort");
  m.step(3);
  EXPECT_EQ(m.hal().get_value("iocontrol.0.tool-change"), "FALSE");
  EXPECT_EQ(m.status().io.tool_in_spindle, 0) << "the change did not complete";
  EXPECT_EQ(m.reporter.last[900].first, CommandState::Rejected);
}

TEST(ToolTable, G10L1UpdatesAndPersists) {
  TaskMachine m;
  auto_mode(m);
  m.ok(m.mdi("G10 L1 P2 Z33.25 R4"), "G10 L1");
  const auto t = cnc::tooltable::ToolTable::load(m.dir / "tool.tbl", cnc::tooltable::ChangerKind::NonRandom);
  const auto& tool = t.at(*t.find_tool(2));
  EXPECT_DOUBLE_EQ(tool.offset[2], 33.25);
  EXPECT_DOUBLE_EQ(tool.diameter, 8);
}

TEST(ToolTable, AKilledSaveLeavesTheOldOrTheNewTable) {
  cnc::testing::TempDir dir;
  const auto path = dir / "tool.tbl";
  cnc::tooltable::ToolTable small(cnc::tooltable::ChangerKind::NonRandom);
  cnc::tooltable::ToolTable big(cnc::tooltable::ChangerKind::NonRandom);
  for (int i = 1; i <= 3; ++i) {
    cnc::tooltable::Tool t;
    t.number = i;
    t.pocket = i;
    small.update_tool(t);
  }
  for (int i = 1; i <= 800; ++i) {
    cnc::tooltable::Tool t;
    t.number = i;
    t.pocket = i;
    t.diameter = i * 0.5;
    t.comment = "a long comment to make the file bigger " + std::to_string(i);
    big.update_tool(t);
  }
  small.save(path);
  unsigned seed = 4242;
  for (int round = 0; round < 30; ++round) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      for (;;) {
        big.save(path);
        small.save(path);
      }
    }
    ::usleep(1000 + (rand_r(&seed) % 20000));
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    // The table must parse, and be exactly one of the two versions.
    const auto loaded = cnc::tooltable::ToolTable::load(path, cnc::tooltable::ChangerKind::NonRandom);
    const auto n = loaded.tools().size();
    EXPECT_TRUE(n == 3 || n == 800) << "round " << round << ": " << n << " tools (seed 4242)";
  }
}

// A save killed between writing its temporary file and renaming it leaves
// the temporary behind; the I/O controller removes it at start.
TEST(ToolTable, TemporaryFilesOfAKilledSaveAreRemovedAtStart) {
  cnc::testing::TempDir dir;
  const auto table = dir.write("tool.tbl", "T1 P1 Z10 ;one\n");
  const auto stale = dir.write(".tool.tbl.Qw3rTy", "T1 P1 Z10 ;half\n");
  const timespec old_times[2] = {{1'000'000'000, 0}, {1'000'000'000, 0}};
  ASSERT_EQ(::utimensat(AT_FDCWD, stale.c_str(), old_times, 0), 0);
  cnc::hal::Hal hal;
  cnc::io::IoConfig cfg;
  cfg.tool_table = table;
  cnc::io::IoController io(hal, cfg, nullptr);
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_TRUE(std::filesystem::exists(table));
}
