// Servo-cycle compute time of the motion controller: 9 joints (trivkins
// XYZABCUVW) in coord mode following a long program of short moves. Prints
// the median, p99.9 and maximum of the time one motion cycle takes
// (command handling and controller), measured per cycle. Never fails on a
// figure.
//   bench_motion [cycles=200000] [planner=simple|lookahead]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "core/motion/motion_controller.hpp"
#include "core/util/time.hpp"
#include "kinematics/trivkins.hpp"
#include "tests/core/motion/simple_planner.hpp"
#ifdef CNC_HAVE_TP
#include "core/tp/lookahead_planner.hpp"
#endif

using namespace cnc;

int main(int argc, char** argv) {
  const int cycles = argc > 1 ? std::atoi(argv[1]) : 200000;
  const bool lookahead = argc > 2 && std::strcmp(argv[2], "lookahead") == 0;
  motion::MotionConfig cfg;
  cfg.num_joints = 9;
  cfg.max_linear_velocity = 200;
  cfg.max_linear_acceleration = 2000;
  cfg.max_linear_jerk = 100000;
  for (int j = 0; j < 9; ++j) {
    auto& jc = cfg.joints[static_cast<std::size_t>(j)];
    jc.min_limit = -1000;
    jc.max_limit = 1000;
    jc.max_velocity = 200;
    jc.max_acceleration = 2000;
    jc.max_jerk = 100000;
    jc.ferror = 10;
    jc.min_ferror = 10;
    auto& ax = cfg.axes[static_cast<std::size_t>(j)];
    ax.present = true;
    ax.min_limit = -1000;
    ax.max_limit = 1000;
    ax.max_velocity = 200;
    ax.max_acceleration = 2000;
    ax.max_jerk = 100000;
  }
  kin::TrivKins kins(kin::JointMap::parse("XYZABCUVW", "bench", false), kin::KinematicsType::Identity);
  tp::PlannerConfig pc;
  pc.cycle_time_s = 0.001;
  pc.max_linear_velocity = 200;
  pc.max_linear_acceleration = 2000;
  pc.max_linear_jerk = 100000;
  pc.axis_mask = 0x1ff;
  for (auto& a : pc.axes) a = tp::AxisLimits{200, 2000, 100000};
  std::unique_ptr<tp::TrajectoryPlanner> planner;
#ifdef CNC_HAVE_TP
  if (lookahead) planner = tp::make_planner(pc, tp::PlannerThreading::Inline);
#endif
  if (!planner) planner = std::make_unique<testing::SimplePlanner>(pc);
  motion::MotionController mc(cfg, kins, *planner, nullptr);
  // A perfect drive: feedback is last cycle's command.
  auto feedback = [&] {
    for (int j = 0; j < 9; ++j) mc.in().joints[static_cast<std::size_t>(j)].motor_pos_fb = mc.out().joints[static_cast<std::size_t>(j)].motor_pos_cmd;
  };
  uint64_t serial = 0;
  auto send = [&](motion::MotionCommand c) {
    c.serial = ++serial;
    motion::MotionResult r;
    return mc.handle(c, r) && r.accepted;
  };
  motion::MotionCommand c;
  c.type = motion::Cmd::Enable;
  send(c);
  mc.update(0.001);
  for (int j = 0; j < 9; ++j) {
    c.type = motion::Cmd::Home;
    c.joint = static_cast<int16_t>(j);
    send(c);
  }
  for (int i = 0; i < 50; ++i) {
    feedback();
    mc.update(0.001);
  }
  c.type = motion::Cmd::Coord;
  if (!send(c)) {
    std::fprintf(stderr, "bench_motion: could not enter coord mode\n");
    return 1;
  }
  // Feed short moves (0.5 mm) on all nine axes, keeping the planner busy.
  std::vector<int64_t> times;
  times.reserve(static_cast<std::size_t>(cycles));
  double t = 0;
  uint32_t id = 1;
  for (int k = 0; k < cycles; ++k) {
    // the feed side (not timed): keep the queue topped up
    for (int n = 0; n < 4; ++n) {
      motion::MotionCommand s;
      s.type = motion::Cmd::SetLine;
      t += 0.01;
      for (int a = 0; a < 9; ++a) s.end[a] = 50 * std::sin(t + a);
      s.segment.feed = 150;
      s.segment.max_acceleration = 2000;
      s.segment.term = tp::TermCond::Blend;
      s.segment.tolerance = 0.01;
      s.segment.id = id++;
      s.serial = ++serial;
      motion::MotionResult r;
      if (!mc.handle(s, r)) {
        t -= 0.01;
        --id;
        break;
      }
      if (!r.accepted) {
        std::fprintf(stderr, "bench_motion: segment refused: %s\n", r.reason.c_str());
        return 1;
      }
    }
    feedback();
    const int64_t t0 = monotonic_ns();
    mc.update(0.001);
    times.push_back(monotonic_ns() - t0);
  }
  std::sort(times.begin(), times.end());
  const auto at = [&](double q) { return static_cast<double>(times[static_cast<std::size_t>(q * static_cast<double>(times.size() - 1))]) / 1e3; };
  std::printf("motion controller, 9 joints, coord mode, planner %s, %d cycles\n",
              lookahead ? "lookahead (inline)" : "simple (test)", cycles);
  std::printf("  cycle compute time: median %.2f us, p99 %.2f us, p99.9 %.2f us, max %.2f us\n", at(0.5), at(0.99),
              at(0.999), at(1.0));
  motion::MotionStatus s;
  mc.fill_status(s);
  std::printf("  (the planner's own work is included; final queue depth %d)\n", s.traj.queue);
  return 0;
}
