// The modules as users load them: `loadrt <module> <args>` in a HAL file,
// geometry with setp, [KINS]JOINTS checked against the module.
#include <gtest/gtest.h>

#include "core/hal/commands.hpp"
#include "core/hal/hal.hpp"
#include "core/ini/ini_file.hpp"
#include "kinematics/kinematics.hpp"

using namespace cnc;
using namespace cnc::kin;

namespace {

class Loaded : public ::testing::Test {
 protected:
  Loaded() { register_kinematics_components(registry); }

  std::string run(const std::string& line) { return interp().execute(line); }
  std::string error_of(const std::string& line) {
    try {
      run(line);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "(no error)";
  }
  Kinematics& kins(const std::string& name) {
    auto* c = hal.find<KinematicsComponent>(name);
    EXPECT_NE(c, nullptr) << name << " is not loaded";
    return c->kinematics();
  }
  hal::CommandInterpreter& interp() {
    if (!interp_) interp_ = std::make_unique<hal::CommandInterpreter>(hal, registry, ini ? &*ini : nullptr, nullptr);
    return *interp_;
  }

  hal::Hal hal;
  hal::ComponentRegistry registry;
  std::optional<ini::IniFile> ini;

 private:
  std::unique_ptr<hal::CommandInterpreter> interp_;
};

}  // namespace

TEST_F(Loaded, EveryModuleIsRegisteredWithHelp) {
  for (const char* n : {"trivkins", "matrixkins", "xyzac-trt-kins", "xyzbc-trt-kins", "headtable-kins", "scarakins",
                        "genserkins"}) {
    const auto* e = registry.find(n);
    ASSERT_NE(e, nullptr) << n;
    EXPECT_FALSE(e->help.empty()) << n;
  }
}

TEST_F(Loaded, TrivkinsGantryFromLoadrt) {
  run("loadrt trivkins coordinates=XYYZ kinstype=B");
  Kinematics& k = kins("trivkins");
  EXPECT_EQ(k.num_joints(), 4);
  EXPECT_EQ(k.type(), KinematicsType::Both);
  EXPECT_EQ(k.axis_mask(), 0x7u);
  EXPECT_EQ(k.joint_axis(1), 1);
  EXPECT_EQ(k.joint_axis(2), 1);
}

TEST_F(Loaded, TrivkinsDefaultsToAllNineAxesAndIdentity) {
  run("loadrt trivkins");
  Kinematics& k = kins("trivkins");
  EXPECT_EQ(k.num_joints(), 9);
  EXPECT_EQ(k.axis_mask(), 0x1FFu);
  EXPECT_EQ(k.type(), KinematicsType::Identity);
}

TEST_F(Loaded, LoadrtErrorsNameTheModuleTheArgumentAndWhatIsExpected) {
  EXPECT_EQ(error_of("loadrt trivkins coordinates=XYQ"),
            "trivkins: coordinates=XYQ: 'Q' is not an axis letter; expected letters from XYZABCUVW");
  EXPECT_EQ(error_of("loadrt trivkins kinstype=Q"),
            "trivkins: kinstype=Q: expected 1 (identity), B (both), F (forward only) or I (inverse only)");
  EXPECT_EQ(error_of("loadrt trivkins coordinate=XYZ"),
            "trivkins: unknown argument \"coordinate\"; it takes coordinates, kinstype");
  EXPECT_EQ(error_of("loadrt xyzac-trt-kins coordinates=XYZBC"),
            "xyzac-trt-kins: coordinates=XYZBC lacks A; this module needs XYZAC");
  EXPECT_EQ(error_of("loadrt xyzac-trt-kins tool-offset=long"), "xyzac-trt-kins: tool-offset=long: expected a number");
  EXPECT_EQ(error_of("loadrt headtable-kins head=C"),
            "headtable-kins: head=C: expected A (head tilts about X) or B (about Y)");
  EXPECT_EQ(error_of("loadrt genserkins joint-types=RRR"),
            "genserkins: joint-types=RRR: expected 6 letters, R (revolute) or P (prismatic) per joint");
  EXPECT_NE(error_of("loadrt scarakins coordinates=XYZ").find("scarakins: unknown argument \"coordinates\""),
            std::string::npos);
  EXPECT_TRUE(hal.components().empty()) << "a refused loadrt leaves nothing behind";
  EXPECT_TRUE(hal.pins().empty());
}

TEST_F(Loaded, OnlyOneKinematicsModule) {
  EXPECT_EQ(find_kinematics(hal), nullptr);
  run("loadrt trivkins coordinates=XYZ");
  ASSERT_NE(find_kinematics(hal), nullptr);
  EXPECT_STREQ(find_kinematics(hal)->kinematics().name(), "trivkins");
  EXPECT_EQ(error_of("loadrt scarakins"),
            "scarakins: kinematics module \"trivkins\" is already loaded; load exactly one");
}

TEST_F(Loaded, KinsJointsMustCoverTheModulesJoints) {
  ini = ini::IniFile::parse("[KINS]\nJOINTS = 3\nKINEMATICS = trivkins coordinates=XYYZ\n", "mill.ini");
  EXPECT_EQ(error_of("loadrt [KINS]KINEMATICS"),
            "trivkins: the module drives 4 joints (XYYZ) but mill.ini:2: [KINS]JOINTS = 3; set [KINS]JOINTS to 4");
}

TEST_F(Loaded, KinsKinematicsExpandsFromTheIni) {
  ini = ini::IniFile::parse("[KINS]\nJOINTS = 4\nKINEMATICS = trivkins coordinates=XYYZ kinstype=both\n", "mill.ini");
  run("loadrt [KINS]KINEMATICS");
  EXPECT_EQ(kins("trivkins").num_joints(), 4);
}

TEST_F(Loaded, TrtGeometryFromLoadrtThenSetp) {
  run("loadrt xyzac-trt-kins coordinates=XYZAC y-offset=5 z-rot-point=30");
  EXPECT_EQ(hal.get_value("xyzac-trt-kins.y-offset"), "5");
  EXPECT_EQ(hal.get_value("xyzac-trt-kins.z-rot-point"), "30");
  run("setp xyzac-trt-kins.x-rot-point 10");
  run("setp xyzac-trt-kins.y-rot-point 20");
  run("setp xyzac-trt-kins.z-offset -3");
  // The hand-computed pose of five_axis_test: (1, 2, 3) at A = 90 -> (1, 49, 4).
  Pose p;
  p[Axis::X] = 1;
  p[Axis::Y] = 2;
  p[Axis::Z] = 3;
  p[Axis::A] = 90;
  double j[5];
  ASSERT_EQ(kins("xyzac-trt-kins").inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 1, 1e-12);
  EXPECT_NEAR(j[1], 49, 1e-12);
  EXPECT_NEAR(j[2], 4, 1e-12);

  // A tool change: the motion controller's tool offset reaches the pin.
  run("net tool-z xyzac-trt-kins.tool-offset");
  run("sets tool-z 10");
  ASSERT_EQ(kins("xyzac-trt-kins").inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[1], 59, 1e-12);
  EXPECT_NEAR(j[2], 14, 1e-12);
}

TEST_F(Loaded, SwitchableModulesExportKinstypePins) {
  run("loadrt xyzbc-trt-kins");
  Kinematics& k = kins("xyzbc-trt-kins");
  EXPECT_EQ(hal.get_value("kinstype.is-0"), "TRUE");
  EXPECT_EQ(hal.get_value("kinstype.is-1"), "FALSE");
  EXPECT_TRUE(k.switch_to(1));
  EXPECT_EQ(k.active_switch(), 1);
  EXPECT_EQ(hal.get_value("kinstype.is-0"), "FALSE");
  EXPECT_EQ(hal.get_value("kinstype.is-1"), "TRUE");
  EXPECT_EQ(k.joint_axis(0), 0) << "identity: joints are axes again";
  EXPECT_FALSE(k.switch_to(2));
  EXPECT_EQ(k.active_switch(), 1);
  EXPECT_TRUE(k.switch_to(0));
  EXPECT_EQ(k.joint_axis(0), -1);
  EXPECT_EQ(k.joint_coordinate(0), 0);
}

TEST_F(Loaded, ScaraPinsStartAtLinuxCncDefaults) {
  run("loadrt scarakins");
  EXPECT_EQ(hal.get_value("scarakins.d1"), "490");
  EXPECT_EQ(hal.get_value("scarakins.d2"), "340");
  EXPECT_EQ(hal.get_value("scarakins.d6"), "50");
  run("setp scarakins.d6 0");
  const double j[6] = {0, 0, 0, 0, 0, 0};
  Pose p;
  ASSERT_EQ(kins("scarakins").forward(j, p), KinResult::Ok);
  EXPECT_DOUBLE_EQ(p[Axis::X], 590);
}

TEST_F(Loaded, GenserLimitsComeFromTheIni) {
  ini = ini::IniFile::parse("[JOINT_1]\nMIN_LIMIT = -120\nMAX_LIMIT = 45.5\n", "arm.ini");
  run("loadrt genserkins a-1=85 alpha-1=-1.5707963267948966");
  EXPECT_EQ(hal.get_value("genserkins.min-limit-1"), "-120");
  EXPECT_EQ(hal.get_value("genserkins.max-limit-1"), "45.5");
  EXPECT_EQ(hal.get_value("genserkins.a-1"), "85");
  EXPECT_EQ(hal.get_value("genserkins.max-limit-0"), "1e+09") << "no limit unless configured";
  EXPECT_TRUE(hal.has_pin("genserkins.last-iterations"));
}
