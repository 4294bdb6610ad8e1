// The task controller: machine states, modes, MDI, program control, run
// from line, against the simulated mill in-process.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include "tests/core/task/fixture.hpp"

using cnc::ipc::CommandState;
using cnc::ipc::CommandType;
using cnc::ipc::InterpState;
using cnc::ipc::TaskMode;
using cnc::ipc::TaskState;
using cnc::testing::TaskMachine;

namespace {
constexpr int kEstop = 1, kReset = 2, kOff = 3, kOn = 4;
constexpr int kManual = 1, kAuto = 2, kMdi = 3;

const char* kProgram =
    "G10 L2 P1 X0 Y0 Z-80\n"             // 1  stock top at machine Z-80
    "G21 G90 G17 G54 G64 P0.01\n"        // 2
    "T2 M6\n"                            // 3
    "G43 H2\n"                           // 4
    "S1200 M3\n"                         // 5
    "M8\n"                               // 6
    "G0 X10 Y10 Z5\n"                    // 7
    "G1 Z-1 F300\n"                      // 8
    "G1 X30 F900\n"                      // 9
    "M1\n"                               // 10
    "G1 Y30\n"                           // 11
    "/G1 X10\n"                          // 12
    "G1 Y10\n"                           // 13
    "G0 Z5\n"                            // 14
    "M5 M9\n"                            // 15
    "M2\n";                              // 16
}  // namespace

TEST(TaskStates, EveryTransitionOfTheDiagram) {
  TaskMachine m;
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  auto r = m.send(CommandType::TaskSetState, kOn);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_EQ(r.second, "the machine is in E-stop: reset it first (estop-reset)");
  r = m.send(CommandType::TaskSetState, kOff);
  EXPECT_EQ(r.second, "the machine is in E-stop");
  m.ok(m.send(CommandType::TaskSetState, kReset), "reset");
  EXPECT_EQ(m.task().state(), TaskState::EstopReset);
  EXPECT_TRUE(m.io().user_enabled());
  m.ok(m.send(CommandType::TaskSetState, kOn), "on");
  EXPECT_EQ(m.task().state(), TaskState::On);
  EXPECT_TRUE(m.status().motion.enabled);
  m.ok(m.send(CommandType::TaskSetState, kOff), "off");
  EXPECT_EQ(m.task().state(), TaskState::Off);
  m.step(3);
  EXPECT_FALSE(m.status().motion.enabled);
  m.ok(m.send(CommandType::TaskSetState, kOn), "on again");
  m.ok(m.send(CommandType::TaskSetState, kEstop), "estop");
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  m.step(3);
  EXPECT_FALSE(m.status().motion.enabled);
  EXPECT_FALSE(m.io().user_enabled());
  r = m.send(CommandType::TaskSetState, 9);
  EXPECT_EQ(r.second, "unknown state 9: expected 1 (E-stop), 2 (reset), 3 (off) or 4 (on)");
}

// "Machine on" is done when every amplifier answered the enable
// (joint.N.amp-ready-in); one that does not within its AMP_READY_TIMEOUT
// disables motion and the command is refused, naming the joint.
TEST(TaskStates, MachineOnIsRefusedWhenAnAmplifierIsNotReadyInTime) {
  TaskMachine m({{"JOINT_1", "AMP_READY_TIMEOUT", "0.05"}}, "setp joint.1.amp-ready-in FALSE\n");
  m.ok(m.send(CommandType::TaskSetState, kReset), "reset");
  const auto r = m.send(CommandType::TaskSetState, kOn);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_EQ(r.second,
            "motion was disabled as the machine was turned on (joint 1's amplifier was not ready yet): see the error "
            "channel");
  EXPECT_NE(m.task().state(), TaskState::On);
  EXPECT_FALSE(m.status().motion.enabled);
  EXPECT_NE(m.errors().find("joint 1 amplifier not ready 0.050 s after enable (joint.1.amp-ready-in stayed false)"),
            std::string::npos);
}

