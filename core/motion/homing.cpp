// Homing (the manual's 3.7 and LinuxCNC's HOME_* parameters), part of the
// motion controller: one state machine per joint, sequences for "home all",
// synchronised groups (negative HOME_SEQUENCE, e.g. the two joints of a
// gantry) that finish with one coordinated final move, and homing by the
// drive itself (HOME_MODE = DRIVE). Runs in the servo thread.
#include <algorithm>
#include <cmath>

#include "core/motion/motion_controller.hpp"

namespace cnc::motion {
namespace {
double sign_of(double v) { return v < 0 ? -1.0 : 1.0; }
}  // namespace

void MotionController::latch_home(int j, double joint_pos_at_latch) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const double delta = cfg_.joints[static_cast<std::size_t>(j)].homing.offset - joint_pos_at_latch;
  // Relabel the joint so that the latch point reads HOME_OFFSET: command and
  // feedback move together and the motor command does not jump.
  jt.motor_offset -= delta;
  jt.pos_fb += delta;
  jt.pos_cmd += delta;
  jt.free.shift(delta);
  out_.joints[static_cast<std::size_t>(j)].pos_cmd += delta;  // keeps vel_cmd continuous
}

void MotionController::abort_homing(int j, const char* why) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  if (jt.home_state == HomeState::Idle) return;
  jt.home_state = HomeState::Idle;
  jt.homed = false;
  jt.stopping = false;
  jt.free.stop();
  if (jt.index_armed) out_.joints[static_cast<std::size_t>(j)].index_enable_write = 0;
  jt.index_armed = false;
  jt.drive_home_request = false;
  jt.unlock_request = false;
  if (why) post_error("joint %d: homing failed: %s", j, why);
  if (home_all_) {
    // One joint failing stops the whole home-all sequence.
    home_all_ = false;
    home_sequence_ = -1;
    for (int k = 0; k < cfg_.num_joints; ++k) {
      if (k != j && joints_[static_cast<std::size_t>(k)].home_state != HomeState::Idle) abort_homing(k, nullptr);
    }
  } else if (joint_in_sync_group(j)) {
    const int seq = cfg_.joints[static_cast<std::size_t>(j)].homing.sequence;
    for (int k = 0; k < cfg_.num_joints; ++k) {
      if (k != j && cfg_.joints[static_cast<std::size_t>(k)].homing.sequence == seq) abort_homing(k, nullptr);
    }
  }
}

void MotionController::finish_joint_home(int j) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  jt.home_state = HomeState::Idle;
  jt.homed = true;
  jt.stopping = false;
  jt.unlock_request = false;
}

void MotionController::enter_home_state(int j, HomeState state) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
  const double span = search_span(j);
  const double dir = sign_of(h.search_vel);
  const double latch_dir = sign_of(h.latch_vel);
  jt.home_state = state;
  switch (state) {
    case HomeState::InitialBackoff:
    case HomeState::FinalBackoff:
      jt.free.set_target(jt.pos_cmd - dir * span, joint_limits(j, h.search_vel * feed_scale_));
      break;
    case HomeState::InitialSearch:
      jt.free.set_target(jt.pos_cmd + dir * span, joint_limits(j, h.search_vel * feed_scale_));
      break;
    case HomeState::RiseSearch:
    case HomeState::FallSearch:
      jt.free.set_target(jt.pos_cmd + latch_dir * span, joint_limits(j, h.latch_vel * feed_scale_));
      break;
    case HomeState::FinalMove:
      start_final_move(j);
      break;
    default:
      break;
  }
}

void MotionController::stop_then(int j, HomeState state) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  jt.free.stop();
  jt.stopping = true;
  jt.next_state = state;
}

void MotionController::begin_search(int j) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
  if (h.search_vel == 0) {
    if (h.latch_vel == 0) {
      // Immediate homing: where the joint is now is HOME_OFFSET.
      latch_home(j, jt.pos_fb);
      jt.home_state = HomeState::StopAfterLatch;
      return;
    }
    // Index only: arm the index and move at the latch velocity.
    out_.joints[static_cast<std::size_t>(j)].index_enable_write = 1;
    jt.index_armed = true;
    jt.free.set_target(jt.pos_cmd + sign_of(h.latch_vel) * search_span(j), joint_limits(j, h.latch_vel * feed_scale_));
    jt.home_state = HomeState::IndexSearch;
    return;
  }
  enter_home_state(j, in_.joints[static_cast<std::size_t>(j)].home_sw ? HomeState::InitialBackoff : HomeState::InitialSearch);
}

