// A simulated machine around a MotionController for tests: joints whose
// feedback follows the motor command one cycle late, home switches, limit
// switches and index pulses at physical positions, and helpers to send
// commands and read the error channel.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/motion/motion_controller.hpp"
#include "core/util/messages.hpp"
#include "kinematics/trivkins.hpp"
#include "tests/core/motion/simple_planner.hpp"

namespace cnc::testing {

struct SimJoint {
  double pos = 0;                      // physical = motor position
  double home_min = 1e99, home_max = 1e99;
  double pos_lim = 1e99, neg_lim = -1e99;
  double index_spacing = 0, index_offset = 0;
  bool index_enable = false;
  double index_position = 0;
  double lag = 0;                      // extra first-order lag factor per cycle (0: exact)
  bool amp_fault = false;
  // Cycles with amp-enable-out before the amplifier says ready and follows
  // (0: at once, as an unconnected joint.N.amp-ready-in; -1: never).
  int ready_after = 0;
  int enabled_cycles = 0;
  bool ready() const { return ready_after == 0 || (ready_after > 0 && enabled_cycles >= ready_after); }
};

inline motion::MotionConfig basic_config(int joints = 3) {
  motion::MotionConfig c;
  c.num_joints = joints;
  c.servo_period_s = 0.001;
  c.max_linear_velocity = 100;
  c.max_linear_acceleration = 1000;
  for (int j = 0; j < joints; ++j) {
    auto& jc = c.joints[static_cast<std::size_t>(j)];
    jc.min_limit = -10;
    jc.max_limit = 200;
    jc.max_velocity = 100;
    jc.max_acceleration = 1000;
    jc.max_jerk = 50000;
    jc.ferror = 1;
    jc.min_ferror = 0.5;
  }
  for (int a = 0; a < 3; ++a) {
    auto& ax = c.axes[static_cast<std::size_t>(a)];
    ax.present = true;
    ax.min_limit = -10;
    ax.max_limit = 200;
    ax.max_velocity = 100;
    ax.max_acceleration = 1000;
    ax.max_jerk = 50000;
  }
  c.comp_reserve = 0.05;
  return c;
}

class Machine {
 public:
  // Makes the coordinated planner (default: the exact-stop SimplePlanner).
  using PlannerMaker = std::function<std::unique_ptr<tp::TrajectoryPlanner>(const tp::PlannerConfig&)>;

  explicit Machine(motion::MotionConfig cfg = basic_config(), const char* coordinates = "XYZ",
                   const PlannerMaker& make_planner = nullptr)
      : cfg_(cfg),
        kins_(kin::JointMap::parse(coordinates, "test", true), kin::KinematicsType::Identity),
        tp_(make_planner ? make_planner(motion::planner_config(cfg, 0x7))
                         : std::make_unique<SimplePlanner>(motion::planner_config(cfg, 0x7))),
        mc_(cfg_, kins_, *tp_, &messages_) {
    sims.resize(static_cast<std::size_t>(cfg.num_joints));
  }

  std::vector<SimJoint> sims;

  motion::MotionController& mc() { return mc_; }
  const motion::MotionOutputs& out() const { return mc_.out(); }
  const motion::JointOutputs& joint(int j) const { return mc_.out().joints[static_cast<std::size_t>(j)]; }
  motion::MotionStatus status() const {
    motion::MotionStatus s;
    mc_.fill_status(s);
    return s;
  }