TEST(TaskStates, ResetIsRefusedWhileTheEstopChainStaysOpen) {
  // Break the simulated loop: emc-enable-in is held false.
  TaskMachine m({{"EMCIO", "ESTOP_RESET_TIMEOUT", "0.05"}}, "delsig estop-loop\nsetp iocontrol.0.emc-enable-in FALSE\n");
  const auto r = m.send(CommandType::TaskSetState, kReset);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("the E-stop chain did not close"), std::string::npos) << r.second;
  EXPECT_EQ(m.task().state(), TaskState::Estop);
}

TEST(TaskStates, AnOpeningChainIsAnEstop) {
  TaskMachine m({}, "delsig estop-loop\nnet chain iocontrol.0.emc-enable-in\nsets chain TRUE\n");
  m.power_up_and_home();
  m.hal().set_signal("chain", "FALSE");
  m.step(3);
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  EXPECT_NE(m.errors().find("E-stop chain opened"), std::string::npos);
}

TEST(TaskStates, AMotionFaultTurnsTheMachineOff) {
  TaskMachine m;
  m.power_up_and_home();
  m.hal().set_value("motion.enable", "FALSE");
  m.step(5);
  EXPECT_EQ(m.task().state(), TaskState::Off);
  EXPECT_NE(m.errors().find("motion.enable went false"), std::string::npos);
}

TEST(TaskModes, AutoAndMdiNeedAHomedMachineThatIsOn) {
  TaskMachine m;
  auto r = m.send(CommandType::TaskSetMode, kMdi);
  EXPECT_EQ(r.second, "the machine is not on (state ESTOP)");
  m.ok(m.send(CommandType::TaskSetState, kReset), "reset");
  m.ok(m.send(CommandType::TaskSetState, kOn), "on");
  r = m.send(CommandType::TaskSetMode, kAuto);
  EXPECT_EQ(r.second, "home all joints before AUTO (or set [TRAJ]NO_FORCE_HOMING = 1)");
  m.ok(m.send(CommandType::JointHome, -1), "home");
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  EXPECT_EQ(m.task().mode(), TaskMode::Auto);
  EXPECT_EQ(m.status().motion.mode, cnc::ipc::MotionMode::Coord);
  m.ok(m.send(CommandType::TaskSetMode, kManual), "manual");
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  r = m.send(CommandType::TaskSetMode, 7);
  EXPECT_EQ(r.second, "unknown mode 7: expected 1 (MANUAL), 2 (AUTO) or 3 (MDI)");
}

TEST(TaskModes, JoggingAndHomingNeedManualMode) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  cnc::ipc::Command jog;
  jog.type = CommandType::JogIncr;
  jog.i[0] = 0;
  jog.i[1] = 0;
  jog.d[0] = 10;
  jog.d[1] = 1;
  EXPECT_EQ(m.send(jog).second, "jogging needs MANUAL mode (now MDI)");
  EXPECT_EQ(m.send(CommandType::JointHome, 0).second, "homing needs MANUAL mode (now MDI)");
  m.ok(m.send(CommandType::TaskSetMode, kManual), "manual");
  const double x0 = m.status().motion.position[0];
  m.ok(m.send(jog), "axis jog (teleop)");
  m.run_until([&] { return m.status().motion.inpos; });
  m.step(2);
  EXPECT_NEAR(m.status().motion.position[0], x0 - 0 + 1, 1e-9);
}

TEST(TaskMdi, QueuedLinesRunInOrderAndErrorsSayWhy) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G0 X100 Y50"), "G0");
  m.ok(m.mdi("G1 Z-10 F600"), "G1");
  auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 100, 1e-9);
  EXPECT_NEAR(s.motion.position[2], -10, 1e-9);
  const auto r = m.mdi("G1 X10 Y10 G2");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("modal group"), std::string::npos) << r.second;
  const auto r2 = m.mdi("G0 X500");
  EXPECT_EQ(r2.first, CommandState::Rejected);
  EXPECT_NE(r2.second.find("outside the soft limits"), std::string::npos) << r2.second;
}

TEST(TaskMdi, SplinesBecomeShortLinesEndingOnTheEndPoint) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G17 G0 X10 Y10 Z-10"), "start");
  m.ok(m.mdi("G5 I10 J0 P-10 Q0 X30 Y30 F1200"), "cubic spline");
  const auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 30, 1e-9);
  EXPECT_NEAR(s.motion.position[1], 30, 1e-9);
  EXPECT_EQ(m.errors(), "");
}

