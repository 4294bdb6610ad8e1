// The wizard's logic without widgets (commission/wizard/step_runner): the
// command line of every step, the reading of a child's output and status,
// the hold-to-run protocol, the done steps of a state, the tune recordings,
// the homing method list and the status strip.
#include "commission/wizard/step_runner.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <memory>

#include "core/ipc/status.hpp"
#include "tests/support/testing.hpp"

namespace cnc::commission::wizard {
namespace {

const CommandBuilder b("/m/commission.json");

Argv with_state(std::initializer_list<std::string> rest) {
  Argv a{"--state", "/m/commission.json"};
  a.insert(a.end(), rest);
  return a;
}

// ------------------------------------------------------------ command lines

TEST(WizardCommands, ScanBuildsCanopenAndEthercatCommandLines) {
  EXPECT_EQ(b.scan(false, " socketcan:can0 ", "/eds", "1,2,3"),
            with_state({"scan", "--interface", "socketcan:can0", "--eds-dir", "/eds", "--expect", "1,2,3"}));
  EXPECT_EQ(b.scan(true, "raw:eth0", "/esi"), with_state({"scan-ethercat", "--interface", "raw:eth0", "--esi-dir", "/esi"}));
  EXPECT_EQ(b.scan(false, "socketcan:can0", ""), with_state({"scan", "--interface", "socketcan:can0"}));
}

TEST(WizardCommands, ScanRefusesAMissingInterfaceAndBadExpectedNodes) {
  EXPECT_THROW(b.scan(false, "  ", ""), std::invalid_argument);
  EXPECT_THROW(b.scan(false, "socketcan:can0", "", "1,x"), std::invalid_argument);
  EXPECT_THROW(b.scan(false, "socketcan:can0", "", "0"), std::invalid_argument);
  EXPECT_THROW(b.scan(false, "socketcan:can0", "", "128"), std::invalid_argument);
}

TEST(WizardCommands, LssGivesNodeIdsFromTheFirstOneAndRefusesBadInput) {
  EXPECT_EQ(b.lss(" socketcan:can0", 4), with_state({"lss", "--interface", "socketcan:can0", "--first", "4"}));
  EXPECT_THROW(b.lss("", 1), std::invalid_argument);
  EXPECT_THROW(b.lss("socketcan:can0", 0), std::invalid_argument);
  EXPECT_THROW(b.lss("socketcan:can0", 128), std::invalid_argument);
}

TEST(WizardCommands, AssignAndIdentifyNameTheAxisNodeAndJoint) {
  EXPECT_EQ(b.assign('x', 3, 0), with_state({"axis", "X", "assign", "--node", "3", "--joint", "0"}));
  EXPECT_EQ(b.assign('Y', 2, 1, 3, true),
            with_state({"axis", "Y", "assign", "--node", "2", "--joint", "1", "--gantry-node", "3", "--gantry-reverse"}));
  EXPECT_EQ(b.assign('Y', 2, 1, 3), with_state({"axis", "Y", "assign", "--node", "2", "--joint", "1", "--gantry-node", "3"}));
  EXPECT_THROW(b.assign('Y', 2, 1, 2), std::invalid_argument) << "the second drive on the first one's node";
  EXPECT_EQ(b.identify('Z', "/m/scratch.json"),
            (Argv{"--state", "/m/scratch.json", "axis", "Z", "direction-test", "--distance", "0.5", "--velocity", "1"}));
  EXPECT_THROW(b.identify('Z', "/m/commission.json"), std::invalid_argument);  // never the real state
  EXPECT_THROW(b.identify('Z', ""), std::invalid_argument);
  EXPECT_THROW(b.assign('Q', 1, 0), std::invalid_argument);
  EXPECT_THROW(b.assign('X', 0, 0), std::invalid_argument);
  EXPECT_THROW(b.assign('X', 1, -1), std::invalid_argument);
}

TEST(WizardCommands, ScalingLeavesCountsAndGearToTheDriveWhenZero) {
  EXPECT_EQ(b.scaling('X', 5, 0, 0, 0), with_state({"axis", "X", "scaling", "--lead", "5"}));
  EXPECT_EQ(b.scaling('X', 2.5, 131072, 3, 1),
            with_state({"axis", "X", "scaling", "--lead", "2.5", "--counts", "131072", "--gear", "3:1"}));
  EXPECT_THROW(b.scaling('X', 0, 0, 0, 0), std::invalid_argument);
  EXPECT_THROW(b.scaling('X', 5, 0, 3, 0), std::invalid_argument);  // half a gear
}

TEST(WizardCommands, DirectionTestIsLimitedInTravelAndSpeed) {
  EXPECT_EQ(b.direction_test('X', -5, 2), with_state({"axis", "X", "direction-test", "--distance", "-5", "--velocity", "2"}));
  EXPECT_EQ(b.direction_test('X', 5, 2, "/m/up"),
            with_state({"axis", "X", "direction-test", "--distance", "5", "--velocity", "2", "--bring-up", "/m/up"}));
  EXPECT_THROW(b.direction_test('X', 0, 2), std::invalid_argument);
  EXPECT_THROW(b.direction_test('X', kMaxTestTravel + 1, 2), std::invalid_argument);
  EXPECT_THROW(b.direction_test('X', 5, kMaxTestVelocity + 1), std::invalid_argument);
  EXPECT_EQ(b.dial('X', 4.98), with_state({"axis", "X", "dial", "4.98"}));
}

TEST(WizardCommands, LimitsSwitchesAndSoftLimits) {
  EXPECT_EQ(b.limits('Z', -150, 10, 50, 500),
            with_state({"axis", "Z", "limits", "--min", "-150", "--max", "10", "--velocity", "50", "--acceleration", "500"}));
  EXPECT_THROW(b.limits('Z', 10, 10, 50, 500), std::invalid_argument);
  EXPECT_EQ(b.switches('X', 0, 0), with_state({"axis", "X", "switches"}));
  EXPECT_EQ(b.switches('X', 300, 10), with_state({"axis", "X", "switches", "--search", "300", "--velocity", "10"}));
  EXPECT_EQ(b.soft_limits('X', 1.5), with_state({"axis", "X", "soft-limits", "--margin", "1.5"}));
}

TEST(WizardCommands, HomingTakesControllerOrDriveMethods) {
  EXPECT_EQ(b.homing_methods(), with_state({"homing-methods"}));
  EXPECT_EQ(b.homing('X', "controller", 5), with_state({"axis", "X", "homing", "--method", "controller", "--repeat", "5"}));
  EXPECT_EQ(b.homing('X', "drive:35", 1), with_state({"axis", "X", "homing", "--method", "drive:35", "--repeat", "1"}));
  EXPECT_THROW(b.homing('X', "drive:", 5), std::invalid_argument);
  EXPECT_THROW(b.homing('X', "drive:3x", 5), std::invalid_argument);
  EXPECT_THROW(b.homing('X', "switch", 5), std::invalid_argument);
  EXPECT_THROW(b.homing('X', "controller", 0), std::invalid_argument);
}

TEST(WizardCommands, TuneRecordsIntoTheGivenFolder) {
  EXPECT_EQ(b.tune('X', 0, 0, 20, "/m/tune-X"), with_state({"axis", "X", "tune", "--margin", "20", "--record", "/m/tune-X"}));
  EXPECT_EQ(b.tune('X', 200, 2000, 25, ""),
            with_state({"axis", "X", "tune", "--max-velocity", "200", "--max-acceleration", "2000", "--margin", "25"}));
  EXPECT_THROW(b.tune('X', 0, 0, 100, ""), std::invalid_argument);
}

TEST(WizardCommands, ResponseAlwaysBringsUpItsOwnControllerAndWritesAGainOnlyWhenGiven) {
  EXPECT_EQ(b.response('X', 0, "/m/response-X", "/m"),
            with_state({"axis", "X", "response", "--record", "/m/response-X", "--bring-up", "/m"}));
  EXPECT_EQ(b.response('Y', 700, "", "/m"), with_state({"axis", "Y", "response", "--velocity-gain", "700", "--bring-up", "/m"}));
  EXPECT_THROW(b.response('X', 0, "/m/r", ""), std::invalid_argument);
  EXPECT_THROW(b.response('X', -1, "/m/r", "/m"), std::invalid_argument);
}

TEST(WizardCommands, CompensationStepsTakeValuesOrACsvFile) {
  EXPECT_EQ(b.comp_program('X', "/m/c.ngc"), with_state({"axis", "X", "comp-program", "--out", "/m/c.ngc"}));
  EXPECT_EQ(b.comp_run('X'), with_state({"axis", "X", "comp-run"}));
  EXPECT_EQ(b.comp_run('X', "/m/laser.csv"), with_state({"axis", "X", "comp-run", "--laser", "/m/laser.csv"}));
  EXPECT_EQ(b.comp_measurements('X', "", "0.01\n-0.002, 0.003 "),
            with_state({"axis", "X", "comp-measurements", "--values", "0.01,-0.002,0.003"}));
  EXPECT_EQ(b.comp_measurements('X', "/m/l.csv", ""), with_state({"axis", "X", "comp-measurements", "--csv", "/m/l.csv"}));
  EXPECT_THROW(b.comp_measurements('X', "", ""), std::invalid_argument);
  EXPECT_THROW(b.comp_measurements('X', "/m/l.csv", "1"), std::invalid_argument);
  EXPECT_THROW(b.comp_measurements('X', "", "1,abc"), std::invalid_argument);
  EXPECT_EQ(b.comp_fit('X', false), with_state({"axis", "X", "comp-fit"}));
  EXPECT_EQ(b.comp_fit('X', true), with_state({"axis", "X", "comp-fit", "--install"}));
}

TEST(WizardCommands, WriteBackupBringUpAndShutdown) {
  EXPECT_EQ(b.write("/m/cfg", "mill", false), with_state({"write", "--dir", "/m/cfg", "--name", "mill"}));
  EXPECT_EQ(b.write("/m/cfg", "mill", true), with_state({"write", "--dir", "/m/cfg", "--name", "mill", "--yes"}));
  EXPECT_THROW(b.write("", "mill", true), std::invalid_argument);
  EXPECT_EQ(b.backup("/m/bk"), with_state({"backup", "--dir", "/m/bk"}));
  EXPECT_EQ(b.bring_up("/m/up"), with_state({"bring-up", "--dir", "/m/up"}));
  EXPECT_EQ(b.shutdown(), with_state({"shutdown"}));
}

TEST(WizardCommands, MotionStepsFiveToEightRunOnAControllerOfTheirOwnWhenAFolderIsGiven) {
  EXPECT_EQ(b.switches('X', 240, 20, " /m/up "),
            with_state({"axis", "X", "switches", "--search", "240", "--velocity", "20", "--bring-up", "/m/up"}));
  EXPECT_EQ(b.homing('X', "controller", 5, "/m/up"),
            with_state({"axis", "X", "homing", "--method", "controller", "--repeat", "5", "--bring-up", "/m/up"}));
  EXPECT_EQ(b.tune('X', 100, 2000, 20, "/m/tune-X", 0, "/m/up"),
            with_state({"axis", "X", "tune", "--max-velocity", "100", "--max-acceleration", "2000", "--margin", "20",
                        "--record", "/m/tune-X", "--bring-up", "/m/up"}));
  EXPECT_EQ(b.comp_run('X', "", "", "/m/up"), with_state({"axis", "X", "comp-run", "--bring-up", "/m/up"}));
}

TEST(WizardCommands, TuneTakesTheTestsPerSeries) {
  EXPECT_EQ(b.tune('X', 0, 0, 20, "", 3), with_state({"axis", "X", "tune", "--margin", "20", "--steps", "3"}));
  EXPECT_THROW(b.tune('X', 0, 0, 20, "", 1), std::invalid_argument);
  EXPECT_THROW(b.tune('X', 0, 0, 20, "", 21), std::invalid_argument);
}

TEST(WizardCommands, AcceptingTheTuningSetsTheRecommendedSpeedsKeepingTheSoftLimits) {
  Axis x;
  x.letter = 'X';
  x.min_limit = -28.5;
  x.max_limit = 210.25;
  EXPECT_THROW(b.accept_tuning(x), std::invalid_argument);  // nothing to accept yet
  x.tuning = AxisTuning{};
  x.tuning->max_velocity = 96;
  x.tuning->max_acceleration = 1600;
  EXPECT_EQ(b.accept_tuning(x), with_state({"axis", "X", "limits", "--min", "-28.5", "--max", "210.25", "--velocity",
                                            "96", "--acceleration", "1600"}));
}

TEST(WizardCommands, CompensationCycleOptionsAndTheLaserPin) {
  EXPECT_EQ(b.comp_program('X', "/m/c.ngc", {0, 60, 4, 2, 0.3, 1200}),
            with_state({"axis", "X", "comp-program", "--out", "/m/c.ngc", "--min", "0", "--max", "60", "--targets", "4",
                        "--runs", "2", "--dwell", "0.3", "--feed", "1200"}));
  EXPECT_THROW(b.comp_program('X', "/m/c.ngc", {60, 0, 0, 0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(b.comp_program('X', "/m/c.ngc", {0, 0, -1, 0, 0, 0}), std::invalid_argument);
  EXPECT_EQ(b.comp_run('X', "", " cia402-sim.0.node.01.table-position "),
            with_state({"axis", "X", "comp-run", "--laser-pin", "cia402-sim.0.node.01.table-position"}));
  EXPECT_THROW(b.comp_run('X', "/m/laser.csv", "laser.0.position"), std::invalid_argument);  // one source
  EXPECT_EQ(b.comp_run_camera('X', " exec:capture --png ", 0.1, 2.5, "/m/up"),
            with_state({"axis", "X", "comp-run", "--camera", "exec:capture --png", "--pitch", "0.1",
                        "--um-per-px", "2.5", "--bring-up", "/m/up"}));
  EXPECT_EQ(b.comp_run_camera('X', "/dev/video0"), with_state({"axis", "X", "comp-run", "--camera", "/dev/video0"}));
  EXPECT_THROW(b.comp_run_camera('X', " "), std::invalid_argument) << "no camera";
  EXPECT_THROW(b.comp_run_camera('X', "/dev/video0", -1), std::invalid_argument);
}

TEST(WizardCommands, CheckRunsTheCheckProgramOnTheWrittenConfiguration) {
  EXPECT_EQ(b.check(), with_state({"check"}));
  EXPECT_EQ(b.check(" /m/mine.ngc ", 120), with_state({"check", "--program", "/m/mine.ngc", "--timeout", "120"}));
  EXPECT_THROW(b.check("", -1), std::invalid_argument);
}

TEST(WizardCommands, NumbersAreWrittenShortAndExact) {
  EXPECT_EQ(number_arg(5), "5");
  EXPECT_EQ(number_arg(0.1), "0.1");
  EXPECT_EQ(number_arg(-1e-5), "-1e-05");
  EXPECT_EQ(std::stod(number_arg(1.0 / 3)), 1.0 / 3);
}

// ------------------------------------------------------------ output

TEST(WizardOutput, ProgressLinesAreParsed) {
  auto p = parse_progress("progress: 3/5 moving to the negative limit");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->index, 3);
  EXPECT_EQ(p->count, 5);
  EXPECT_EQ(p->text, "moving to the negative limit");
  EXPECT_DOUBLE_EQ(p->fraction(), 0.6);
  p = parse_progress("progress: 0/2");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->text, "");
  EXPECT_FALSE(parse_progress("axis X: 409.6 counts/mm"));
  EXPECT_FALSE(parse_progress("progress: 3 of 5"));
  EXPECT_FALSE(parse_progress("progress: 6/5 too far"));
  EXPECT_FALSE(parse_progress("progress: 1/0"));
}

TEST(WizardOutput, ChunksAreSplitIntoProgressAndResultLines) {
  OutputCollector c;
  auto p = c.add_stdout("progress: 1/2 fir");
  EXPECT_TRUE(p.empty());
  p = c.add_stdout("st\nresult one\nprogress: 2/2 second\r\nresult ");
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].text, "first");
  EXPECT_EQ(p[1].index, 2);
  c.add_stdout("two");  // no newline at the end: kept by finish()
  const StepResult r = c.finish(true, 0, false);
  EXPECT_EQ(r.outcome, StepResult::Outcome::Done);
  EXPECT_EQ(r.lines, (std::vector<std::string>{"result one", "result two"}));
  ASSERT_TRUE(r.last_progress);
  EXPECT_EQ(r.last_progress->index, 2);
  EXPECT_EQ(r.summary(), "done");
}

TEST(WizardOutput, ExitStatusGivesTheOutcomeAndTheSummaryCarriesTheChildsError) {
  {
    OutputCollector c;
    c.add_stderr("cnc-commission: axis X: switch \"home\" never changed; check its wiring\n");
    const StepResult r = c.finish(true, 1, false);
    EXPECT_EQ(r.outcome, StepResult::Outcome::Problem);
    EXPECT_NE(r.summary().find("switch \"home\" never changed"), std::string::npos) << r.summary();
  }
  {  // a subcommand this build lacks: status 2 and the program's own words
    OutputCollector c;
    c.add_stderr("cnc-commission: axis: unknown step switches\n(cnc-commission --help for the commands)\n");
    const StepResult r = c.finish(true, 2, false);
    EXPECT_EQ(r.outcome, StepResult::Outcome::Usage);
    EXPECT_NE(r.summary().find("unknown step switches"), std::string::npos) << r.summary();
  }
  {
    OutputCollector c;
    EXPECT_EQ(c.finish(false, 0, false).outcome, StepResult::Outcome::Crashed);
  }
  {  // the problem is in the result lines when stderr is empty
    OutputCollector c;
    c.add_stdout("problem: node 4 does not answer\n");
    EXPECT_NE(c.finish(true, 1, false).summary().find("node 4 does not answer"), std::string::npos);
  }
}

TEST(WizardOutput, AnInterruptedRunIsAbortedNotAProblem) {
  OutputCollector c;
  c.add_stderr("cnc-commission: aborted: axis X stopped after 1.2 mm, the drives disabled\n");
  const StepResult r = c.finish(true, 1, true);
  EXPECT_EQ(r.outcome, StepResult::Outcome::Aborted);
  EXPECT_NE(r.summary().find("aborted"), std::string::npos);
  OutputCollector d;  // it had ended by itself before the signal: done
  EXPECT_EQ(d.finish(true, 0, true).outcome, StepResult::Outcome::Done);
}

// ------------------------------------------------------------ hold-to-run

TEST(WizardHoldToRun, PressStartsAndReleaseRequestsSigint) {
  HoldToRun h;
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
  h.started();
  EXPECT_TRUE(h.running());
  EXPECT_FALSE(h.interrupt_requested());
  EXPECT_EQ(h.release(), HoldToRun::Action::Interrupt);
  EXPECT_TRUE(h.interrupt_requested());
  EXPECT_EQ(h.release(), HoldToRun::Action::None);  // once
  h.finished();
  EXPECT_FALSE(h.running());
}

TEST(WizardHoldToRun, ReleaseBeforeTheChildStartedStillInterrupts) {
  HoldToRun h;
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
  EXPECT_EQ(h.release(), HoldToRun::Action::Interrupt);  // the window sends it once the child runs
}

TEST(WizardHoldToRun, ReleaseAfterTheRunEndedSendsNothingAndAPressDuringARunStartsNothing) {
  HoldToRun h;
  h.press();
  h.started();
  h.finished();
  EXPECT_EQ(h.release(), HoldToRun::Action::None);
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
  h.started();
  h.release();
  EXPECT_EQ(h.press(), HoldToRun::Action::None);  // still stopping
  h.finished();
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
}

TEST(WizardHoldToRun, ARefusedStartLeavesTheButtonReadyForTheNextPress) {
  HoldToRun h;
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
  h.finished();  // the page refused to start (bad input, another step running)
  EXPECT_FALSE(h.running());
  EXPECT_EQ(h.release(), HoldToRun::Action::None);  // nothing to interrupt
  EXPECT_EQ(h.press(), HoldToRun::Action::Start);
}

// ------------------------------------------------------------ done steps

State machine_with_axes() {
  State s;
  ScannedNode n;
  n.node_id = 1;
  s.nodes.push_back(n);
  Axis x;
  x.letter = 'X';
  x.node = 1;
  s.axes.push_back(x);
  return s;
}

TEST(WizardDoneSteps, AFreshStateHasNothingDone) {
  const auto d = steps_done(State{}, "");
  for (bool v : d) EXPECT_FALSE(v);
}

TEST(WizardDoneSteps, StepsOneToFourFollowTheStateResults) {
  State s = machine_with_axes();
  auto d = steps_done(s, "");
  EXPECT_TRUE(d[0]);
  EXPECT_TRUE(d[1]);
  EXPECT_FALSE(d[2]);
  s.axes[0].scaling.encoder_counts = 4096;
  s.axes[0].scaling.screw_lead = 5;
  d = steps_done(s, "");
  EXPECT_TRUE(d[2]);
  EXPECT_FALSE(d[3]);
  s.axes[0].direction = DirectionTest{};
  EXPECT_FALSE(steps_done(s, "")[3]) << "a test without the dial reading is not done";
  s.axes[0].direction->has_dial = true;
  EXPECT_TRUE(steps_done(s, "")[3]);
  // A second, enabled axis without scaling undoes step 3; disabled, it does not count.
  Axis y;
  y.letter = 'Y';
  y.node = 2;
  s.axes.push_back(y);
  EXPECT_FALSE(steps_done(s, "")[2]);
  s.axes[1].enabled = false;
  EXPECT_TRUE(steps_done(s, "")[2]);
}

TEST(WizardDoneSteps, StepsFiveToEightNeedTheirResultInEveryEnabledAxis) {
  const State s = machine_with_axes();
  const std::string none = R"({"axes": [{"letter": "X"}, {"letter": "Y", "enabled": false}]})";
  const std::string sw = R"({"axes": [{"letter": "X", "switches": {"home": {"seen": true}}}, {"letter": "Y", "enabled": false}]})";
  const std::string all =
      R"({"axes": [{"letter": "X", "switches": {}, "homing": {"spread": 0.001}, "tuning": {}, "compensation": {}}]})";
  auto d = steps_done(s, none);
  for (int k = 4; k < 8; ++k) EXPECT_FALSE(d[static_cast<std::size_t>(k)]) << k;
  d = steps_done(s, sw);
  EXPECT_TRUE(d[4]);
  EXPECT_FALSE(d[5]);
  d = steps_done(s, all);
  for (int k = 4; k < 8; ++k) EXPECT_TRUE(d[static_cast<std::size_t>(k)]) << k;
  EXPECT_FALSE(steps_done(s, R"({"axes": [{"letter": "X", "homing": null}]})")[5]);
}

TEST(WizardDoneSteps, WriteIsDoneWhenTheLogSaysAConfigurationWasWritten) {
  State s = machine_with_axes();
  EXPECT_FALSE(steps_done(s, "")[8]);
  s.log.push_back("configuration written to /m/machine.ini");
  EXPECT_TRUE(steps_done(s, "")[8]);
}

TEST(WizardDoneSteps, ReadFromTheStateFile) {
  testing::TempDir dir;
  State s = machine_with_axes();
  s.axes[0].scaling.encoder_counts = 4096;
  s.axes[0].scaling.screw_lead = 5;
  save_state(s, dir / "state.json");
  const auto d = steps_done(dir / "state.json");
  EXPECT_TRUE(d[0] && d[1] && d[2]);
  EXPECT_FALSE(d[3]);
  const auto none = steps_done(dir / "missing.json");
  EXPECT_FALSE(none[0]);
}

// ------------------------------------------------------------ tune CSV

TEST(WizardTuneCsv, ColumnsAreTakenByName) {
  const TuneTrace t = parse_tune_csv(
      "# test 2: 50 mm/s, 500 mm/s2\n"
      "torque_pct,time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,extra\n"
      "12.5,0,0,0,0,0,x\n"
      "20,0.001,0.05,0.049,0.001,50,y\n",
      "t.csv");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.time_s[1], 0.001);
  EXPECT_DOUBLE_EQ(t.ferror_mm[1], 0.001);
  EXPECT_DOUBLE_EQ(t.velocity_mm_s[1], 50);
  EXPECT_DOUBLE_EQ(t.torque_pct[0], 12.5);
  EXPECT_DOUBLE_EQ(t.feedback_mm[1], 0.049);
  EXPECT_DOUBLE_EQ(t.command_mm[1], 0.05);
}

