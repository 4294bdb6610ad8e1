// A deliberately simple coordinated-mode planner for the motion
// controller's tests: every segment is a jerk-limited move along its own
// path that stops at its end (exact stop). It implements the whole
// tp::TrajectoryPlanner interface (pause, resume, step, abort, probe,
// dwell, overrides) so that the motion controller can be tested apart from
// the real planner.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/motion/free_planner.hpp"
#include "core/tp/planner.hpp"

namespace cnc::testing {

class SimplePlanner : public tp::TrajectoryPlanner {
 public:
  explicit SimplePlanner(const tp::PlannerConfig& c) : cfg_(c) {}

  void set_position(const Pose& p) noexcept override { reset(p); }
  void reset(const Pose& p) noexcept override {
    pos_ = end_ = p;
    count_ = 0;
    active_ = paused_ = stepping_ = aborting_ = false;
    s_.reset(0);
  }
  tp::Result add_line(const Pose& end, const tp::SegmentParams& p) noexcept override {
    Seg s;
    s.kind = Seg::Line;
    s.end = end;
    s.p = p;
    return push(s);
  }
  tp::Result add_circle(const Pose& end, const std::array<double, 3>& c, const std::array<double, 3>& n, int turns,
                        const tp::SegmentParams& p) noexcept override {
    Seg s;
    s.kind = Seg::Arc;
    s.end = end;
    s.center = c;
    s.normal = n;
    s.turns = turns;
    s.p = p;
    return push(s);
  }
  tp::Result add_dwell(double seconds, const tp::SegmentParams& p) noexcept override {
    Seg s;
    s.kind = Seg::Dwell;
    s.dwell = seconds;
    s.p = p;
    return push(s);
  }

  void run_cycle(const tp::CycleInputs& in, tp::CycleOutputs& out) noexcept override {
    const double dt = cfg_.cycle_time_s;
    out.probe_tripped = false;
    out.waiting_for_spindle = false;
    if (!active_ && count_ > 0 && !aborting_) start_front();
    if (active_) {
      Seg& s = q_[head_];
      if (s.kind == Seg::Dwell) {
        if (!paused_) s.dwell -= dt;
        out.waiting_for_spindle = s.dwell <= 0 && s.p.wait_spindle_at_speed && !in.spindles_at_speed && !aborting_;
        if (s.dwell <= 0 && !out.waiting_for_spindle) finish_front();
      } else {
        const double scale = s.p.type == tp::MotionType::Traverse ? in.rapid_scale : in.feed_scale;
        double v = std::min({s.p.feed * scale, s.p.max_velocity > 0 ? s.p.max_velocity : 1e300, in.max_velocity,
                             cfg_.max_linear_velocity});
        if (paused_ || aborting_ || v <= 0) {
          s_.stop();
        } else {
          s_.set_target(s.length, motion::FreeLimits{v, acc_, acc_ * 50});
        }
        s_.update(dt);
        pos_ = point_at(s, s_.position());
        if (s.p.type == tp::MotionType::Probe && in.probe_input && !probe_hit_) {
          probe_hit_ = true;
          out.probe_tripped = true;
          out.probed_position = pos_;
          aborting_ = true;
        }
        if (s_.done() && aborting_) {
          count_ = 0;
          active_ = false;
          aborting_ = false;
          end_ = pos_;
        } else if (s_.done() && s_.position() >= s.length) {
          pos_ = s.end;
          finish_front();
        }
        out.path_velocity = std::fabs(s_.velocity());
      }
    } else if (aborting_) {
      // An abort while a dwell ended: nothing queued behind it runs.
      count_ = 0;
      aborting_ = false;
      end_ = pos_;
    }
    out.position = pos_;
    out.move_end = active_ ? q_[head_].end : pos_;
    out.distance_to_go = active_ ? std::max(0.0, q_[head_].length - s_.position()) : 0;
    out.done = count_ == 0 && !active_;
    out.line = active_ ? q_[head_].p.line : last_line_;
    out.id = active_ ? q_[head_].p.id : last_id_;
    out.tag = active_ ? q_[head_].p.tag : last_tag_;
    if (out.done) out.path_velocity = 0;
  }