TEST(TaskMdi, MacrosFromTheMdiCommandList) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G0 X10 Y10 Z-5"), "move");
  cnc::ipc::Command macro;
  macro.type = CommandType::TaskPlanExecute;
  macro.i[0] = 0;  // "G53 G0 Z0;G53 G0 X280 Y180, Park" (configs/sim)
  m.ok(m.send(macro), "macro 0");
  const auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 280, 1e-9);
  EXPECT_NEAR(s.motion.position[2], 0, 1e-9);
  macro.i[0] = 9;
  EXPECT_EQ(m.send(macro).second, "no [MDI_COMMAND_LIST]MDI_COMMAND_MACRO9 (there are 2)");
}

TEST(TaskProgram, RunsToTheEndWithToolSpindleAndCoolant) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", kProgram), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  bool saw_spindle = false, saw_flood = false;
  ASSERT_TRUE(m.run_until([&] {
    const auto s = m.status();
    saw_spindle = saw_spindle || s.spindles[0].enabled;
    saw_flood = saw_flood || s.io.flood;
    return !m.program_running();
  }, 400000)) << m.errors();
  const auto s = m.status();
  EXPECT_EQ(m.errors(), "");
  EXPECT_EQ(s.io.tool_in_spindle, 2);
  EXPECT_TRUE(saw_spindle);
  EXPECT_TRUE(saw_flood);
  EXPECT_FALSE(s.spindles[0].enabled);
  EXPECT_FALSE(s.io.flood);
  // Final position: X10 Y10 Z5 with G54 Z-80 and T2's length offset 42.5.
  EXPECT_NEAR(s.motion.position[0], 10, 1e-9);
  EXPECT_NEAR(s.motion.position[1], 10, 1e-9);
  EXPECT_NEAR(s.motion.position[2], -80 + 5 + 42.5, 1e-9);
  EXPECT_NE(m.log.find("program finished"), std::string::npos);
}

// A feed move after M3 waits for spindle.0.at-speed; past
// [SPINDLE_0]AT_SPEED_TIMEOUT the program is aborted naming the spindle.
TEST(TaskProgram, SpindleAtSpeedTimeoutAbortsTheProgramNamingTheSpindle) {
  TaskMachine m({{"SPINDLE_0", "AT_SPEED_TIMEOUT", "0.2"}}, "setp spindle.0.at-speed FALSE\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X10 Y0 Z0\nM3 S1000\nG1 X50 F3000\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  bool saw_wait = false;
  ASSERT_TRUE(m.run_until([&] {
    saw_wait = saw_wait || m.status().motion.spindle_wait == 0;
    return !m.program_running();
  }, 20000));
  EXPECT_TRUE(saw_wait);
  const std::string errors = m.errors();
  EXPECT_NE(errors.find("program aborted at line 3: spindle 0 did not reach speed within 0.2 s "
                        "([SPINDLE_0]AT_SPEED_TIMEOUT; spindle.0.at-speed stayed FALSE)"),
            std::string::npos)
      << errors;
  m.step(10);
  EXPECT_NEAR(m.status().motion.position[0], 10, 1e-9);  // the feed move never started
  EXPECT_FALSE(m.status().spindles[0].enabled);           // the abort stopped the spindle
}

TEST(TaskProgram, PauseHoldsResumeFinishes) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X0 Y0 Z0\nG1 X200 F3000\nG1 Y150\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.position[0] > 50; }));
  m.ok(m.send(CommandType::TaskPlanPause), "pause");
  m.step(500);
  const double x = m.status().motion.position[0];
  m.step(200);
  EXPECT_EQ(m.status().motion.position[0], x);
  EXPECT_EQ(m.task().interp_state(), InterpState::Paused);
  EXPECT_EQ(m.send(CommandType::TaskSetMode, kManual).second,
            "cannot change to MANUAL mode while a program or MDI runs: abort it first");
  m.ok(m.send(CommandType::TaskPlanResume), "resume");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 400000));
  EXPECT_NEAR(m.status().motion.position[1], 150, 1e-9);
}

