// The HAL components: screwcomp attaches [JOINT_n]COMP_FILE tables to
// motmod at start-up (errors name file and line), and replaces a table on
// JOINT_LOAD_COMP while the machine is stopped, the servo thread switching
// without a lock; complog records one point per stop of a measurement
// cycle and writes the measurement file.
#include <gtest/gtest.h>

#include <fstream>
#include <map>

#include "comp/measurement.hpp"
#include "comp/measurement_logger.hpp"
#include "comp/screw_compensation.hpp"
#include "comp/screwcomp_component.hpp"
#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/motion/motion_component.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/messages.hpp"
#include "kinematics/kinematics.hpp"
#include "sim/machine/components.hpp"
#include "tests/core/motion/simple_planner.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::comp;

namespace {

class Reporter : public ipc::CommandReporter {
 public:
  void report(const ipc::Command& cmd, ipc::CommandState state, std::string_view reason) override {
    last[cmd.serial] = {state, std::string(reason)};
  }
  std::map<uint32_t, std::pair<ipc::CommandState, std::string>> last;
};

const char* kIni = R"(
[EMCMOT]
SERVO_PERIOD = 1000000
[KINS]
KINEMATICS = trivkins coordinates=X
JOINTS = 1
[TRAJ]
MAX_LINEAR_VELOCITY = 100
MAX_LINEAR_ACCELERATION = 1000
[AXIS_X]
MIN_LIMIT = -10
MAX_LIMIT = 200
MAX_VELOCITY = 95
MAX_ACCELERATION = 950
[JOINT_0]
MIN_LIMIT = -10
MAX_LIMIT = 200
MAX_VELOCITY = 100
MAX_ACCELERATION = 1000
BACKLASH = 0.02
)";

const char* kHal = R"(
loadrt trivkins coordinates=X
loadrt motmod servo_period_nsec=1000000 num_joints=1
loadrt screwcomp
loadrt sim_joint count=1
addf sim-joint.0 servo-thread
addf motion-command-handler servo-thread
addf motion-controller servo-thread
net x-cmd joint.0.motor-pos-cmd => sim-joint.0.pos-cmd
net x-fb sim-joint.0.pos-fb => joint.0.motor-pos-fb
net x-en joint.0.amp-enable-out => sim-joint.0.enable
)";

// A one-joint machine built from INI and HAL text, stepped cycle by cycle.
class Rig {
 public:
  // `emcmot_extra` goes into [EMCMOT]; `hal` replaces the HAL file.
  explicit Rig(const std::string& joint_extra, const std::string& comp_file_text = "",
               const std::string& emcmot_extra = "", const std::string& hal = kHal) {
    if (!comp_file_text.empty()) dir.write("x.comp", comp_file_text);
    std::string ini = std::string(kIni) + joint_extra;
    ini.insert(ini.find("[KINS]"), emcmot_extra);
    dir.write("m.ini", ini);
    dir.write("m.hal", hal);
    ini_ = ini::IniFile::load(dir / "m.ini");
    hal::register_core_components(registry_);
    kin::register_kinematics_components(registry_);
    motion::register_components(registry_, [](const tp::PlannerConfig& c) -> std::unique_ptr<tp::TrajectoryPlanner> {
      return std::make_unique<cnc::testing::SimplePlanner>(c);
    });
    comp::register_components(registry_);
    sim::register_sim_joint(registry_);
    hal::CommandInterpreter interp(hal_, registry_, &ini_, &messages);
    interp.run_file(dir / "m.hal");
    for (hal::Component* c : hal_.components()) c->on_ready();
    motion_ = hal_.find<motion::MotionComponent>("motmod");
    screw_ = hal_.find<ScrewCompComponent>("screwcomp");
    thread_ = hal_.find_thread("servo-thread");
    info_.period_ns = info_.actual_period_ns = 1'000'000;
  }
  void step(int n = 1) {
    for (int i = 0; i < n; ++i) {
      thread_->run_cycle(info_);
      ++info_.cycle;
      now_ns += 1'000'000;
      motion::MotionResult r;
      while (motion_->poll_result(r)) results.push_back(r);
      screw_->update(now_ns);
    }
  }
  void motion(motion::Cmd type, int joint = 0, double v0 = 0, double v1 = 0) {
    motion::MotionCommand c;
    c.type = type;
    c.joint = static_cast<int16_t>(joint);
    c.value[0] = v0;
    c.value[1] = v1;
    motion_->submit(c);
    step(2);
  }
  std::pair<ipc::CommandState, std::string> load(const std::string& file, int type, int max_cycles = 5000) {
    ipc::Command c;
    c.type = ipc::CommandType::JointLoadComp;
    c.serial = ++serial_;
    c.i[0] = 0;
    c.i[1] = type;
    c.text.assign(file);
    EXPECT_TRUE(screw_->handle_command(c, reporter));
    for (int k = 0; k < max_cycles; ++k) {
      const auto& r = reporter.last[c.serial];
      if (r.first == ipc::CommandState::Done || r.first == ipc::CommandState::Rejected) return r;
      step();
    }
    return reporter.last[c.serial];
  }
  std::string pin(const std::string& name) { return hal_.get_value(name); }
  double motor() { return std::stod(pin("joint.0.motor-pos-cmd")); }
  double pos_cmd() { return std::stod(pin("joint.0.pos-cmd")); }

