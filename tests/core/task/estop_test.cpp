// E-stop does not depend on the task cycle: a request through the E-stop
// word or an open E-stop chain disables the machine in the servo thread
// while the task stands still; the task catches up on its next cycle with
// the reason. Motion that stops running is an E-stop naming the function;
// an amplifier fault (a spindle's too) aborts the program with the reason
// and the drive's explanation.
#include <gtest/gtest.h>
#include <unistd.h>

#include "tests/core/task/fixture.hpp"

using cnc::ipc::CommandState;
using cnc::ipc::CommandType;
using cnc::ipc::TaskState;
using cnc::testing::TaskMachine;

namespace {
constexpr int kReset = 2, kOn = 4;
constexpr int kManual = 1, kAuto = 2;

// Joint 0 jogging at 20 units/s.
void start_jog(TaskMachine& m) {
  m.ok(m.send(CommandType::TaskSetMode, kManual), "manual");
  cnc::ipc::Command jog;
  jog.type = CommandType::JogCont;
  jog.i[0] = 0;
  jog.i[1] = 1;
  jog.d[0] = -20;
  m.ok(m.send(jog), "jog");
  m.step(200);
  ASSERT_GT(std::fabs(m.status().joints[0].velocity), 1);
}
}  // namespace

TEST(TaskEstop, ARequestStopsTheServoWhileTheTaskStandsStillThenTheTaskNamesTheRequester) {
  TaskMachine m;
  m.power_up_and_home();
  start_jog(m);
  const uint64_t word = cnc::ipc::bump_estop_request(m.estop, ::getpid());
  m.servo_only(1);  // no task cycle: the task is stalled
  EXPECT_EQ(m.hal().get_value("joint.0.amp-enable-out"), "FALSE");
  EXPECT_EQ(m.hal().get_value("motion.motion-enabled"), "FALSE");
  EXPECT_TRUE(cnc::ipc::estop_acknowledges(m.estop.acknowledged.load(), word));
  const auto ms = m.motion().status();
  EXPECT_TRUE(ms.traj.estop_latched);
  EXPECT_EQ(ms.traj.estop_pid, ::getpid());
  EXPECT_EQ(m.task().state(), TaskState::On) << "the task has not run yet";
  m.task_cycle();
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  m.errors();
  EXPECT_NE(m.log.find("E-stop requested by process " + std::to_string(::getpid())), std::string::npos) << m.log;
  EXPECT_FALSE(m.io().user_enabled()) << "the task opens the chain too";
}

TEST(TaskEstop, AnOpenChainStopsTheServoWithoutTheTask) {
  TaskMachine m({}, "delsig estop-loop\nnet chain iocontrol.0.emc-enable-in\nsets chain TRUE\n");
  m.power_up_and_home();
  start_jog(m);
  m.hal().set_signal("chain", "FALSE");
  m.servo_only(1);
  EXPECT_EQ(m.hal().get_value("joint.0.amp-enable-out"), "FALSE");
  EXPECT_EQ(m.motion().status().traj.estop_cause, cnc::ipc::EstopCause::ChainOpen);
  m.task_cycle();
  EXPECT_EQ(m.task().state(), TaskState::Estop);
  EXPECT_NE(m.errors().find("E-stop chain opened"), std::string::npos);
}

TEST(TaskEstop, ResetClearsTheLatchOnlyWithTheChainClosed) {
  TaskMachine m({{"EMCIO", "ESTOP_RESET_TIMEOUT", "0.05"}},
                "delsig estop-loop\nnet chain iocontrol.0.emc-enable-in\nsets chain TRUE\n");
  m.power_up_and_home();
  cnc::ipc::bump_estop_request(m.estop, 1);
  m.step(2);
  ASSERT_EQ(m.task().state(), TaskState::Estop);
  EXPECT_TRUE(m.motion().status().traj.estop_latched);
  // The chain opens (a pressed button) and stays open: no reset.
  m.hal().set_signal("chain", "FALSE");
  auto r = m.send(CommandType::TaskSetState, kReset);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("the E-stop chain did not close"), std::string::npos) << r.second;
  EXPECT_TRUE(m.motion().status().traj.estop_latched);
  // Closed again: the reset clears the latch and the machine comes on.
  m.hal().set_signal("chain", "TRUE");
  m.ok(m.send(CommandType::TaskSetState, kReset), "reset");
  EXPECT_FALSE(m.motion().status().traj.estop_latched);
  m.ok(m.send(CommandType::TaskSetState, kOn), "on");
  EXPECT_TRUE(m.status().motion.enabled);
}