TEST(TaskProgram, AbortStopsMotionAndTheProgram) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X0 Y0\nS1000 M3\nG1 X200 F2000\nG1 Y150\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().task.current_line == 3 && m.status().motion.position[0] > 20; }));
  m.ok(m.send(CommandType::TaskAbort), "abort");
  EXPECT_FALSE(m.program_running());
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.inpos; }));
  EXPECT_LT(m.status().motion.position[0], 200);
  EXPECT_FALSE(m.status().spindles[0].enabled) << "abort stops the spindle";
}

TEST(TaskProgram, OptionalStopAndBlockDelete) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", kProgram), "open");
  m.ok(m.send(CommandType::TaskPlanSetOptionalStop, 1), "M1 on");
  m.ok(m.send(CommandType::TaskPlanSetBlockDelete, 1), "block delete on");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.task().interp_state() == InterpState::Paused; }, 400000)) << m.errors();
  const auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 30, 1e-9) << "stopped at M1 after line 9";
  m.ok(m.send(CommandType::TaskPlanResume), "resume");
  double min_x = 1e9;
  ASSERT_TRUE(m.run_until([&] {
    const auto st = m.status();
    if (st.motion.position[1] > 29) min_x = std::min(min_x, st.motion.position[0]);
    return !m.program_running();
  }, 400000));
  EXPECT_NEAR(min_x, 30, 1e-9) << "the /G1 X10 line was skipped";
}

TEST(TaskProgram, SingleStepRunsOneBlockAtATime) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X10 Y10\nG0 X20\nG0 X30\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanStep), "step 1");
  ASSERT_TRUE(m.run_until([&] { return m.task().interp_state() == InterpState::Paused; }));
  EXPECT_NEAR(m.status().motion.position[0], 10, 1e-9);
  m.ok(m.send(CommandType::TaskPlanStep), "step 2");
  ASSERT_TRUE(m.run_until([&] {
    return m.task().interp_state() == InterpState::Paused && m.status().motion.position[0] > 19;
  }));
  EXPECT_NEAR(m.status().motion.position[0], 20, 1e-9);
}

TEST(TaskProgram, RunFromLineRestoresToolOffsetsSpindleAndCoolant) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", kProgram), "open");
  cnc::ipc::Command preview;
  preview.type = CommandType::TaskPlanRunPreview;
  preview.i[0] = 11;
  m.ok(m.send(preview), "preview");
  m.errors();
  EXPECT_NE(m.log.find("run from line 11"), std::string::npos) << m.log;
  EXPECT_EQ(m.status().task.run_from_line_pending, 11);
  EXPECT_NEAR(m.status().task.run_from_line_start[0], 30, 1e-9) << "where line 10 leaves the tool";
  m.ok(m.send(CommandType::TaskPlanRun, 11), "run from 11");
  bool spindle = false, flood = false;
  ASSERT_TRUE(m.run_until([&] {
    const auto s = m.status();
    spindle = spindle || s.spindles[0].enabled;
    flood = flood || s.io.flood;
    return !m.program_running();
  }, 400000)) << m.errors();
  EXPECT_EQ(m.status().io.tool_in_spindle, 2) << "the tool of line 3 was loaded";
  EXPECT_TRUE(spindle);
  EXPECT_TRUE(flood);
  EXPECT_NEAR(m.status().motion.position[2], -80 + 5 + 42.5, 1e-9) << "G54 and G43 H2 were restored";
}

TEST(TaskProgram, ProgramErrorsNameTheLineAndStopTheProgram) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("bad.ngc", "G0 X10\nG1 X20 F100\nG2 X30 Y0\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 100000));
  const std::string e = m.errors();
  EXPECT_NE(e.find("bad.ngc:3:"), std::string::npos) << e;
}

TEST(TaskRules, CommandsAreRefusedWithReasons) {
  TaskMachine m;
  EXPECT_EQ(m.send(CommandType::TaskPlanRun, 0).second, "running a program needs AUTO mode (now MANUAL)");
  EXPECT_EQ(m.send(CommandType::TaskPlanPause).second, "nothing is running to pause");
  EXPECT_EQ(m.send(CommandType::TaskPlanResume).second, "nothing is paused");
  EXPECT_EQ(m.send(CommandType::CoolantFloodOn).second, "the machine is not on (state ESTOP)");
  EXPECT_EQ(m.send(CommandType::JointHome, 0).second, "the machine is not on (state ESTOP)");
  cnc::ipc::Command open;
  open.type = CommandType::TaskPlanOpen;
  open.text.assign("/nonexistent/x.ngc");
  EXPECT_EQ(m.send(open).second, "cannot read program /nonexistent/x.ngc: No such file or directory");
}

