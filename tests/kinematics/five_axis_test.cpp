// Table-table and head-table 5-axis kinematics: hand-computed poses, round
// trips over seeded random poses (closed form: below 1e-9 mm), the tool tip
// held on the workpiece while the rotary axes turn, and a programmed 5-axis
// segment whose tool tip stays on its path.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <numbers>

#include "core/motion/motion_component.hpp"
#include "core/motion/motion_controller.hpp"
#include "core/tp/lookahead_planner.hpp"
#include "core/util/messages.hpp"
#include "kinematics/five_axis.hpp"
#include "tests/kinematics/kin_test_util.hpp"

using namespace cnc;
using namespace cnc::kin;
using cnc::kin::testing::linear_error;
using cnc::kin::testing::max_error;
using cnc::kin::testing::pose_text;
using cnc::kin::testing::Rng;
using Eigen::Vector3d;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Pose make_pose(double x, double y, double z, double a, double b, double c) {
  Pose p;
  p[Axis::X] = x;
  p[Axis::Y] = y;
  p[Axis::Z] = z;
  p[Axis::A] = a;
  p[Axis::B] = b;
  p[Axis::C] = c;
  return p;
}

JointMap map(const char* letters) { return JointMap::parse(letters, "test", true); }

// A table-table machine as a test sets it up: the C axis through `r`, the
// tilt axis `d` from it, tool length `tool`.
struct TrtGeometry {
  Vector3d r{12.5, -7.25, -120.0};
  Vector3d d{0.0, 3.5, -40.0};  // for A; (x, 0, z) for B
  double tool = 55.0;
};

void apply(TableTableKins& k, const TrtGeometry& g) {
  auto& p = k.params();
  p.x_rot_point.set(g.r.x());
  p.y_rot_point.set(g.r.y());
  p.z_rot_point.set(g.r.z());
  p.x_offset.set(g.d.x());
  p.y_offset.set(g.d.y());
  p.z_offset.set(g.d.z());
  p.tool_offset.set(g.tool);
}

// The physical machine, written as turns about lines (not the module's
// formula): where a workpiece point is in machine coordinates.
Vector3d trt_machine_point(const TrtGeometry& g, TiltAxis tilt, const Vector3d& w, double t_deg, double c_deg) {
  const Vector3d on_c = g.r + Eigen::AngleAxisd(c_deg * kDeg, Vector3d::UnitZ()) * (w - g.r);
  const Vector3d pivot = g.r + g.d;
  const Vector3d axis = tilt == TiltAxis::A ? Vector3d::UnitX() : Vector3d::UnitY();
  return pivot + Eigen::AngleAxisd(t_deg * kDeg, axis) * (on_c - pivot);
}

// Where the tool tip of a table-table machine is, as a workpiece point.
Vector3d trt_tip_on_workpiece(const TrtGeometry& g, TiltAxis tilt, const double* j, int tilt_joint, int c_joint) {
  const Vector3d tip_m = Vector3d(j[0], j[1], j[2]) - Vector3d(0, 0, g.tool);
  const Vector3d pivot = g.r + g.d;
  const Vector3d axis = tilt == TiltAxis::A ? Vector3d::UnitX() : Vector3d::UnitY();
  const Vector3d on_c = pivot + Eigen::AngleAxisd(-j[tilt_joint] * kDeg, axis) * (tip_m - pivot);
  return g.r + Eigen::AngleAxisd(-j[c_joint] * kDeg, Vector3d::UnitZ()) * (on_c - g.r);
}

struct HeadGeometry {
  Vector3d r{5.0, -2.0, 0.0};
  double pivot = 100.0;
  double tool = 20.0;
};

void apply(HeadTableKins& k, const HeadGeometry& g) {
  k.params().x_rot_point.set(g.r.x());
  k.params().y_rot_point.set(g.r.y());
  k.params().pivot_length.set(g.pivot);
  k.params().tool_offset.set(g.tool);
}