// In the daemon the task closes the chain and, in the same task cycle,
// asks motion to clear its latch: motion must judge the chain as it is then.
TEST(TaskEstop, ResetSucceedsWhenTheChainClosesWithinTheSameTaskCycle) {
  TaskMachine m;
  m.step(2);
  ASSERT_TRUE(m.motion().status().traj.estop_latched) << "the chain is open at start-up";
  cnc::ipc::Command reset;
  reset.type = CommandType::TaskSetState;
  reset.i[0] = kReset;
  reset.serial = 1000;
  ASSERT_TRUE(m.task().handle_command(reset, m.reporter));
  m.task_cycle();  // the waiter sees the chain closed and sends ESTOP_RESET now
  ASSERT_TRUE(m.run_until([&] {
    const auto it = m.reporter.last.find(1000);
    return it != m.reporter.last.end() && it->second.first != CommandState::Executing &&
           it->second.first != CommandState::Received;
  }));
  EXPECT_EQ(m.reporter.last[1000].first, CommandState::Done) << m.reporter.last[1000].second;
  EXPECT_EQ(m.task().state(), TaskState::EstopReset);
}

TEST(TaskEstop, MotionThatStopsRunningIsAnEstopNamingTheFunction) {
  TaskMachine m;
  m.power_up_and_home();
  start_jog(m);
  m.hal().remove_function("motion-controller", "servo-thread");
  ASSERT_TRUE(m.run_until([&] { return m.task().state() == TaskState::Estop; }, 2'000'000));
  const std::string e = m.errors();
  EXPECT_NE(e.find("E-stop: motion-controller is in no HAL thread any more (removed with delf?)"), std::string::npos)
      << e;
  const auto s = m.status();
  EXPECT_TRUE(s.motion.servo_stalled);
  EXPECT_TRUE(s.motion.inpos) << "the status does not keep saying 'moving'";
  EXPECT_EQ(s.motion.current_vel, 0.0);
  EXPECT_FALSE(m.io().user_enabled());
  // No reset while motion does not run.
  const auto r = m.send(CommandType::TaskSetState, kReset);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("cannot reset the E-stop: motion-controller is in no HAL thread"), std::string::npos)
      << r.second;
  // Back in the thread: motion runs, the E-stop can be reset.
  m.hal().add_function("motion-controller", "servo-thread", 6);
  m.step(10);
  EXPECT_FALSE(m.status().motion.servo_stalled);
  m.ok(m.send(CommandType::TaskSetState, kReset), "reset");
}

TEST(TaskFaults, ASpindleAmplifierFaultAbortsTheProgramSayingWhichDriveAndWhy) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kAuto), "auto");
  m.ok(m.open("p.ngc", "G0 X0 Y0 Z0\nS1000 M3\nG1 X200 F600\nG1 Y150\nM2\n"), "open");
  m.ok(m.send(CommandType::TaskPlanRun, 0), "run");
  ASSERT_TRUE(m.run_until([&] { return m.status().task.current_line == 3 && m.status().motion.position[0] > 20; }));
  // The drive panel as the drive layer contributes it to the status before
  // the task (there are no drives in this machine): the spindle's drive,
  // not explained yet, and an axis drive.
  cnc::ipc::Status drives{};
  drives.drives[0].present = true;
  drives.drives[0].joint = -1;
  drives.drives[0].name.assign("spindle");
  drives.drives[1].present = true;
  drives.drives[1].joint = 0;
  drives.drives[1].name.assign("x-axis");
  drives.drives[1].fault_text.assign("fault 0x7500 communication");
  m.task().contribute_status(drives);
  m.hal().set_value("spindle.0.amp-fault-in", "TRUE");
  m.step();
  EXPECT_FALSE(m.program_running()) << "the program is aborted at once";
  EXPECT_EQ(m.task().state(), TaskState::Off);
  m.errors();
  EXPECT_EQ(m.log.find("program aborted"), std::string::npos) << "waits for the drive's explanation";
  // The spindle drive's explanation arrives a few cycles later.
  drives.drives[0].fault_text.assign("fault 0x2310 continuous over-current (0x603F)");
  m.task().contribute_status(drives);
  m.step();
  const std::string e = m.errors();
  EXPECT_NE(e.find("program aborted at line 3: spindle 0 amplifier fault (spindle.0.amp-fault-in); drive spindle: "
                   "fault 0x2310 continuous over-current (0x603F)"),
            std::string::npos)
      << e;
  EXPECT_EQ(e.find("x-axis"), std::string::npos) << "only the spindle's drive is named";
  EXPECT_EQ(m.status().task.errors_since_start, 1) << "wait-program reports it";
  m.step(200);
  EXPECT_LT(std::fabs(m.status().motion.current_vel), 1e-9) << "the axes stopped";
}