// A bad INI value the task reads is an error at start-up naming the key, not
// a controller that stops later when an operator presses "spindle faster".
TEST(TaskRules, BadSpindleIncrementStopsTheStartNamingTheKey) {
  try {
    TaskMachine m({{"SPINDLE_0", "INCREMENT", "fast"}});
    FAIL() << "a non-number INCREMENT was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("INCREMENT"), std::string::npos) << e.what();
  }
}

// A program starts where the machine stands: axes it does not name stay
// put, whatever moved the machine before (MDI, a jog, an aborted program)
// and whatever offsets are active. (It used to start as if the machine
// stood at machine zero: Y and Z travelled back to 0 at rapid.)
namespace {
void run_program(TaskMachine& m, const std::string& text) {
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("axes.ngc", text), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 400000)) << m.errors();
  ASSERT_EQ(m.errors(), "");
}
void expect_at(TaskMachine& m, double x, double y, double z) {
  const auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], x, 1e-9);
  EXPECT_NEAR(s.motion.position[1], y, 1e-9);
  EXPECT_NEAR(s.motion.position[2], z, 1e-9);
}
}  // namespace

TEST(TaskProgram, AfterAnMdiMoveAProgramMovesOnlyTheAxesItNames) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G53 G0 X200 Y150 Z-60"), "mdi move");
  run_program(m, "G0 X250\nM2\n");
  expect_at(m, 250, 150, -60);
  // Relative moves start from there too (not refused as outside the limits).
  run_program(m, "G91 G0 X-5\nG90\nM2\n");
  expect_at(m, 245, 150, -60);
}

TEST(TaskProgram, AfterAJogAProgramMovesOnlyTheAxesItNames) {
  TaskMachine m;
  m.power_up_and_home();
  cnc::ipc::Command jog;
  jog.type = CommandType::JogAbs;
  jog.i[0] = 2;  // axis Z, teleop
  jog.d[0] = 50;
  jog.d[1] = -10;
  m.ok(m.send(jog), "jog z");
  jog.i[0] = 1;
  jog.d[1] = 150;
  m.ok(m.send(jog), "jog y");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.inpos; }));
  run_program(m, "G0 X250\nM2\n");
  expect_at(m, 250, 150, -10);
}

TEST(TaskProgram, WithAWorkOffsetAProgramMovesOnlyTheAxesItNames) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G10 L2 P1 X100 Y50 Z-80"), "G54");
  m.ok(m.mdi("G54 G0 X10 Y20 Z5"), "mdi move");
  run_program(m, "G54 G0 X30\nM2\n");
  expect_at(m, 130, 70, -75);
}

TEST(TaskProgram, AfterAnAbortAProgramMovesOnlyTheAxesItNames) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G53 G0 X0 Y0 Z-20\nG53 G1 Y150 F1500\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.position[1] < 1; }));
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.position[1] > 40; }));
  m.ok(m.send(CommandType::TaskAbort), "abort");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.inpos; }));
  const double y = m.status().motion.position[1];
  ASSERT_GT(y, 40);
  ASSERT_LT(y, 150);
  run_program(m, "G0 X120\nM2\n");
  expect_at(m, 120, y, -20);
}

namespace {
// One servo cycle is told that the thread is late (as after a stall or a
// streak of overruns), then the thread is on time again.
void servo_thread_late(TaskMachine& m, uint32_t streak, int64_t missed) {
  m.cycle_info().overrun_streak = streak;
  m.cycle_info().missed_cycles = missed;
  m.step();
  m.cycle_info().overrun_streak = 0;
  m.cycle_info().missed_cycles = 0;
}
}  // namespace

