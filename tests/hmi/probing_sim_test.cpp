// The screen's probing routines (hmi/probing) against the simulated part of
// configs/sim (sim_part, [SIM_PART]: a block with a bore, probed by a ball
// tip at the drives' true table positions): the controller as cncd builds
// it from configs/sim (tests/comp/sim_mill.hpp: HAL files, motion, task,
// interpreter, the CANopen masters and the simulated drives), stepped in
// simulated time. Each routine runs as the Probe page runs it: a stage's
// MDI lines one after the other in MDI mode, each done before the next,
// then the probe result from the status taken after them.
//
// The truth is the part's position as the machine's encoders see it: the
// table position of a face plus (joint position - table position) measured
// at rest near the part after a move in the probing direction (that
// difference holds the pitch error and the backlash side that no probe can
// see without screw compensation). Tolerance: 5 um plus the latch lag (the
// simulated probe signal reaches the drives two servo periods after the
// contact: two periods of travel at the latch feed).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cia402/components.hpp"
#include "core/ipc/operator_commands.hpp"
#include "fieldbus/canopen/components.hpp"
#include "hmi/probing.hpp"
#include "sim/machine/part.hpp"
#include "tests/comp/sim_mill.hpp"
#include "tests/fieldbus/canopen/pace.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::hmi::probing;

namespace {

constexpr double kLatchFeed = 30;     // mm/min
constexpr double kServoPeriod = 1e-3;  // s, configs/sim
// 5 um plus two servo periods of travel at the latch feed.
const double kTolerance = 0.005 + 2 * kServoPeriod * kLatchFeed / 60;

const char* const kTablePins[] = {"cia402-sim.0.node.01.table-position", "cia402-sim.0.node.02.table-position",
                                  "cia402-sim.1.node.03.table-position"};

class Bench {
 public:
  Bench()
      : mill_(cnc::testing::source_dir() / "configs/sim", work_.path() / "sim", "sim.ini",
              [](hal::ComponentRegistry& r) {
                canopen::register_components(r);
                cia402::register_components(r);
              }),
        part_(sim::Part::from_ini(ini::IniFile::load(work_.path() / "sim" / "sim.ini"), "SIM_PART")) {
    mill_.pace = canopen::test::acyclic_pacer(mill_.hal());
    settings_.tip_diameter = part_.tip_diameter;
    settings_.search_distance = 10;
    settings_.latch_distance = 1;
    settings_.search_feed = 300;
    settings_.latch_feed = kLatchFeed;
    settings_.clearance = 5;
  }

  std::string power_up() {
    mill_.step(100);
    std::string e = mill_.power_up();
    if (!e.empty()) return e;
    const auto r = mill_.send(ipc::commands::set_mode(ipc::TaskMode::Mdi));
    return r.first == ipc::CommandState::Done ? std::string() : "mdi mode: " + r.second;
  }

  // One MDI line, to its end; empty on success.
  std::string mdi(const std::string& line) {
    const auto r = mill_.send(ipc::commands::mdi(line));
    return r.first == ipc::CommandState::Done ? std::string() : line + ": " + r.second + mill_.errors();
  }

  // Runs a routine as the Probe page does; empty on success. After a
  // failure, the routine's cleanup lines, as the page sends them.
  std::string run(Routine& routine) {
    while (!routine.done()) {
      for (const std::string& line : routine.stage().lines) {
        if (std::string e = mdi(line); !e.empty()) {
          routine.fail(e);
          break;
        }
      }
      if (routine.failed()) break;
      mill_.step(20);  // the status after the answer (published every 10th cycle here)
      routine.completed(mill_.status().motion.probe_tripped, mill_.status().motion.probed_position);
    }
    if (routine.failed()) {
      mill_.errors();  // the failure's own message
      for (const std::string& line : routine.cleanup_lines()) {
        if (std::string e = mdi(line); !e.empty()) return routine.error() + "; cleanup: " + e;
      }
    }
    return routine.error();
  }

  bool has_gcode(int code) const {
    const auto& g = mill_.status().task.active_gcodes;
    return std::find(std::begin(g), std::end(g), code) != std::end(g);
  }

  Start start() const { return start_from(mill_.status()); }

  double pin(const std::string& name) { return std::stod(mill_.hal().get_value(name)); }