void MotionController::on_latch_event(int j) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
  if (h.use_index) {
    out_.joints[static_cast<std::size_t>(j)].index_enable_write = 1;
    jt.index_armed = true;
    jt.home_state = HomeState::IndexSearch;  // keep moving at the latch velocity
    return;
  }
  latch_home(j, jt.pos_fb);
  jt.free.stop();
  jt.home_state = HomeState::StopAfterLatch;
}

void MotionController::start_final_move(int j) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
  const double vel = c.homing.final_vel > 0 ? c.homing.final_vel : c.max_velocity;
  jt.free.set_target(c.homing.home, joint_limits(j, vel * feed_scale_));
  jt.home_state = HomeState::FinalMove;
}

void MotionController::home_step(int j, double /*dt*/) noexcept {
  Joint& jt = joints_[static_cast<std::size_t>(j)];
  const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
  const JointInputs& in = in_.joints[static_cast<std::size_t>(j)];
  // A state that saw its event waits for the joint to stop before the next.
  if (jt.stopping) {
    if (!jt.free.done()) return;
    jt.stopping = false;
    enter_home_state(j, jt.next_state);
    return;
  }
  switch (jt.home_state) {
    case HomeState::Idle:
    case HomeState::Finished:
      return;
    case HomeState::Start:
      if (h.mode == HomeMode::Drive) {
        jt.drive_home_request = true;
        jt.home_state = HomeState::DriveHoming;
      } else if (h.locking_indexer) {
        jt.unlock_request = true;
        jt.home_state = HomeState::UnlockWait;
      } else {
        begin_search(j);
      }
      return;
    case HomeState::UnlockWait:
      if (in.is_unlocked) begin_search(j);
      return;
    case HomeState::InitialBackoff:
      if (!in.home_sw) stop_then(j, HomeState::InitialSearch);
      else if (jt.free.done()) abort_homing(j, "the home switch did not release within the travel");
      return;
    case HomeState::InitialSearch:
      // Latch on the approach (latch velocity of the same sign): back off
      // first. Latch on release (opposite sign): move off the switch slowly.
      if (in.home_sw) stop_then(j, sign_of(h.latch_vel) == sign_of(h.search_vel) ? HomeState::FinalBackoff : HomeState::FallSearch);
      else if (jt.free.done()) abort_homing(j, "the home switch was not found within the travel");
      return;
    case HomeState::FinalBackoff:
      if (!in.home_sw) stop_then(j, HomeState::RiseSearch);
      else if (jt.free.done()) abort_homing(j, "the home switch did not release while backing off");
      return;
    case HomeState::RiseSearch:
      if (in.home_sw) on_latch_event(j);
      else if (jt.free.done()) abort_homing(j, "the home switch was not found at the latch velocity");
      return;
    case HomeState::FallSearch:
      if (!in.home_sw) on_latch_event(j);
      else if (jt.free.done()) abort_homing(j, "the home switch did not release at the latch velocity");
      return;
    case HomeState::IndexSearch:
      if (jt.index_armed && !in.index_enable) {
        // The feedback device cleared index-enable and latched where the
        // index was: that point becomes HOME_OFFSET exactly.
        jt.index_armed = false;
        latch_home(j, in.index_position - jt.motor_offset - jt.backlash_filt - jt.screw_comp);
        jt.free.stop();
        jt.home_state = HomeState::StopAfterLatch;
      } else if (jt.free.done()) {
        abort_homing(j, "no index pulse was seen");
      }
      return;
    case HomeState::StopAfterLatch:
      if (!jt.free.done()) return;
      if (joint_in_sync_group(j)) jt.home_state = HomeState::WaitGroup;
      else start_final_move(j);
      return;
    case HomeState::WaitGroup:
      return;  // run_sync_groups starts the group's final move
    case HomeState::FinalMove:
      if (joint_in_sync_group(j) || !jt.free.done()) return;
      if (h.locking_indexer) {
        jt.unlock_request = false;
        jt.home_state = HomeState::LockWait;
      } else {
        finish_joint_home(j);
      }
      return;
    case HomeState::LockWait:
      if (!in.is_unlocked) finish_joint_home(j);
      return;
    case HomeState::DriveHoming:
      if (in.drive_home_error) {
        abort_homing(j, "the drive reported a homing error");
      } else if (in.drive_home_done && !in.drive_home_busy) {
        // The drive has set its own position so that its reference reads
        // HOME_OFFSET; the command resumes from the feedback, no jump.
        jt.drive_home_request = false;
        jt.motor_offset = 0;
        jt.pos_fb = in.motor_pos_fb - jt.backlash_filt - jt.screw_comp;
        jt.pos_cmd = jt.pos_fb;
        out_.joints[static_cast<std::size_t>(j)].pos_cmd = jt.pos_fb;
        jt.free.reset(jt.pos_fb);
        jt.home_state = HomeState::StopAfterLatch;
      }
      return;
  }
}