TEST(TaskOverrun, HoldPausesTheProgramAndResumeFinishesIt) {
  TaskMachine m({{"EMCMOT", "OVERRUN_ACTION", "HOLD"}});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X0 Y0 Z0\nG1 X200 F3000\nG1 Y150\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().task.current_line == 2 && m.status().motion.position[0] > 50; }));
  servo_thread_late(m, 3, 1);
  m.step(500);
  EXPECT_TRUE(m.status().task.paused);
  EXPECT_EQ(m.task().interp_state(), InterpState::Paused);
  const double x = m.status().motion.position[0];
  m.step(200);
  EXPECT_EQ(m.status().motion.position[0], x) << "held until the operator resumes";
  m.errors();
  EXPECT_NE(m.log.find("paused: the servo thread is late ([EMCMOT]OVERRUN_ACTION = HOLD); resume when ready"),
            std::string::npos)
      << m.log;
  m.ok(m.send(CommandType::TaskPlanResume), "resume");
  m.step(50);
  EXPECT_FALSE(m.status().task.paused) << "the resume is not taken back by the hold it ended";
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 400000));
  EXPECT_NEAR(m.status().motion.position[1], 150, 1e-9);
}

TEST(TaskOverrun, StopTurnsTheMachineOffWithTheReason) {
  TaskMachine m({{"EMCMOT", "OVERRUN_ACTION", "STOP"}});
  m.power_up_and_home();
  ASSERT_EQ(m.task().state(), TaskState::On);
  servo_thread_late(m, 1, 2000);
  m.step(5);
  EXPECT_EQ(m.task().state(), TaskState::Off);
  EXPECT_NE(m.errors().find("the servo thread is late: 1 consecutive overruns, 2000 periods missed just now "
                            "(OVERRUN_ACTION = STOP): motion disabled"),
            std::string::npos);
}

TEST(TaskOverrun, WarnLeavesTheMachineOnAndTheProgramRunning) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X0 Y0 Z0\nG1 X200 F3000\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().task.current_line == 2 && m.status().motion.position[0] > 50; }));
  servo_thread_late(m, 1, 2000);
  m.step(50);
  EXPECT_EQ(m.task().state(), TaskState::On);
  EXPECT_FALSE(m.status().task.paused);
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 400000));
  EXPECT_EQ(m.errors(), "");
}

TEST(TaskOverrun, HoldWithNothingRunningLeavesTheNextMdiFree) {
  TaskMachine m({{"EMCMOT", "OVERRUN_ACTION", "HOLD"}});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G0 X10 Y10 Z0"), "first move");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.inpos && m.status().task.interp_state == InterpState::Idle; }));
  servo_thread_late(m, 3, 1);
  m.step(5);
  EXPECT_FALSE(m.status().task.paused);
  m.ok(m.mdi("G0 X20"), "second move");
  ASSERT_TRUE(m.run_until([&] { return m.status().motion.inpos && m.status().motion.position[0] == 20; }, 20000))
      << "motion was resumed: the move ran";
}

// Nothing acknowledged is lost: an MDI line that changes a persistent
// parameter (G10 L2) is answered "done" only after the parameter file holds
// it; when the file cannot be written the line is rejected with the reason
// and the error is posted (it used to answer done and post nothing).
TEST(TaskParameters, DoneFollowsTheDurableWriteOfTheParameterFile) {
  cnc::testing::TempDir vars;
  const auto file = vars / "sim.var";
  TaskMachine m({{"RS274NGC", "PARAMETER_FILE", file.string()}});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G10 L2 P1 X33"), "G10 L2");
  // No step after the answer: the file already holds the offset.
  const std::string text = TaskMachine::read_text(file);
  EXPECT_NE(text.find("5221\t33.000000"), std::string::npos) << text;
  // A line that changes nothing persistent does not rewrite the file.
  struct stat before {}, after {};
  ASSERT_EQ(::stat(file.c_str(), &before), 0);
  m.ok(m.mdi("G0 X10"), "move");
  ASSERT_EQ(::stat(file.c_str(), &after), 0);
  EXPECT_EQ(before.st_ino, after.st_ino) << "rewritten although nothing persistent changed";
}