  // Joint position minus table position of `axis` at rest where the machine
  // stands, after a move toward `direction` (+1/-1) as a probe makes.
  double offset(int axis, int direction) {
    const std::string a(1, "XYZ"[axis]);
    const double here = pin("joint." + std::to_string(axis) + ".pos-fb");
    EXPECT_EQ(mdi("G91 G1 " + a + gcode_number(-direction * 0.5) + " F300"), "");
    EXPECT_EQ(mdi("G1 " + a + gcode_number(direction * 0.5) + " F" + gcode_number(kLatchFeed)), "");
    EXPECT_EQ(mdi("G90"), "");
    mill_.step(300);  // settled
    const double off = pin("joint." + std::to_string(axis) + ".pos-fb") - pin(kTablePins[axis]);
    EXPECT_NEAR(pin("joint." + std::to_string(axis) + ".pos-fb"), here, 0.001);
    return off;
  }
  double table_offset(int axis) { return pin("joint." + std::to_string(axis) + ".pos-fb") - pin(kTablePins[axis]); }

  // Rapid (machine coordinates) to where a table position is, by the
  // offset at the current place: within the backlash, enough to start a
  // probe from.
  std::string go(double table_x, double table_y, double table_z) {
    const double ox = table_offset(0), oy = table_offset(1), oz = table_offset(2);
    if (std::string e = mdi("G53 G0 Z0"); !e.empty()) return e;
    if (std::string e = mdi("G53 G0 X" + gcode_number(table_x + ox) + " Y" + gcode_number(table_y + oy)); !e.empty()) {
      return e;
    }
    return mdi("G53 G0 Z" + gcode_number(table_z + oz));
  }

  cnc::testing::SimMill& mill() { return mill_; }
  const sim::Part& part() const { return part_; }
  Settings& settings() { return settings_; }

 private:
  cnc::testing::TempDir work_;
  cnc::testing::SimMill mill_;
  sim::Part part_;
  Settings settings_;
};

class ProbingTheSimulatedPart : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    bench_ = new Bench();
    const std::string e = bench_->power_up();
    if (!e.empty()) {
      setup_error_ = new std::string(e);
    }
  }
  static void TearDownTestSuite() {
    delete bench_;
    bench_ = nullptr;
    delete setup_error_;
    setup_error_ = nullptr;
  }
  void SetUp() override {
    if (setup_error_) GTEST_FAIL() << "power up: " << *setup_error_;
  }
  static Bench& b() { return *bench_; }
  const sim::Part& part() { return bench_->part(); }
  double depth() { return part().z_top - 5; }  // table Z where the walls are probed

  static Bench* bench_;
  static std::string* setup_error_;
};

Bench* ProbingTheSimulatedPart::bench_ = nullptr;
std::string* ProbingTheSimulatedPart::setup_error_ = nullptr;

TEST_F(ProbingTheSimulatedPart, TheToolSetterStillTripsOnZAlone) {
  // Beside the part, down onto the setter (table Z -100 everywhere).
  ASSERT_EQ(b().go(part().x_max + 20, part().y_max + 20, -95), "");
  const double contact = -100 + b().table_offset(2);
  ASSERT_EQ(b().mdi("G91 G38.2 Z-10 F" + gcode_number(kLatchFeed)), "");
  ASSERT_EQ(b().mdi("G90 G53 G0 Z0"), "");
  b().mill().step(20);
  const ipc::Status& s = b().mill().status();
  EXPECT_TRUE(s.motion.probe_tripped);
  EXPECT_NEAR(s.motion.probed_position[2], contact, 0.004);
  EXPECT_EQ(b().mill().errors(), "");  // every drive latched: no "latched nothing" message
}