Vector3d head_tip_on_workpiece(const HeadGeometry& g, TiltAxis head, const double* j) {
  const Vector3d pivot = Vector3d(j[0], j[1], j[2]) + Vector3d(0, 0, g.pivot);
  const Vector3d axis = head == TiltAxis::A ? Vector3d::UnitX() : Vector3d::UnitY();
  const Vector3d tool_dir = Eigen::AngleAxisd(j[3] * kDeg, axis) * Vector3d::UnitZ();  // tip -> spindle
  const Vector3d tip_m = pivot - (g.pivot + g.tool) * tool_dir;
  return g.r + Eigen::AngleAxisd(-j[4] * kDeg, Vector3d::UnitZ()) * (tip_m - g.r);
}

}  // namespace

// ---- hand-computed poses ----

TEST(TableTableKins, XyzacKnownPoses) {
  TableTableKins k("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  auto& p = k.params();
  p.x_rot_point.set(10);
  p.y_rot_point.set(20);
  p.z_rot_point.set(30);
  p.y_offset.set(5);
  p.z_offset.set(-3);
  double j[5];
  // A = 90: p - r = (-9, -18, -27); minus d (0, 5, -3) = (-9, -23, -24);
  // turned 90 degrees about X: (-9, 24, -23); plus r + d (10, 25, 27).
  ASSERT_EQ(k.inverse(make_pose(1, 2, 3, 90, 0, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 1, 1e-12);
  EXPECT_NEAR(j[1], 49, 1e-12);
  EXPECT_NEAR(j[2], 4, 1e-12);
  EXPECT_EQ(j[3], 90);
  EXPECT_EQ(j[4], 0);
  // C = 90: (-9, -18, -27) turned about Z: (18, -9, -27); plus r.
  ASSERT_EQ(k.inverse(make_pose(1, 2, 3, 0, 0, 90), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 28, 1e-12);
  EXPECT_NEAR(j[1], 11, 1e-12);
  EXPECT_NEAR(j[2], 3, 1e-12);
  // Tool 10, A = 90: the tip (1, 2, -7) lands at (1, 59, 4); the slides
  // carry the gauge point 10 above it.
  p.tool_offset.set(10);
  ASSERT_EQ(k.inverse(make_pose(1, 2, 3, 90, 0, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 1, 1e-12);
  EXPECT_NEAR(j[1], 59, 1e-12);
  EXPECT_NEAR(j[2], 14, 1e-12);
  Pose back;
  ASSERT_EQ(k.forward(j, back), KinResult::Ok);
  EXPECT_LT(max_error(back, make_pose(1, 2, 3, 90, 0, 0)), 1e-12) << pose_text(back);
}

TEST(TableTableKins, XyzbcKnownPose) {
  TableTableKins k("xyzbc-trt-kins", TiltAxis::B, map("XYZBC"));
  auto& p = k.params();
  p.x_rot_point.set(10);
  p.y_rot_point.set(20);
  p.z_rot_point.set(30);
  p.x_offset.set(4);
  p.z_offset.set(-3);
  double j[5];
  // B = 90: (-9, -18, -27) - (4, 0, -3) = (-13, -18, -24); turned about Y:
  // (x, y, z) -> (z, y, -x) = (-24, -18, 13); plus r + d (14, 20, 27).
  ASSERT_EQ(k.inverse(make_pose(1, 2, 3, 0, 90, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], -10, 1e-12);
  EXPECT_NEAR(j[1], 2, 1e-12);
  EXPECT_NEAR(j[2], 40, 1e-12);
  EXPECT_EQ(j[3], 90);
}

TEST(HeadTableKins, KnownPoses) {
  HeadTableKins k("headtable-kins", TiltAxis::B, map("XYZBC"));
  k.params().x_rot_point.set(5);
  k.params().pivot_length.set(100);
  k.params().tool_offset.set(20);
  double j[5];
  // B = 90: tip (10, 0, 30); the tool lies along +X, the tilt axis 120 from
  // the tip at (130, 0, 30), the gauge point reference 100 below it.
  ASSERT_EQ(k.inverse(make_pose(10, 0, 50, 0, 90, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 130, 1e-12);
  EXPECT_NEAR(j[1], 0, 1e-12);
  EXPECT_NEAR(j[2], -70, 1e-12);
  // C = 90 about (5, 0): tip (10, 0, 30) -> (5, 5, 30); head upright: +20.
  ASSERT_EQ(k.inverse(make_pose(10, 0, 50, 0, 0, 90), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 5, 1e-12);
  EXPECT_NEAR(j[1], 5, 1e-12);
  EXPECT_NEAR(j[2], 50, 1e-12);

  HeadTableKins ka("headtable-kins", TiltAxis::A, map("XYZAC"));
  ka.params().pivot_length.set(100);
  ka.params().tool_offset.set(20);
  // A = 90 about X: the tool axis turns from +Z to -Y.
  ASSERT_EQ(ka.inverse(make_pose(0, 0, 20, 90, 0, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 0, 1e-12);
  EXPECT_NEAR(j[1], -120, 1e-12);
  EXPECT_NEAR(j[2], -100, 1e-12);
}

TEST(FiveAxis, AtZeroAnglesTheyActLikeAThreeAxisMillWithToolLength) {
  TableTableKins trt("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  apply(trt, TrtGeometry{});
  HeadTableKins ht("headtable-kins", TiltAxis::B, map("XYZBC"));
  apply(ht, HeadGeometry{});
  double j[5];
  ASSERT_EQ(trt.inverse(make_pose(1, 2, 3, 0, 0, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[0], 1, 1e-12);
  EXPECT_NEAR(j[1], 2, 1e-12);
  EXPECT_NEAR(j[2], 3, 1e-12) << "the pose already carries the tool length (G43)";
  ASSERT_EQ(ht.inverse(make_pose(1, 2, 3, 0, 0, 0), nullptr, j), KinResult::Ok);
  EXPECT_NEAR(j[2], 3, 1e-12);
}

// ---- round trips ----

namespace {

template <class K>
void round_trip(K& k, Rng& rng, int samples, int tilt_index, double tilt_range) {
  const int n = k.num_joints();
  for (int i = 0; i < samples; ++i) {
    Pose p = make_pose(rng.uniform(-300, 300), rng.uniform(-300, 300), rng.uniform(-200, 200), 0, 0,
                       rng.uniform(-720, 720));
    p[tilt_index] = rng.uniform(-tilt_range, tilt_range);
    double j[kMaxJoints];
    ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
    Pose back;
    ASSERT_EQ(k.forward(j, back), KinResult::Ok);
    ASSERT_LT(max_error(back, p), 1e-9) << "sample " << i << ": " << pose_text(p) << " -> " << pose_text(back);
    // And from the joint side.
    double j2[kMaxJoints];
    ASSERT_EQ(k.inverse(back, j, j2), KinResult::Ok);
    for (int m = 0; m < n; ++m) ASSERT_NEAR(j2[m], j[m], 1e-9) << "sample " << i << " joint " << m;
  }
}

}  // namespace

TEST(TableTableKins, RandomRoundTripsAreExact) {
  Rng rng(0x5A17);
  TableTableKins ac("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  apply(ac, TrtGeometry{});
  round_trip(ac, rng, 20000, static_cast<int>(Axis::A), 120);
  TrtGeometry gb;
  gb.d = Vector3d(-6.0, 0.0, -35.0);
  TableTableKins bc("xyzbc-trt-kins", TiltAxis::B, map("XYZBC"));
  apply(bc, gb);
  round_trip(bc, rng, 20000, static_cast<int>(Axis::B), 120);
}

TEST(HeadTableKins, RandomRoundTripsAreExact) {
  Rng rng(0xBEAD);
  HeadTableKins b("headtable-kins", TiltAxis::B, map("XYZBC"));
  apply(b, HeadGeometry{});
  round_trip(b, rng, 20000, static_cast<int>(Axis::B), 110);
  HeadTableKins a("headtable-kins", TiltAxis::A, map("XYZAC"));
  apply(a, HeadGeometry{});
  round_trip(a, rng, 20000, static_cast<int>(Axis::A), 110);
}

TEST(TableTableKins, GantryAndExtraLettersFollowTheJointMap) {
  TableTableKins k("xyzac-trt-kins", TiltAxis::A, map("XYYZACW"));
  apply(k, TrtGeometry{});
  EXPECT_EQ(k.num_joints(), 7);
  EXPECT_EQ(k.joint_coordinate(2), 1);
  Pose p = make_pose(10, 20, 30, 25, 0, 40);
  p[Axis::W] = 7;
  double j[7];
  ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
  EXPECT_EQ(j[1], j[2]) << "both Y joints follow the computed Y";
  EXPECT_EQ(j[6], 7) << "W passes through";
  Pose back;
  ASSERT_EQ(k.forward(j, back), KinResult::Ok);
  EXPECT_LT(max_error(back, p), 1e-9);
}

// ---- tool-centre point ----

TEST(TableTableKins, ToolTipStaysOnTheWorkpiecePointWhileTheTableTurns) {
  Rng rng(0x7C9);
  const TrtGeometry g;
  for (TiltAxis tilt : {TiltAxis::A, TiltAxis::B}) {
    TableTableKins k(tilt == TiltAxis::A ? "xyzac-trt-kins" : "xyzbc-trt-kins", tilt,
                     map(tilt == TiltAxis::A ? "XYZAC" : "XYZBC"));
    apply(k, g);
    const int t = 3;  // the tilt joint, in XYZAC and XYZBC alike
    const Vector3d w(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-20, 20));
    double first[5] = {};
    for (int step = 0; step <= 90; ++step) {
      Pose p = make_pose(w.x(), w.y(), w.z() + g.tool, 0, 0, step * 4.0);
      p[tilt == TiltAxis::A ? Axis::A : Axis::B] = -45 + step;
      double j[5];
      ASSERT_EQ(k.inverse(p, nullptr, j), KinResult::Ok);
      const Vector3d tip = trt_tip_on_workpiece(g, tilt, j, t, 4);
      ASSERT_LT((tip - w).norm(), 1e-9) << "step " << step;
      // And the machine really moves the tip there.
      const Vector3d at = trt_machine_point(g, tilt, w, j[t], j[4]);
      ASSERT_LT((at - (Vector3d(j[0], j[1], j[2]) - Vector3d(0, 0, g.tool))).norm(), 1e-9);
      if (step == 0) std::copy(j, j + 5, first);
    }
    double last[5];
    Pose p = make_pose(w.x(), w.y(), w.z() + g.tool, 0, 0, 360);
    p[tilt == TiltAxis::A ? Axis::A : Axis::B] = 45;
    ASSERT_EQ(k.inverse(p, nullptr, last), KinResult::Ok);
    EXPECT_GT(std::hypot(last[0] - first[0], last[1] - first[1], last[2] - first[2]), 10.0)
        << "the slides move to follow the turning table";
  }
}

TEST(HeadTableKins, ToolTipStaysWhileTheHeadTilts) {
  const HeadGeometry g;
  HeadTableKins k("headtable-kins", TiltAxis::B, map("XYZBC"));
  apply(k, g);
  const Vector3d w(12, -8, 3);
  for (int step = 0; step <= 120; ++step) {
    double j[5];
    ASSERT_EQ(k.inverse(make_pose(w.x(), w.y(), w.z() + g.tool, 0, -60 + step, step * 3.0), nullptr, j),
              KinResult::Ok);
    ASSERT_LT((head_tip_on_workpiece(g, TiltAxis::B, j) - w).norm(), 1e-9) << "step " << step;
  }
}

// ---- a programmed 5-axis segment ----

// The kinematics half of "a 5-axis program segment run through coord mode
// keeps the tool tip on the programmed path": the planner's straight line in
// X Y Z A C, sampled every servo period, through inverse kinematics; the
// physical tool tip follows the programmed path at every sample and stays
// within a micrometre between samples when the joints are interpolated
// linearly (as the motion controller interpolates between coarse positions).
TEST(FiveAxisPath, ToolTipFollowsAProgrammedSegment) {
  const TrtGeometry g;
  TableTableKins k("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  apply(k, g);
  const Vector3d from(-40, 25, 10), to(60, -30, -5);
  const double a0 = -20, a1 = 35, c0 = 10, c1 = 200;
  const int samples = 2000;  // 2 s at 1 ms: 57 mm/s along the path, C at 95 deg/s
  double prev[5] = {};
  double worst_between = 0;
  for (int i = 0; i <= samples; ++i) {
    const double s = static_cast<double>(i) / samples;
    const Vector3d w = from + s * (to - from);
    const Pose p = make_pose(w.x(), w.y(), w.z() + g.tool, a0 + s * (a1 - a0), 0, c0 + s * (c1 - c0));
    double j[5];
    ASSERT_EQ(k.inverse(p, i > 0 ? prev : nullptr, j), KinResult::Ok);
    ASSERT_LT((trt_tip_on_workpiece(g, TiltAxis::A, j, 3, 4) - w).norm(), 1e-9) << "sample " << i;
    Pose fb;
    ASSERT_EQ(k.forward(j, fb), KinResult::Ok);
    ASSERT_LT(linear_error(fb, p), 1e-9) << "carte_pos_fb matches carte_pos_cmd";
    if (i > 0) {
      double mid[5];
      for (int m = 0; m < 5; ++m) mid[m] = 0.5 * (prev[m] + j[m]);
      const Vector3d w_mid = from + (s - 0.5 / samples) * (to - from);
      worst_between = std::max(worst_between, (trt_tip_on_workpiece(g, TiltAxis::A, mid, 3, 4) - w_mid).norm());
    }
    std::copy(j, j + 5, prev);
  }
  EXPECT_LT(worst_between, 1e-3) << "chord error of joint interpolation between 1 ms samples";
  EXPECT_GT(worst_between, 0.0) << "the check can fail: joint space is curved here";
}

// ---- identity switch ----

TEST(FiveAxis, SwitchToIdentityForSetupAndBack) {
  TableTableKins k("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  apply(k, TrtGeometry{});
  const Pose p = make_pose(10, 20, 30, 30, 0, 45);
  double tcp[5], id[5];
  ASSERT_EQ(k.inverse(p, nullptr, tcp), KinResult::Ok);
  ASSERT_TRUE(k.switch_to(1));
  ASSERT_EQ(k.inverse(p, nullptr, id), KinResult::Ok);
  EXPECT_EQ(id[0], 10);
  EXPECT_EQ(id[1], 20);
  EXPECT_EQ(id[2], 30);
  EXPECT_EQ(id[3], 30);
  EXPECT_EQ(id[4], 45);
  Pose back;
  ASSERT_EQ(k.forward(tcp, back), KinResult::Ok);
  EXPECT_EQ(back[Axis::X], tcp[0]) << "identity forward reads the joints";
  ASSERT_TRUE(k.switch_to(0));
  ASSERT_EQ(k.forward(tcp, back), KinResult::Ok);
  EXPECT_LT(max_error(back, p), 1e-9);
}

// ---- the same segment run through the motion controller in coord mode ----

namespace {

motion::MotionConfig trt_motion_config() {
  motion::MotionConfig c;
  c.num_joints = 5;
  c.servo_period_s = 0.001;
  c.max_linear_velocity = 200;
  c.max_linear_acceleration = 2000;
  c.max_linear_jerk = 50000;
  for (int j = 0; j < 5; ++j) {
    auto& jc = c.joints[static_cast<std::size_t>(j)];
    jc.type = j < 3 ? motion::JointType::Linear : motion::JointType::Angular;
    jc.min_limit = j == 4 ? -1000 : -500;
    jc.max_limit = j == 4 ? 1000 : 500;
    jc.max_velocity = j < 3 ? 500 : 720;
    jc.max_acceleration = 1e5;
    jc.max_jerk = 1e8;
    jc.ferror = jc.min_ferror = 10;
  }
  const int axes[5] = {0, 1, 2, 3, 5};  // X Y Z A C
  for (int i = 0; i < 5; ++i) {
    auto& ax = c.axes[static_cast<std::size_t>(axes[i])];
    ax.present = true;
    ax.min_limit = i == 4 ? -1000 : -500;
    ax.max_limit = i == 4 ? 1000 : 500;
    ax.max_velocity = i < 3 ? 100 : 180;
    ax.max_acceleration = i < 3 ? 1000 : 1800;
    ax.max_jerk = i < 3 ? 20000 : 36000;
  }
  return c;
}

}  // namespace

// "A 5-axis program segment run through coord mode keeps the tool tip on the
// programmed path": the motion controller with xyzac-trt-kins and the
// look-ahead planner; every servo period the joint commands it writes put
// the physical tool tip (the geometry above, not the module's formula) on
// the programmed straight line in workpiece coordinates.
TEST(FiveAxisCoordMode, ToolTipStaysOnTheProgrammedLineEveryServoPeriod) {
  const TrtGeometry g;
  TableTableKins k("xyzac-trt-kins", TiltAxis::A, map("XYZAC"));
  apply(k, g);
  const motion::MotionConfig cfg = trt_motion_config();
  auto planner = tp::make_planner(motion::planner_config(cfg, 0x1 | 0x2 | 0x4 | 0x8 | 0x20), tp::PlannerThreading::Inline);
  MessageQueue messages;
  motion::MotionController mc(cfg, k, *planner, &messages);
  uint64_t serial = 0;
  const auto accept = [&](motion::MotionCommand c) {
    c.serial = ++serial;
    motion::MotionResult r;
    ASSERT_TRUE(mc.handle(c, r));
    ASSERT_TRUE(r.accepted) << motion::to_string(c.type) << ": " << r.reason.c_str();
  };
  double joints[5] = {};
  const auto step = [&] {
    for (int j = 0; j < 5; ++j) mc.in().joints[static_cast<std::size_t>(j)].motor_pos_fb = joints[j];
    mc.update(cfg.servo_period_s);
    for (int j = 0; j < 5; ++j) joints[j] = mc.out().joints[static_cast<std::size_t>(j)].motor_pos_cmd;
  };
  const auto status = [&] {
    motion::MotionStatus s;
    mc.fill_status(s);
    return s;
  };
  motion::MotionCommand c;
  c.type = motion::Cmd::Enable;
  accept(c);
  for (int j = 0; j < 5; ++j) {
    c = {};
    c.type = motion::Cmd::Home;
    c.joint = static_cast<int16_t>(j);
    accept(c);
    for (int i = 0; i < 1000 && !status().joints[j].homed; ++i) step();
    ASSERT_TRUE(status().joints[j].homed) << "joint " << j;
  }
  c = {};
  c.type = motion::Cmd::Coord;
  accept(c);
  step();
  ASSERT_EQ(status().traj.mode, ipc::MotionMode::Coord);

  // From the pose the homed joints give to a far pose with A and C turning.
  const Pose start = status().traj.position;
  Pose end = start;
  end[Axis::X] += 60;
  end[Axis::Y] -= 30;
  end[Axis::Z] -= 15;
  end[Axis::A] = 35;
  end[Axis::C] = 200;
  c = {};
  c.type = motion::Cmd::SetLine;
  for (int a = 0; a < kNumAxes; ++a) c.end[a] = end[a];
  c.segment.feed = 50;
  c.segment.max_velocity = 100;
  c.segment.max_acceleration = 1000;
  c.segment.line = 7;
  accept(c);

  const Vector3d tip0 = Vector3d(start[Axis::X], start[Axis::Y], start[Axis::Z] - g.tool);
  const Vector3d tip1 = Vector3d(end[Axis::X], end[Axis::Y], end[Axis::Z] - g.tool);
  const Vector3d dir = (tip1 - tip0).normalized();
  double worst = 0, last_along = -1e-9;
  int samples = 0;
  bool moved = false;
  for (int i = 0; i < 60000; ++i) {
    step();
    const Vector3d tip = trt_tip_on_workpiece(g, TiltAxis::A, joints, 3, 4);
    const double along = (tip - tip0).dot(dir);
    worst = std::max(worst, (tip - tip0 - along * dir).norm());
    EXPECT_GE(along, last_along - 1e-9) << "the tip goes back along the line at sample " << i;
    last_along = along;
    ++samples;
    const auto s = status();
    moved = moved || s.traj.current_vel > 0;
    if (moved && s.traj.queue == 0 && s.traj.inpos && s.traj.current_vel == 0) break;
  }
  EXPECT_TRUE(moved);
  EXPECT_LT(worst, 1e-6) << "tool tip off the programmed line (mm), " << samples << " samples";
  EXPECT_LT((trt_tip_on_workpiece(g, TiltAxis::A, joints, 3, 4) - tip1).norm(), 1e-9) << "ends on the end point";
  EXPECT_NEAR(joints[3], 35, 1e-9);
  EXPECT_NEAR(joints[4], 200, 1e-9);
  Message m;
  while (messages.pop(m)) EXPECT_NE(m.kind, MessageKind::Error) << m.text.c_str();
}