TEST(TaskParameters, AParameterFileThatCannotBeWrittenRejectsTheLineAndSaysWhy) {
  cnc::testing::TempDir vars;
  const auto folder = vars / "config";
  std::filesystem::create_directories(folder);
  TaskMachine m({{"RS274NGC", "PARAMETER_FILE", (folder / "sim.var").string()}});
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  std::filesystem::remove_all(folder);  // as a full or read-only disk: the write fails
  const auto r = m.mdi("G10 L2 P1 X33");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("the parameter file could not be written"), std::string::npos) << r.second;
  EXPECT_NE(m.errors().find("are lost at a restart"), std::string::npos);
  // The work-offset command of the screen says so too.
  cnc::ipc::Command c;
  c.type = CommandType::SetWorkOffset;
  c.i[0] = 1;
  c.d[0] = 44;
  const auto w = m.send(c);
  EXPECT_EQ(w.first, CommandState::Rejected);
  EXPECT_NE(w.second.find("could not be written"), std::string::npos) << w.second;
}

TEST(TaskParameters, TemporaryFilesOfAnInterruptedSaveAreRemovedAtStartAndAMissingFolderIsAnError) {
  cnc::testing::TempDir vars;
  const auto stale = vars.write(".sim.var.Ab12Cd", "5221\t1\n");
  const auto fresh = vars.write(".sim.var.Zz99Yy", "5221\t2\n");  // perhaps being written right now
  const timespec old_times[2] = {{1'000'000'000, 0}, {1'000'000'000, 0}};
  ASSERT_EQ(::utimensat(AT_FDCWD, stale.c_str(), old_times, 0), 0);
  {
    TaskMachine m({{"RS274NGC", "PARAMETER_FILE", (vars / "sim.var").string()}});
  }
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_TRUE(std::filesystem::exists(fresh));
  try {
    TaskMachine m({{"RS274NGC", "PARAMETER_FILE", (vars / "missing" / "sim.var").string()}});
    FAIL() << "a parameter file in a missing folder was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("the folder of the parameter file does not exist"), std::string::npos)
        << e.what();
  }
}

// The status shows the modal state of the line motion executes, not of the
// interpreter's read-ahead (LinuxCNC 2.9's state tags): during the drilling
// cycle the interpreter has already read M5 and F0 further on.
TEST(TaskStateTags, StatusShowsTheCodesFeedAndSpeedOfTheExecutingLineNotOfTheReadAhead) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("drill.ngc",
              "G21 G90 G17 G54\n"                    // 1
              "S1000 M3\n"                            // 2
              "G0 X0 Y0 Z-10\n"                       // 3
              "G81 X10 Y0 Z-40 R-12 F200\n"           // 4
              "G80\n"                                 // 5
              "M5\n"                                  // 6
              "F0\n"                                  // 7
              "G0 Z-5\n"                              // 8
              "M2\n"),                                // 9
       "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] {
    const auto s = m.status();
    return s.task.current_line == 4 && s.task.read_line >= 7 && s.motion.current_vel > 0;
  }, 400000)) << m.errors();
  const auto s = m.status();
  EXPECT_EQ(s.task.active_gcodes[0], 810);
  EXPECT_EQ(s.task.active_mcodes[0], 3);
  EXPECT_DOUBLE_EQ(s.task.active_settings[1], 200);
  EXPECT_DOUBLE_EQ(s.task.active_settings[2], 1000);
  ASSERT_TRUE(m.run_until([&] { return !m.program_running(); }, 400000)) << m.errors();
  // At rest and idle: the interpreter's own state (M2 reset the spindle to M5).
  const auto e = m.status();
  EXPECT_EQ(e.task.active_mcodes[0], 5);
}

// Everything given to motion has run once it is at rest: a block executed
// by the task (M5, at rest) shows its own state while the program goes on.
TEST(TaskStateTags, WithMotionAtRestTheLastExecutedItemsStateIsShown) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("dwell.ngc",
              "G21 G90\n"            // 1
              "S500 M3\n"             // 2
              "G1 X5 F100\n"          // 3
              "M5\n"                  // 4
              "G4 P0.5\n"             // 5
              "M2\n"),                // 6
       "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] {
    const auto s = m.status();
    return s.task.current_line == 3 && s.motion.current_vel > 0;
  }, 400000)) << m.errors();
  EXPECT_EQ(m.status().task.active_mcodes[0], 3);
  ASSERT_TRUE(m.run_until([&] { return !m.status().spindles[0].enabled; }, 400000)) << m.errors();
  EXPECT_EQ(m.status().task.active_mcodes[0], 5);
}