TEST(WizardTuneCsv, ErrorsNameTheFileLineAndColumn) {
  const std::string h = "time_s,command_mm,feedback_mm,ferror_mm,velocity_mm_s,torque_pct\n";
  try {
    parse_tune_csv(h + "0,0,0,0,0,0\n0.001,0,0,oops,0,0\n", "t.csv");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("t.csv:3: ferror_mm \"oops\""), std::string::npos) << e.what();
  }
  try {
    parse_tune_csv("time_s,command_mm\n", "u.csv");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("u.csv:1: no column feedback_mm"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_tune_csv(h + "0,0,0\n", "v.csv"), std::invalid_argument);
  EXPECT_THROW(parse_tune_csv("", "w.csv"), std::invalid_argument);
  EXPECT_THROW(load_tune_csv("/nonexistent/x.csv"), std::invalid_argument);
}

// ------------------------------------------------------------ homing methods

TEST(WizardHomingMethods, ControllerAndDriveMethodsAreTakenFromTheLines) {
  const auto m = parse_homing_methods({"controller  the joint's homing sequence (HOME_* keys)", "",
                                       "drive:1     negative limit switch, then the first index pulse",
                                       "drive:35  current position is home", "  17 negative limit switch",
                                       "methods of the drive (CiA 402 0x6098):"});
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].method, "controller");
  EXPECT_EQ(m[1].method, "drive:1");
  EXPECT_EQ(m[2].method, "drive:35");
  EXPECT_EQ(m[3].method, "drive:17");
  EXPECT_EQ(m[3].description, "17 negative limit switch");
}