  void pause() noexcept override { paused_ = true; }
  void resume() noexcept override { paused_ = false; stepping_ = false; }
  void step() noexcept override {
    if (paused_) {
      paused_ = false;
      stepping_ = true;
    }
  }
  void abort() noexcept override {
    if (count_ > 0 || active_) aborting_ = true;
    if (!active_) {
      count_ = 0;
      aborting_ = false;
    }
  }
  bool is_done() const noexcept override { return count_ == 0 && !active_; }
  bool is_paused() const noexcept override { return paused_; }
  int queue_depth() const noexcept override { return count_; }
  bool is_queue_full() const noexcept override { return count_ == kCapacity; }
  void set_config(const tp::PlannerConfig& c) noexcept override { cfg_ = c; }

 private:
  static constexpr int kCapacity = 64;
  struct Seg {
    enum Kind { Line, Arc, Dwell } kind = Line;
    Pose start, end;
    std::array<double, 3> center{}, normal{};
    int turns = 0;
    double dwell = 0, length = 0;
    double radius = 0, sweep = 0, axial = 0, base_n = 0;
    std::array<double, 3> r0{}, r0perp{};
    tp::SegmentParams p;
  };

  tp::Result push(Seg s) noexcept {
    if (count_ == kCapacity) return tp::Result::QueueFull;
    s.start = end_;
    if (s.kind == Seg::Line) {
      double l2 = 0;
      for (int a = 0; a < kNumAxes; ++a) l2 += (s.end[a] - s.start[a]) * (s.end[a] - s.start[a]);
      s.length = std::sqrt(l2);
    } else if (s.kind == Seg::Arc) {
      const auto& n = s.normal;
      double r[3], e[3];
      for (int i = 0; i < 3; ++i) {
        r[i] = s.start[i] - s.center[i];
        e[i] = s.end[i] - s.center[i];
      }
      const double rn = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
      const double en = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
      for (int i = 0; i < 3; ++i) {
        r[i] -= rn * n[i];
        e[i] -= en * n[i];
      }
      s.radius = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      if (s.radius < 1e-12) return tp::Result::InvalidSegment;
      for (int i = 0; i < 3; ++i) s.r0[i] = r[i];
      s.r0perp = {n[1] * r[2] - n[2] * r[1], n[2] * r[0] - n[0] * r[2], n[0] * r[1] - n[1] * r[0]};
      double ang = std::atan2(e[0] * s.r0perp[0] + e[1] * s.r0perp[1] + e[2] * s.r0perp[2],
                              e[0] * r[0] + e[1] * r[1] + e[2] * r[2]);
      if (ang <= 1e-12) ang += 2 * M_PI;
      s.sweep = ang + 2 * M_PI * s.turns;
      s.axial = en - rn;
      s.base_n = rn;
      s.length = std::hypot(s.radius * s.sweep, s.axial);
    }
    q_[(head_ + count_) % kCapacity] = s;
    ++count_;
    if (s.kind != Seg::Dwell) end_ = s.end;
    return tp::Result::Ok;
  }

  Pose point_at(const Seg& s, double d) const noexcept {
    const double f = s.length > 0 ? std::clamp(d / s.length, 0.0, 1.0) : 1.0;
    Pose p;
    for (int a = 0; a < kNumAxes; ++a) p[a] = s.start[a] + (s.end[a] - s.start[a]) * f;
    if (s.kind == Seg::Arc) {
      const double phi = s.sweep * f;
      for (int i = 0; i < 3; ++i) {
        p[i] = s.center[i] + s.r0[i] * std::cos(phi) + s.r0perp[i] * std::sin(phi) + s.normal[i] * (s.base_n + s.axial * f);
      }
    }
    return p;
  }

  void start_front() noexcept {
    Seg& s = q_[head_];
    s.start = pos_;
    active_ = true;
    probe_hit_ = false;
    s_.reset(0);
    acc_ = s.p.max_acceleration > 0 ? s.p.max_acceleration : cfg_.max_linear_acceleration;
    if (acc_ > 1e90) acc_ = 1000;
  }
  void finish_front() noexcept {
    last_line_ = q_[head_].p.line;
    last_id_ = q_[head_].p.id;
    last_tag_ = q_[head_].p.tag;
    head_ = (head_ + 1) % kCapacity;
    --count_;
    active_ = false;
    if (stepping_) {
      stepping_ = false;
      paused_ = true;
    }
  }

  tp::PlannerConfig cfg_;
  Seg q_[kCapacity];
  int head_ = 0, count_ = 0;
  bool active_ = false, paused_ = false, stepping_ = false, aborting_ = false, probe_hit_ = false;
  Pose pos_, end_;
  motion::FreePlanner s_;
  double acc_ = 1000;
  int32_t last_line_ = 0;
  uint32_t last_id_ = 0;
  tp::StateTag last_tag_;
};

}  // namespace cnc::testing