// A rejected MDI line is not shown as running afterwards, and it is not
// counted as an error of a program (errors_since_start: the program's).
TEST(TaskStaleStatus, ARejectedMdiLineIsNoLongerRunningAndNotAProgramError) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  const auto r = m.mdi("G0 X1000");
  ASSERT_EQ(r.first, CommandState::Rejected) << r.second;
  m.step(5);
  const auto s = m.status();
  EXPECT_EQ(std::string(s.task.command.view()), "");
  EXPECT_EQ(s.task.errors_since_start, 0);
}

TEST(TaskPython, AnMdiCallOfAPythonOwordFunctionMovesTheMachineAndReturnsItsValue) {
  // [PYTHON] as LinuxCNC's: TOPLEVEL imports the module `oword`, whose
  // functions are O-word subroutines; emccanon calls are machine moves.
  cnc::testing::TempDir py;
  py.write("oword.py",
           "import emccanon\n"
           "def goto(self, x, y):\n"
           "    emccanon.STRAIGHT_FEED(0, x, y, -5, 0, 0, 0, 0, 0, 0)\n"
           "def square(self, v):\n"
           "    return v * v\n");
  py.write("subs.py", "import oword\n");
  TaskMachine m({}, "", "",
                "[PYTHON]\nPATH_PREPEND = " + py.path().string() + "\nTOPLEVEL = " + (py / "subs.py").string() + "\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G1 F600 X0 Y0 Z0"), "start");
  m.ok(m.mdi("o<goto> call [12] [34]"), "python goto");
  auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 12, 1e-9);
  EXPECT_NEAR(s.motion.position[1], 34, 1e-9);
  EXPECT_NEAR(s.motion.position[2], -5, 1e-9);
  m.ok(m.mdi("o<square> call [3]"), "python square");
  m.ok(m.mdi("G0 X#<_value>"), "move to the value");
  EXPECT_NEAR(m.status().motion.position[0], 9, 1e-9);
  EXPECT_EQ(m.errors(), "");
}

TEST(TaskPython, AGeneratorRemapWaitsForTheMachineInTheTaskAndGoesOnFromWhereItStopped) {
  // A remapped M420 whose Python body moves, waits for the machine (yield
  // INTERP_EXECUTE_FINISH: the task lets motion finish, synchronises and
  // calls the interpreter again) and then moves on from the position read.
  cnc::testing::TempDir py;
  py.write("remap.py",
           "from interpreter import *\n"
           "def m420(self, **words):\n"
           "    self.execute('G1 F600 X10')\n"
           "    yield INTERP_EXECUTE_FINISH\n"
           "    self.params['_seen'] = self.current_x\n"
           "    self.execute('G1 Y[#<_seen> + 1]')\n"
           "    yield INTERP_EXECUTE_FINISH\n"
           "    self.execute('G1 Z-[#<_seen> / 2]')\n");
  py.write("subs.py", "import remap\n");
  TaskMachine m({{"RS274NGC", "REMAP", "M420 modalgroup=10 py=m420"}}, "", "",
                "[PYTHON]\nPATH_PREPEND = " + py.path().string() + "\nTOPLEVEL = " + (py / "subs.py").string() + "\n");
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G0 X0 Y0 Z0"), "start");
  m.ok(m.mdi("M420"), "remapped M420");
  const auto s = m.status();
  EXPECT_NEAR(s.motion.position[0], 10, 1e-9);
  EXPECT_NEAR(s.motion.position[1], 11, 1e-9);
  EXPECT_NEAR(s.motion.position[2], -5, 1e-9);
  EXPECT_EQ(m.errors(), "");
}

TEST(TaskMdi, AProbeWithoutContactInMdiIsRejectedNamingTheLineNotAProgram) {
  // motion.probe-input is not connected in this mill: the probe never trips
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kMdi), "mdi");
  m.ok(m.mdi("G0 X10 Y10 Z-5"), "start");
  const auto r = m.mdi("G38.2 Z-15 F600");
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_EQ(r.second, "MDI G38.2 Z-15 F600: the probe move ended without contact");
}