TEST_F(ProbingTheSimulatedPart, EdgesAreFoundWithinTolerance) {
  struct Case {
    int axis, direction;
  };
  const double mid_x = (part().x_min + part().x_max) / 2, mid_y = (part().y_min + part().y_max) / 2;
  const double r = part().tip_diameter / 2;
  for (const Case c : {Case{0, 1}, Case{0, -1}, Case{1, 1}, Case{1, -1}}) {
    const double face = c.axis == 0 ? (c.direction > 0 ? part().x_min : part().x_max)
                                    : (c.direction > 0 ? part().y_min : part().y_max);
    const double from = face - c.direction * (r + 4);  // the tip 4 mm off the face
    ASSERT_EQ(b().go(c.axis == 0 ? from : mid_x, c.axis == 1 ? from : mid_y, depth()), "");
    const double off = b().offset(c.axis, c.direction);
    Routine routine(b().settings(), Request{.kind = Kind::Edge, .axis = c.axis, .direction = c.direction}, b().start());
    ASSERT_EQ(b().run(routine), "");
    const double found = c.axis == 0 ? routine.result().x : routine.result().y;
    const double truth = face + off;
    std::printf("edge %c%c: found %.4f, true %.4f: %+.2f um\n", "XY"[c.axis], c.direction > 0 ? '+' : '-', found, truth,
                (found - truth) * 1000);
    EXPECT_NEAR(found, truth, kTolerance) << "edge " << c.axis << " " << c.direction;
  }
}

TEST_F(ProbingTheSimulatedPart, AnOutsideCornerIsFoundWithinTolerance) {
  const double r = part().tip_diameter / 2;
  // Off the (X min, Y min) corner: the material toward +X and +Y.
  ASSERT_EQ(b().go(part().x_min - r - 4, part().y_min - r - 4, depth()), "");
  const double off_x = b().offset(0, 1), off_y = b().offset(1, 1);
  Request q{.kind = Kind::OutsideCorner, .corner_x = 1, .corner_y = 1, .corner_step = 10};
  Routine routine(b().settings(), q, b().start());
  ASSERT_EQ(b().run(routine), "");
  const double tx = part().x_min + off_x, ty = part().y_min + off_y;
  std::printf("outside corner: found X %.4f Y %.4f, true X %.4f Y %.4f: %+.2f %+.2f um\n", routine.result().x,
              routine.result().y, tx, ty, (routine.result().x - tx) * 1000, (routine.result().y - ty) * 1000);
  EXPECT_NEAR(routine.result().x, tx, kTolerance);
  EXPECT_NEAR(routine.result().y, ty, kTolerance);
}

TEST_F(ProbingTheSimulatedPart, ABoreCentreIsFoundWithinToleranceAndSetAsAnOrigin) {
  // Off the bore's centre by (1.3, -0.8) mm.
  ASSERT_EQ(b().go(part().bore_x + 1.3, part().bore_y - 0.8, depth()), "");
  const double ox = (b().offset(0, 1) + b().offset(0, -1)) / 2, oy = (b().offset(1, 1) + b().offset(1, -1)) / 2;
  Routine routine(b().settings(), Request{.kind = Kind::Bore, .coordinate_system = 2, .value_x = 10, .value_y = -5},
                  b().start());
  ASSERT_EQ(b().run(routine), "");
  const double tx = part().bore_x + ox, ty = part().bore_y + oy;
  const Result& res = routine.result();
  std::printf("bore: centre X %.4f Y %.4f, true X %.4f Y %.4f: %+.2f %+.2f um; diameter X %.4f Y %.4f (true %.4f)\n",
              res.x, res.y, tx, ty, (res.x - tx) * 1000, (res.y - ty) * 1000, res.diameter_x, res.diameter_y,
              part().bore_diameter);
  EXPECT_NEAR(res.x, tx, kTolerance);
  EXPECT_NEAR(res.y, ty, kTolerance);
  // The routine ends at the centre.
  EXPECT_NEAR(b().mill().status().motion.position[0], res.x, 0.001);
  EXPECT_NEAR(b().mill().status().motion.position[1], res.y, 0.001);
  // Touch-off: G55 reads X10 Y-5 at the centre.
  ASSERT_EQ(b().mdi("G55"), "");
  b().mill().step(20);
  const ipc::Status& s = b().mill().status();
  EXPECT_EQ(s.task.g5x_index, 2);
  EXPECT_NEAR(s.task.g5x_offset[0], res.x - 10, 1e-4);
  EXPECT_NEAR(s.task.g5x_offset[1], res.y + 5, 1e-4);
  ASSERT_EQ(b().mdi("G54"), "");
}