// ------------------------------------------------------------ status strip

TEST(WizardStatusStrip, ShowsTheEstopChainDrivesAndJointPositions) {
  auto s = std::make_unique<ipc::Status>();
  s->io.estop_chain_ok = true;
  s->task.state = ipc::TaskState::On;
  s->motion.joints = 2;
  s->joints[0].pos_fb = 12.3456;
  s->joints[1].pos_fb = -1;
  s->drives[0].present = true;
  s->drives[0].joint = 0;
  s->drives[0].state = 4;
  s->drives[1].present = true;
  s->drives[1].joint = 1;
  s->drives[1].state = 7;
  s->drives[1].fault_text.assign("0x7305 encoder");
  StatusStrip st = status_strip(*s);
  EXPECT_TRUE(st.estop_ok);
  EXPECT_NE(st.estop.find("closed"), std::string::npos) << st.estop;
  EXPECT_EQ(st.drives, (std::vector<std::string>{"J0 operation enabled", "J1 fault: 0x7305 encoder"}));
  EXPECT_EQ(st.joints, (std::vector<std::string>{"J0 12.346", "J1 -1.000"}));
  s->io.estop_chain_ok = false;
  st = status_strip(*s);
  EXPECT_FALSE(st.estop_ok);
  EXPECT_NE(st.estop.find("chain open"), std::string::npos);
}

}  // namespace
}  // namespace cnc::commission::wizard