TEST(TaskFaults, AFaultWithoutADriveExplanationIsSaidAfterAShortWait) {
  TaskMachine m;
  m.power_up_and_home();
  cnc::ipc::Status drives{};
  drives.drives[0].present = true;
  drives.drives[0].joint = 1;
  drives.drives[0].name.assign("y-axis");
  m.task().contribute_status(drives);
  m.hal().set_value("joint.1.amp-fault-in", "TRUE");
  m.step();
  EXPECT_EQ(m.task().state(), TaskState::Off);
  m.errors();
  EXPECT_EQ(m.log.find("machine off"), std::string::npos) << "waits for the drive's text";
  ASSERT_TRUE(m.run_until(
      [&] {
        m.errors();
        return m.log.find("machine off: motion was disabled by a fault") != std::string::npos;
      },
      2'000'000));
  EXPECT_NE(m.log.find("joint 1 amplifier fault (joint.1.amp-fault-in)"), std::string::npos) << m.log;
}

// A command sent while motion stands still (halcmd stop, delf) is answered
// at once instead of leaving the client waiting, and when motion runs again
// it is dropped, not carried out late (a jog sent while the threads were
// stopped used to run when they started).
TEST(TaskEstop, CommandsSentWhileMotionStandsStillAreRefusedAndNeverRunLate) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kManual), "manual");
  m.cycle_info().now_ns = 1'000'000'000;
  m.step(5);
  m.hal().remove_function("motion-command-handler", "servo-thread");
  m.hal().remove_function("motion-controller", "servo-thread");
  const double x0 = m.status().joints[0].pos_cmd;
  cnc::ipc::Command jog;
  jog.type = CommandType::JogIncr;
  jog.i[0] = 0;
  jog.i[1] = 1;
  jog.d[0] = 20;
  jog.d[1] = -10;
  const auto r = m.send(jog, 2'000'000);
  EXPECT_EQ(r.first, CommandState::Rejected);
  EXPECT_NE(r.second.find("motion is not running"), std::string::npos) << r.second;
  // Motion runs again two seconds later: what was queued is stale.
  m.cycle_info().now_ns += 2'000'000'000;
  m.hal().add_function("motion-command-handler", "servo-thread", 4);
  m.hal().add_function("motion-controller", "servo-thread", 5);
  m.step(2000);
  EXPECT_NEAR(m.status().joints[0].pos_cmd, x0, 1e-9) << "the jog ran late";
}

// The servo thread's gap alone (simulated time: the task has not even
// noticed a stall yet) makes a queued jog stale.
TEST(TaskEstop, AJogQueuedBeforeAServoGapIsDroppedWhenTheThreadRunsAgain) {
  TaskMachine m;
  m.power_up_and_home();
  m.ok(m.send(CommandType::TaskSetMode, kManual), "manual");
  m.cycle_info().now_ns = 1'000'000'000;
  m.step(5);
  m.hal().remove_function("motion-command-handler", "servo-thread");
  m.hal().remove_function("motion-controller", "servo-thread");
  const double x0 = m.status().joints[0].pos_cmd;
  cnc::ipc::Command jog;
  jog.type = CommandType::JogIncr;
  jog.serial = 9999;
  jog.i[0] = 0;
  jog.i[1] = 1;
  jog.d[0] = 20;
  jog.d[1] = -10;
  ASSERT_TRUE(m.task().handle_command(jog, m.reporter));
  m.task_cycle();  // the jog waits in motion's queue
  m.cycle_info().now_ns += 2'000'000'000;
  m.hal().add_function("motion-command-handler", "servo-thread", 4);
  m.hal().add_function("motion-controller", "servo-thread", 5);
  m.step(2000);
  ASSERT_TRUE(m.reporter.last.count(9999));
  EXPECT_EQ(m.reporter.last[9999].first, CommandState::Rejected);
  EXPECT_NE(m.reporter.last[9999].second.find("dropped: the servo thread did not run for 2000 ms"), std::string::npos)
      << m.reporter.last[9999].second;
  EXPECT_NEAR(m.status().joints[0].pos_cmd, x0, 1e-9) << "the jog ran late";
}