void MotionController::run_sync_groups(double dt) noexcept {
  for (int g = 1; g <= max_sequence_; ++g) {
    int members = 0, waiting = 0, moving = 0;
    for (int j = 0; j < cfg_.num_joints; ++j) {
      const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
      if (!h.has_sequence || h.sequence != -g) continue;
      const HomeState st = joints_[static_cast<std::size_t>(j)].home_state;
      if (st == HomeState::Idle) continue;
      ++members;
      waiting += st == HomeState::WaitGroup ? 1 : 0;
      moving += st == HomeState::FinalMove ? 1 : 0;
    }
    if (members == 0) continue;
    FreePlanner& gp = group_planner_[static_cast<std::size_t>(g)];
    if (waiting == members) {
      // Every joint of the group has latched: one final move in lock-step,
      // progress s from 0 to 1, limited by the most constrained joint.
      FreeLimits l{1e300, 1e300, 1e300};
      for (int j = 0; j < cfg_.num_joints; ++j) {
        const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
        if (!c.homing.has_sequence || c.homing.sequence != -g) continue;
        Joint& jt = joints_[static_cast<std::size_t>(j)];
        group_start_[static_cast<std::size_t>(j)] = jt.pos_cmd;
        const double d = std::fabs(c.homing.home - jt.pos_cmd);
        if (d > 1e-12) {
          const FreeLimits jl = joint_limits(j, (c.homing.final_vel > 0 ? c.homing.final_vel : c.max_velocity) * feed_scale_);
          l.max_velocity = std::min(l.max_velocity, jl.max_velocity / d);
          l.max_acceleration = std::min(l.max_acceleration, jl.max_acceleration / d);
          l.max_jerk = std::min(l.max_jerk, jl.max_jerk / d);
        }
        jt.home_state = HomeState::FinalMove;
      }
      gp.reset(0);
      if (l.max_velocity < 1e299) gp.set_target(1, l);
      moving = members;
    }
    if (moving == members) {
      const double s = gp.enabled() ? gp.update(dt) : 1.0;
      const bool done = !gp.enabled() || gp.done();
      for (int j = 0; j < cfg_.num_joints; ++j) {
        const JointConfig& c = cfg_.joints[static_cast<std::size_t>(j)];
        if (!c.homing.has_sequence || c.homing.sequence != -g) continue;
        Joint& jt = joints_[static_cast<std::size_t>(j)];
        if (jt.home_state != HomeState::FinalMove) continue;
        const double start = group_start_[static_cast<std::size_t>(j)];
        jt.pos_cmd = done ? c.homing.home : start + s * (c.homing.home - start);
        jt.free.reset(jt.pos_cmd);
        if (done) finish_joint_home(j);
      }
    }
  }
}

void MotionController::run_homing(double dt) noexcept {
  bool any = false;
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (joints_[static_cast<std::size_t>(j)].home_state == HomeState::Idle) continue;
    any = true;
    home_step(j, dt);
  }
  if (any) run_sync_groups(dt);
  if (!home_all_) {
    if (!any) home_sequence_ = -1;
    return;
  }
  // Home all: the next sequence starts when every joint of this one is done.
  for (int j = 0; j < cfg_.num_joints; ++j) {
    if (joints_[static_cast<std::size_t>(j)].home_state != HomeState::Idle) return;
  }
  for (int next = home_sequence_ + 1; next <= max_sequence_; ++next) {
    bool members = false;
    for (int j = 0; j < cfg_.num_joints; ++j) {
      const HomingConfig& h = cfg_.joints[static_cast<std::size_t>(j)].homing;
      members = members || (h.has_sequence && std::abs(h.sequence) == next);
    }
    if (members) {
      start_home_sequence(next);
      return;
    }
  }
  home_all_ = false;
  home_sequence_ = -1;
  post_text("homing finished");
}

}  // namespace cnc::motion