  cnc::testing::TempDir dir;
  MessageQueue messages;
  Reporter reporter;
  std::vector<motion::MotionResult> results;
  int64_t now_ns = 0;
  ScrewCompComponent* screw_ = nullptr;
  motion::MotionComponent* motion_ = nullptr;

 private:
  ini::IniFile ini_;
  hal::Hal hal_;
  hal::ComponentRegistry registry_;
  hal::Thread* thread_ = nullptr;
  rt::CycleInfo info_;
  uint32_t serial_ = 0;
};

std::string startup_error(const std::string& joint_extra, const std::string& comp_text,
                          const std::string& emcmot_extra = "", const std::string& hal = kHal) {
  try {
    Rig r(joint_extra, comp_text, emcmot_extra, hal);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(ScrewCompComponent, StartUpLoadsCompFileAndTheJointFollowsTheTable) {
  Rig r("COMP_FILE = x.comp\nCOMP_FILE_TYPE = 1\n", "0 0.005 -0.005\n200 0.025 0.015\n");
  EXPECT_EQ(r.pin("screwcomp.0.entries"), "2");
  r.motion(motion::Cmd::Enable);
  r.motion(motion::Cmd::Home, 0);  // immediate: here is HOME_OFFSET 0
  r.step(50);
  r.motion(motion::Cmd::JogAbs, 0, 50, 100);
  r.step(4000);
  EXPECT_DOUBLE_EQ(r.pos_cmd(), 100);
  EXPECT_NEAR(std::stod(r.pin("screwcomp.0.correction")), 0.015, 1e-12);
  EXPECT_EQ(r.pin("screwcomp.0.direction"), "1");
  EXPECT_NEAR(std::stod(r.pin("joint.0.backlash-filt")), 0.015, 1e-12) << "the table, not BACKLASH";
  Message m;
  bool told = false;
  while (r.messages.pop(m)) told = told || std::string(m.text.view()).find("BACKLASH 0.02 is not applied") != std::string::npos;
  EXPECT_TRUE(told) << "BACKLASH with COMP_FILE is reported, as LinuxCNC ignores it";
}

TEST(ScrewCompComponent, ABadCompFileStopsStartUpNamingFileAndLine) {
  const std::string e = startup_error("COMP_FILE = x.comp\nCOMP_FILE_TYPE = 1\n", "0 0 0\n10 0 0\n5 0 0\n");
  EXPECT_NE(e.find("x.comp:3: nominal 5 is not greater than the previous one"), std::string::npos) << e;
}

// COMP_RESERVE = 0 used to be accepted (the documented range was 0..0.5):
// the ramp then never moved, so neither BACKLASH nor a table reached the
// motor while joint.N.backlash-corr showed the correction.
TEST(ScrewCompComponent, CompReserveBelowOnePercentIsRefusedAtStartUpWithFileLineAndRange) {
  for (const char* value : {"0", "0.005"}) {
    const std::string e = startup_error("", "", std::string("COMP_RESERVE = ") + value + "\n");
    EXPECT_NE(e.find("m.ini:4: [EMCMOT]COMP_RESERVE: expected a number between 0.01 and 0.5, got \"" +
                     std::string(value) + "\": below 1 % the backlash and screw-table correction has no room"),
              std::string::npos)
        << e;
  }
  EXPECT_NE(startup_error("", "", "COMP_RESERVE = 0.6\n").find("m.ini:4: [EMCMOT]COMP_RESERVE: expected a number"),
            std::string::npos);
  // Every accepted value applies the correction.
  for (const char* value : {"0.01", "0.5"}) {
    Rig r("", "", std::string("COMP_RESERVE = ") + value + "\n");
    r.motion(motion::Cmd::Enable);
    r.motion(motion::Cmd::Home, 0);
    r.step(50);
    r.motion(motion::Cmd::JogAbs, 0, 50, 10);
    r.step(3000);
    EXPECT_NEAR(std::stod(r.pin("joint.0.backlash-filt")), 0.01, 1e-12) << "BACKLASH/2 applied with " << value;
  }
}

// screwcomp reads COMP_FILE; without it the table was ignored silently.
TEST(ScrewCompComponent, CompFileWithoutTheScrewcompComponentIsRefusedAtStartUp) {
  std::string hal = kHal;
  hal.erase(hal.find("loadrt screwcomp\n"), std::string("loadrt screwcomp\n").size());
  const std::string e = startup_error("COMP_FILE = x.comp\nCOMP_FILE_TYPE = 1\n", "0 0 0\n", "", hal);
  EXPECT_NE(e.find("m.ini:21: [JOINT_0]COMP_FILE: a compensation table needs the screwcomp component: add `loadrt "
                   "screwcomp` after `loadrt motmod`"),
            std::string::npos)
      << e;
  EXPECT_EQ(startup_error("", "", "", hal), "no error") << "BACKLASH alone needs no screwcomp";
}

TEST(ScrewCompComponent, ATableLongerThanLinuxCncsIsUsedWholeAndSaysSo) {
  std::string text;
  for (int i = 0; i < 300; ++i) text += std::to_string(i * 0.5) + " 0.001 -0.001\n";
  Rig r("COMP_FILE = x.comp\nCOMP_FILE_TYPE = 1\n", text);
  EXPECT_EQ(r.pin("screwcomp.0.entries"), "300");
  Message m;
  std::string said;
  while (r.messages.pop(m)) said += std::string(m.text.view()) + "\n";
  EXPECT_NE(said.find("x.comp has 300 entries, all in use here; LinuxCNC 2.9 would use only the first 256"),
            std::string::npos)
      << said;
}

TEST(ScrewCompComponent, LoadReplacesATableWhileStoppedWithoutARestart) {
  Rig r("");  // no COMP_FILE: BACKLASH until a table arrives
  EXPECT_EQ(r.pin("screwcomp.0.entries"), "0");
  r.motion(motion::Cmd::Enable);
  r.motion(motion::Cmd::Home, 0);
  r.step(50);
  r.motion(motion::Cmd::JogAbs, 0, 50, 50);
  r.step(3000);
  EXPECT_NEAR(std::stod(r.pin("joint.0.backlash-filt")), 0.01, 1e-12) << "BACKLASH/2 moving +";

  write_file_atomically(r.dir / "new.comp", "0 0.004 -0.004\n100 0.004 -0.004\n");
  // Moving: refused.
  r.motion(motion::Cmd::JogAbs, 0, 20, 0);
  auto res = r.load((r.dir / "new.comp").string(), 1, 1);
  EXPECT_EQ(res.first, ipc::CommandState::Rejected);
  EXPECT_NE(res.second.find("only while the machine is stopped"), std::string::npos) << res.second;
  r.step(5000);
  // Stopped: taken by the servo thread, in use at once.
  res = r.load("new.comp", 1);  // relative: from the INI file's folder
  ASSERT_EQ(res.first, ipc::CommandState::Done) << res.second;
  EXPECT_NE(res.second.find("new.comp in use (2 entries)"), std::string::npos) << res.second;
  EXPECT_EQ(r.pin("screwcomp.0.entries"), "2");
  r.step(500);
  EXPECT_NEAR(std::stod(r.pin("joint.0.backlash-filt")), -0.004, 1e-12) << "reverse trim: the last move was -";
  EXPECT_NEAR(r.motor(), r.pos_cmd() - 0.004 + std::stod(r.pin("joint.0.motor-offset")), 1e-12);
}

TEST(ScrewCompComponent, ABadFileOrRequestIsRejectedAndTheOldTableStays) {
  Rig r("COMP_FILE = x.comp\nCOMP_FILE_TYPE = 1\n", "0 0.001 -0.001\n");
  write_file_atomically(r.dir / "bad.comp", "0 0 0\n5 0 0\n5 0.001 0\n");
  auto res = r.load((r.dir / "bad.comp").string(), 1);
  EXPECT_EQ(res.first, ipc::CommandState::Rejected);
  EXPECT_NE(res.second.find("bad.comp:3: nominal 5 is not greater than the previous one"), std::string::npos) << res.second;
  res = r.load((r.dir / "x.comp").string(), 7);
  EXPECT_EQ(res.second, "COMP_FILE_TYPE 7 is not 0 (positions) or 1 (trims)");
  res = r.load((r.dir / "missing.comp").string(), 0);
  EXPECT_NE(res.second.find("cannot read the compensation file"), std::string::npos) << res.second;
  EXPECT_EQ(r.pin("screwcomp.0.entries"), "1");
}

TEST(MeasurementLogger, RecordsOnePointPerStopWithDirectionAndZero) {
  cnc::testing::TempDir dir;
  hal::Hal h;
  hal::ComponentRegistry reg;
  hal::register_core_components(reg);
  comp::register_components(reg);
  MessageQueue q;
  hal::CommandInterpreter interp(h, reg, nullptr, &q);
  interp.execute("loadrt threads name1=servo-thread period1=1000000");
  interp.execute("loadrt complog file=" + (dir / "m%d.csv").string() + " axis=X");
  interp.execute("addf complog servo-thread");
  auto* log = h.find<MeasurementLogger>("complog");
  hal::Thread* t = h.find_thread("servo-thread");
  rt::CycleInfo info;
  info.period_ns = info.actual_period_ns = 1'000'000;
  const auto run = [&](double cmd, double actual, int cycles) {
    h.set_value("complog.commanded", std::to_string(cmd));
    h.set_value("complog.actual", std::to_string(actual));
    for (int i = 0; i < cycles; ++i) t->run_cycle(info);
    log->update(0);
  };
  run(0, 5.0, 10);
  h.set_value("complog.enable", "1");
  // Stops: 10 (from below), 20, a short pause at 25 (too short), 20 (from above), 10.
  run(5, 5.0, 5);
  run(10, 15.0010, 600);
  run(20, 25.0030, 600);
  run(25, 30.0, 100);
  run(20, 25.0010, 600);
  run(10 + 5.7e-14, 14.9990, 3);  // a planner's last sample may round past the target
  run(10, 14.9990, 600);
  h.set_value("complog.enable", "0");
  run(10, 15.0, 3);
  ASSERT_EQ(log->finished().size(), 1u);
  const Measurement m = load_measurement(log->finished()[0]);
  EXPECT_EQ(log->finished()[0].filename(), "m1.csv");
  EXPECT_EQ(m.axis, "X");
  ASSERT_EQ(m.points.size(), 4u);
  const double expect[4][3] = {{10, 1, 0.0}, {20, 1, 2.0}, {20, -1, 0.0}, {10, -1, -2.0}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_DOUBLE_EQ(m.points[i].target, expect[i][0]) << i;
    EXPECT_EQ(m.points[i].direction, static_cast<int>(expect[i][1])) << i;
    EXPECT_NEAR(m.points[i].deviation_um, expect[i][2], 1e-6) << i << ": zeroed at the first point, in um";
    EXPECT_EQ(m.points[i].run, 1) << i;
  }
  EXPECT_EQ(h.get_value("complog.measurements"), "1");
  EXPECT_EQ(h.get_value("complog.points"), "4");
}