  void step(int n = 1) {
    for (int k = 0; k < n; ++k) {
      auto& in = mc_.in();
      for (int j = 0; j < cfg_.num_joints; ++j) {
        SimJoint& s = sims[static_cast<std::size_t>(j)];
        auto& ji = in.joints[static_cast<std::size_t>(j)];
        ji.motor_pos_fb = s.pos;
        ji.home_sw = s.pos >= s.home_min && s.pos <= s.home_max;
        ji.pos_lim_sw = s.pos >= s.pos_lim;
        ji.neg_lim_sw = s.pos <= s.neg_lim;
        ji.index_enable = s.index_enable;
        ji.index_position = s.index_position;
        ji.amp_fault = s.amp_fault;
        ji.amp_ready = s.ready();
      }
      mc_.update(cfg_.servo_period_s);
      ++cycles;
      for (int j = 0; j < cfg_.num_joints; ++j) {
        SimJoint& s = sims[static_cast<std::size_t>(j)];
        const auto& jo = joint(j);
        if (jo.index_enable_write >= 0) s.index_enable = jo.index_enable_write != 0;
        s.enabled_cycles = jo.amp_enable ? s.enabled_cycles + 1 : 0;
        if (!jo.amp_enable || !s.ready()) continue;
        const double before = s.pos;
        s.pos = s.lag > 0 ? s.pos + (jo.motor_pos_cmd - s.pos) * (1 - s.lag) : jo.motor_pos_cmd;
        if (s.index_enable && s.index_spacing > 0) {
          const double k0 = std::floor((before - s.index_offset) / s.index_spacing);
          const double k1 = std::floor((s.pos - s.index_offset) / s.index_spacing);
          if (k0 != k1) {
            s.index_position = s.index_offset + (s.pos > before ? k1 : k0) * s.index_spacing;
            s.index_enable = false;
          }
        }
      }
    }
  }

  // Steps until pred() or max cycles; returns whether pred() became true.
  template <class Pred>
  bool run_until(Pred pred, int max_cycles = 100000) {
    step();  // status reflects a cycle after the last command
    for (int i = 0; i < max_cycles; ++i) {
      if (pred()) return true;
      step();
    }
    return pred();
  }

  motion::MotionResult send(motion::MotionCommand c) {
    c.serial = ++serial_;
    motion::MotionResult r;
    EXPECT_TRUE(mc_.handle(c, r)) << "command not taken";
    return r;
  }
  motion::MotionResult send(motion::Cmd type, int joint = 0, double v0 = 0, double v1 = 0) {
    motion::MotionCommand c;
    c.type = type;
    c.joint = static_cast<int16_t>(joint);
    c.value[0] = v0;
    c.value[1] = v1;
    return send(c);
  }
  void accept(motion::Cmd type, int joint = 0, double v0 = 0, double v1 = 0) {
    const auto r = send(type, joint, v0, v1);
    ASSERT_TRUE(r.accepted) << motion::to_string(type) << ": " << r.reason.c_str();
  }
  motion::MotionResult line(double x, double y, double z, double feed, int line_no = 1) {
    motion::MotionCommand c;
    c.type = motion::Cmd::SetLine;
    c.end[0] = x;
    c.end[1] = y;
    c.end[2] = z;
    c.segment.feed = feed;
    c.segment.line = line_no;
    c.segment.max_acceleration = 1000;
    return send(c);
  }

  // Enable, home all joints immediately (no switches) and enter coord mode.
  void enable_home_coord() {
    accept(motion::Cmd::Enable);
    for (int j = 0; j < cfg_.num_joints; ++j) {
      accept(motion::Cmd::Home, j);
      ASSERT_TRUE(run_until([&] { return status().joints[j].homed; }, 20000)) << "joint " << j;
    }
    accept(motion::Cmd::Coord);
  }

  std::vector<std::string> errors() {
    std::vector<std::string> out;
    Message m;
    while (messages_.pop(m)) {
      if (m.kind == MessageKind::Error) out.emplace_back(m.text.c_str());
    }
    return out;
  }
  // Every message posted so far, any kind, one per line (consumes them).
  std::string all_messages() {
    std::string s;
    Message m;
    while (messages_.pop(m)) s += std::string(m.text.c_str()) + "\n";
    return s;
  }
  std::string all_errors() {
    std::string s;
    for (const auto& e : errors()) s += e + "\n";
    return s;
  }

  uint64_t cycles = 0;

 private:
  motion::MotionConfig cfg_;
  kin::TrivKins kins_;
  std::unique_ptr<tp::TrajectoryPlanner> tp_;
  MessageQueue messages_;
  motion::MotionController mc_;
  uint64_t serial_ = 0;
};

}  // namespace cnc::testing
