// The offline time estimate (core/task/estimate.hpp): programs read through
// the task controller's canon with an INI file's parameters, run by the
// planner; planned motion time (servo periods), not wall time.
#include "core/task/estimate.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/util/error.hpp"

namespace cnc::estimate {
namespace {

namespace fs = std::filesystem;

// A folder with an INI file (trivkins XYZ, 100 mm/s, 1000 mm/s^2,
// 50 000 mm/s^3 per axis and joint; `replace` swaps one line of it for
// another), a tool table and a parameter file; programs are written beside
// them.
class Config {
 public:
  explicit Config(const std::string& var = "", std::pair<std::string, std::string> replace = {}) {
    dir_ = fs::temp_directory_path() / ("estimate_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                                        "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    std::ofstream(dir_ / "tool.tbl") << "T1 P1 Z12.5 D6 ;\nT2 P2 Z30 D10 ;\n";
    if (!var.empty()) std::ofstream(dir_ / "t.var") << var;
    std::string ini =
        "[EMCMOT]\nSERVO_PERIOD = 1000000\n"
        "[TRAJ]\nCOORDINATES = X Y Z\nLINEAR_UNITS = mm\nANGULAR_UNITS = degree\n"
        "[KINS]\nKINEMATICS = trivkins coordinates=XYZ\nJOINTS = 3\n"
        "[RS274NGC]\nPARAMETER_FILE = t.var\n"
        "[EMCIO]\nTOOL_TABLE = tool.tbl\n";
    for (int i = 0; i < 3; ++i) {
      ini += std::string("[AXIS_") + "XYZ"[i] + "]\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nMAX_JERK = 50000\n";
      ini += "[JOINT_" + std::to_string(i) + "]\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nMAX_JERK = 50000\nHOME = 0\n";
    }
    if (!replace.first.empty()) {
      const auto at = ini.find(replace.first);
      if (at != std::string::npos) ini.replace(at, replace.first.size(), replace.second);
    }
    std::ofstream(dir_ / "t.ini") << ini;
  }
  ~Config() { fs::remove_all(dir_); }
  fs::path program(const std::string& text) const {
    std::ofstream(dir_ / "p.ngc") << text;
    return dir_ / "p.ngc";
  }
  fs::path ini() const { return dir_ / "t.ini"; }

 private:
  fs::path dir_;
};

// Minimum time of a rest-to-rest move of length L under v, a, j (v >= a^2/j).
double rest_to_rest(double L, double v, double a, double j) {
  const double t = v / a + a / j;
  const double s = v * t / 2;
  return 2 * t + (L - 2 * s) / v;
}

void expect_end(const Result& r, double x, double y, double z) {
  EXPECT_NEAR(r.end[0], x, 1e-6);
  EXPECT_NEAR(r.end[1], y, 1e-6);
  EXPECT_NEAR(r.end[2], z, 1e-6);
}

// The INI has no [TRAJ]MAX_LINEAR_ACCELERATION / _JERK: the axis limits
// alone apply (motion::planner_config used to hand the planner 1e99 for
// both, which it took as a 1 s smoothing time: 2.16 s here).
TEST(Estimate, AStraightMoveTakesTheJerkLimitedMinimumTimeWithoutTrajLimits) {
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90 G61\nG1 X100 F6000\nM2\n"));
  ASSERT_TRUE(r.completed) << r.error;
  expect_end(r, 100, 0, 0);
  // 1.12 s; the planner may end up to a few servo periods later.
  const double t = rest_to_rest(100, 100, 1000, 50000);
  EXPECT_GE(r.time_s, t - 1e-9);
  EXPECT_LE(r.time_s, t + 0.01);
  EXPECT_LE(r.stats.ratio_v, 1 + 1e-9);
  EXPECT_LE(r.stats.ratio_j, 1 + 1e-9);
}

TEST(Estimate, ProgramCoordinatesBecomeMachineOnesAsInTheTaskCanon) {
  // G55 at X10 Y20 Z-5 rotated 90 degrees, inches, then G92.
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90 G64 P0.01\n"
                                         "G10 L2 P2 X10 Y20 Z-5 R90\n"
                                         "G55 G20\n"
                                         "G1 X1 Y0 Z0 F100\n"  // program X25.4 mm, rotated onto machine +Y
                                         "G92 X0 Y0\n"
                                         "G1 X1\n"             // 25.4 mm further along the rotated X
                                         "M2\n"));
  ASSERT_TRUE(r.completed) << r.error;
  expect_end(r, 10, 20 + 2 * 25.4, -5);
}

TEST(Estimate, OffsetsSetInInchesHoldAfterG21) {
  // G54 Z-1 inch = -25.4 mm; the task canon used to keep -1 and apply it
  // as -1 mm once the program went back to millimetres.
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G20 G90\nG10 L2 P1 X1 Y0 Z-1\nG54\nG0 X0 Y0 Z0\nG21\nG0 X10 Z10\nM2\n"));
  ASSERT_TRUE(r.completed) << r.error;
  expect_end(r, 25.4 + 10, 0, -25.4 + 10);
}

TEST(Estimate, WorkOffsetsComeFromTheParameterFile) {
  // #5221..5223: G54's X, Y, Z.
  Config c("5221\t50.000000\n5222\t-7.500000\n5223\t-20.000000\n");
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90 G54\nG0 X1 Y2 Z3\nM2\n"));
  ASSERT_TRUE(r.completed) << r.error;
  expect_end(r, 51, -5.5, -17);
}

TEST(Estimate, ToolLengthOffsetFollowsTheToolChange) {
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90\nT2 M6\nG43\nG0 X0 Y0 Z-40\nM2\n"));
  ASSERT_TRUE(r.completed) << r.error;
  expect_end(r, 0, 0, -10);  // Z-40 with tool 2's 30 mm
  EXPECT_EQ(r.stops, 0U);    // nothing moved before the change
}

TEST(Estimate, MotionStopsWhereTheTaskWaitsForIt) {
  // Two collinear blended moves: with M66 between them the machine stops.
  Config c;
  const Machine m = load_machine(c.ini());
  const Result through = estimate(m, c.program("G21 G90 G64 P0.01\nG1 X50 F6000\nG1 X100\nM2\n"));
  const Result stopped = estimate(m, c.program("G21 G90 G64 P0.01\nG1 X50 F6000\nM66 P0 L0\nG1 X100\nM2\n"));
  ASSERT_TRUE(through.completed) << through.error;
  ASSERT_TRUE(stopped.completed) << stopped.error;
  EXPECT_EQ(through.stops, 0U);
  EXPECT_EQ(stopped.stops, 1U);
  expect_end(stopped, 100, 0, 0);
  EXPECT_GE(stopped.time_s, 2 * rest_to_rest(50, 100, 1000, 50000) - 1e-9);
  EXPECT_LT(through.time_s, stopped.time_s - 0.1);
}

TEST(Estimate, JointLimitsNarrowTheAxisLimitsAsInMotion) {
  Config c("", {"[JOINT_1]\nMAX_VELOCITY = 100", "[JOINT_1]\nMAX_VELOCITY = 40"});
  const Machine m = load_machine(c.ini());
  EXPECT_TRUE(m.joint_limits_applied);
  EXPECT_DOUBLE_EQ(m.planner.axes[0].max_velocity, 100);
  EXPECT_DOUBLE_EQ(m.planner.axes[1].max_velocity, 40);
  EXPECT_EQ(m.planner.lookahead_segments, 1000);
  EXPECT_DOUBLE_EQ(m.planner.cycle_time_s, 0.001);
}

TEST(Estimate, AMainProgramEndingInM99IsEstimatedOnce) {
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90 G61\nG1 X10 F6000\nG1 X0\nM99\n"));
  ASSERT_TRUE(r.completed) << r.error;
  EXPECT_EQ(r.moves, 2U);
  expect_end(r, 0, 0, 0);
}

TEST(Estimate, AProgramErrorNamesFileAndLine) {
  Config c;
  const Machine m = load_machine(c.ini());
  const Result r = estimate(m, c.program("G21 G90\nG1 X10 F100\nG2 X20\nM2\n"));
  EXPECT_FALSE(r.completed);
  EXPECT_NE(r.error.find("p.ngc:3"), std::string::npos) << r.error;
}

TEST(Estimate, ABadIniValueNamesItsKey) {
  Config c("", {"[AXIS_X]\nMAX_VELOCITY = 100", "[AXIS_X]\nMAX_VELOCITY = fast"});
  try {
    load_machine(c.ini());
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("MAX_VELOCITY"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace cnc::estimate
