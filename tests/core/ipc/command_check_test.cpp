// Range checks of client command arguments: what every client's command
// must satisfy before any part of the controller acts on it.
#include "core/ipc/command_check.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using cnc::ipc::check_arguments;
using cnc::ipc::Command;
using cnc::ipc::CommandType;

namespace {
Command cmd(CommandType t, int i0 = 0, double d0 = 0) {
  Command c;
  c.type = t;
  c.i[0] = i0;
  c.d[0] = d0;
  return c;
}
}  // namespace

TEST(CommandCheck, InRangeArgumentsPass) {
  EXPECT_EQ(check_arguments(cmd(CommandType::JointHome, -1)), "");
  EXPECT_EQ(check_arguments(cmd(CommandType::JointHome, 2)), "");
  EXPECT_EQ(check_arguments(cmd(CommandType::SpindleOn, 0, -3000)), "");
  EXPECT_EQ(check_arguments(cmd(CommandType::TrajSetScale, 0, 1.2)), "");
  EXPECT_EQ(check_arguments(cmd(CommandType::TaskPlanExecute, -1)), "");
  EXPECT_EQ(check_arguments(cmd(CommandType::Ping)), "");
}

TEST(CommandCheck, AJointIndexThatWouldWrapIsRefused) {
  // 4294967296 cast to int32 is 0: joint 0 must not home.
  EXPECT_EQ(check_arguments(cmd(CommandType::JointHome, 16)), "joint 16 is out of range (expected -1 to 15)");
  EXPECT_NE(check_arguments(cmd(CommandType::JointHome, -7)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::TaskPlanExecute, -5)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::TaskSetState, 9)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::TaskSetMode, 0)), "");
}

TEST(CommandCheck, NonFiniteAndHugeRealsAreRefused) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(check_arguments(cmd(CommandType::SpindleOn, 0, 1e308)),
            "speed (rpm) 1e+308 is out of range (expected -1e+06 to 1e+06)");
  EXPECT_EQ(check_arguments(cmd(CommandType::SpindleOn, 0, std::nan(""))), "speed (rpm) is not a finite number");
  EXPECT_NE(check_arguments(cmd(CommandType::TrajSetScale, 0, inf)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::TrajSetScale, 0, -0.5)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::TrajSetMaxVelocity, 0, -1)), "");
  EXPECT_NE(check_arguments(cmd(CommandType::SetParameter, 0, inf)), "");
}

TEST(CommandCheck, JogChecksTheJointOrAxisItNamesAndItsNumbers) {
  Command c = cmd(CommandType::JogIncr, 8, 10);
  c.i[1] = 0;  // axis W
  c.d[1] = 5;
  EXPECT_EQ(check_arguments(c), "");
  c.i[0] = 9;
  EXPECT_EQ(check_arguments(c), "axis 9 is out of range (expected 0 to 8)");
  c.i[0] = 0;
  c.i[1] = 2;
  EXPECT_EQ(check_arguments(c), "joint/axis selector 2 is out of range (expected 0 to 1)");
  c.i[1] = 1;
  c.d[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(check_arguments(c), "distance is not a finite number");
  c.d[1] = 1;
  c.d[0] = -1;
  EXPECT_NE(check_arguments(c), "") << "an incremental jog's velocity is positive";
}

TEST(CommandCheck, EveryRealOfAToolOrOffsetEditIsChecked) {
  Command t = cmd(CommandType::ToolSetOffset, 3);
  t.i[1] = -1;
  EXPECT_EQ(check_arguments(t), "");
  t.d[7] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(check_arguments(t), "offset is not a finite number");
  Command w = cmd(CommandType::SetWorkOffset, 1);
  w.d[2] = -1e9;
  EXPECT_NE(check_arguments(w), "");
  w.d[2] = -80;
  w.i[0] = 10;
  EXPECT_EQ(check_arguments(w), "coordinate system 10 is out of range (expected 0 to 9)");
}