TEST_F(ProbingTheSimulatedPart, TipCalibrationInTheBoreGivesTheTipAsTheMachineSeesItAndEdgesUseIt) {
  ASSERT_EQ(b().go(part().bore_x - 0.6, part().bore_y + 0.9, depth()), "");
  const double off_px = b().offset(0, 1), off_mx = b().offset(0, -1);
  const double off_py = b().offset(1, 1), off_my = b().offset(1, -1);
  Settings nominal = b().settings();
  nominal.tip_diameter = 2;  // what the screen was told: wrong by a millimetre
  Routine routine(nominal, Request{.kind = Kind::TipCalibration, .gauge_diameter = part().bore_diameter}, b().start());
  ASSERT_EQ(b().run(routine), "");
  const Result& res = routine.result();
  // The centre's travel between the true contacts is the bore less the
  // ball plus the offsets' difference (the backlash): the effective tip is
  // the ball less that difference.
  const double expect_x = part().tip_diameter - (off_px - off_mx);
  const double expect_y = part().tip_diameter - (off_py - off_my);
  std::printf("tip calibration: %.4f (X %.4f, Y %.4f); ball %.4f, expected X %.4f Y %.4f: %+.2f %+.2f um\n",
              res.tip_diameter, res.tip_diameter_x, res.tip_diameter_y, part().tip_diameter, expect_x, expect_y,
              (res.tip_diameter_x - expect_x) * 1000, (res.tip_diameter_y - expect_y) * 1000);
  EXPECT_NEAR(res.tip_diameter_x, expect_x, 2 * kTolerance);
  EXPECT_NEAR(res.tip_diameter_y, expect_y, 2 * kTolerance);
  // With the calibrated tip an edge is within tolerance of the face as the
  // encoders see it (the nominal 2 mm would be 0.5 mm off).
  Settings calibrated = b().settings();
  calibrated.tip_diameter = res.tip_diameter;
  const double r = part().tip_diameter / 2;
  ASSERT_EQ(b().go(part().x_max + r + 4, (part().y_min + part().y_max) / 2, depth()), "");
  const double off = b().offset(0, -1);
  Routine edge(calibrated, Request{.kind = Kind::Edge, .axis = 0, .direction = -1}, b().start());
  ASSERT_EQ(b().run(edge), "");
  std::printf("edge X- with the calibrated tip: %.4f, true %.4f: %+.2f um\n", edge.result().x, part().x_max + off,
              (edge.result().x - part().x_max - off) * 1000);
  EXPECT_NEAR(edge.result().x, part().x_max + off, kTolerance);
}

TEST_F(ProbingTheSimulatedPart, RoutinesRestoreTheOperatorsModalStateAfterSuccessAndFailure) {
  const double r = part().tip_diameter / 2;
  ASSERT_EQ(b().go(part().x_min - r - 4, (part().y_min + part().y_max) / 2, depth()), "");
  const double off = b().offset(0, 1);
  // The operator works in inches, incremental, F7 (inch/min).
  ASSERT_EQ(b().mdi("G20"), "");
  ASSERT_EQ(b().mdi("G91"), "");
  ASSERT_EQ(b().mdi("F7"), "");
  b().mill().step(20);
  ASSERT_TRUE(b().has_gcode(200) && b().has_gcode(910));
  Routine edge(b().settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, b().start());
  ASSERT_EQ(b().run(edge), "");
  EXPECT_NEAR(edge.result().x, part().x_min + off, kTolerance);  // the routine's numbers were millimetres
  b().mill().step(20);
  EXPECT_TRUE(b().has_gcode(200)) << "G20 restored";
  EXPECT_TRUE(b().has_gcode(910)) << "G91 restored";
  EXPECT_NEAR(b().mill().status().task.active_settings[1], 7, 1e-9);
  // A probe into the air: the abort resets the interpreter; the page puts
  // the start's modal state back.
  ASSERT_EQ(b().mdi("G90"), "");
  ASSERT_EQ(b().mdi("G53 G0 Z0"), "");
  ASSERT_EQ(b().mdi("G91"), "");
  b().mill().step(20);
  Routine air(b().settings(), Request{.kind = Kind::Edge, .axis = 0, .direction = 1}, b().start());
  EXPECT_NE(b().run(air), "");
  EXPECT_TRUE(air.failed());
  b().mill().step(20);
  EXPECT_TRUE(b().has_gcode(200)) << "G20 restored";
  EXPECT_TRUE(b().has_gcode(910)) << "G91 restored";
  EXPECT_NEAR(b().mill().status().task.active_settings[1], 7, 1e-9);
  ASSERT_EQ(b().mdi("G21"), "");
  ASSERT_EQ(b().mdi("G90"), "");
}

}  // namespace
