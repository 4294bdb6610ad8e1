#include "core/tp/lookahead_planner.hpp"

#include <time.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace cnc::tp {
namespace {

void check_config(const PlannerConfig& c) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("trajectory planner config: " + what); };
  if (!(c.cycle_time_s > 0) || !std::isfinite(c.cycle_time_s)) fail("cycle_time_s must be a positive number");
  if (c.lookahead_segments < 1 || c.lookahead_segments > 1'000'000) fail("lookahead_segments must be 1..1000000");
  if (c.blend_span_segments < 1 || c.blend_span_segments > 32) fail("blend_span_segments must be 1..32");
  if (!(c.max_blend_half_width > 0)) fail("max_blend_half_width must be positive");
  if ((c.axis_mask & ((1u << kNumAxes) - 1)) == 0) fail("axis_mask names no axis");
  for (int i = 0; i < kNumAxes; ++i) {
    if (!(c.axis_mask & (1u << i))) continue;
    const AxisLimits& l = c.axes[static_cast<std::size_t>(i)];
    const std::string axis(1, kAxisLetters[i]);
    if (!(l.max_velocity > 0) || !std::isfinite(l.max_velocity)) fail("axis " + axis + ": max_velocity must be > 0");
    if (!(l.max_acceleration > 0) || !std::isfinite(l.max_acceleration)) {
      fail("axis " + axis + ": max_acceleration must be > 0");
    }
    if (!(l.max_jerk > 0) || !std::isfinite(l.max_jerk)) fail("axis " + axis + ": max_jerk must be > 0");
  }
}

// What counts as standing at the end of what is published (units).
constexpr double kStallGap = 1e-9;

std::size_t segments_capacity(const PlannerConfig& c) {
  return static_cast<std::size_t>(c.lookahead_segments) + 8 * static_cast<std::size_t>(c.blend_span_segments) + 128;
}

bool finite(const SegmentParams& p) {
  return std::isfinite(p.feed) && std::isfinite(p.max_velocity) && std::isfinite(p.max_acceleration) &&
         std::isfinite(p.tolerance) && std::isfinite(p.naive_cam_tolerance);
}

}  // namespace

const char* to_string(Result r) noexcept {
  switch (r) {
    case Result::Ok: return "ok";
    case Result::QueueFull: return "queue full";
    case Result::InvalidSegment: return "invalid segment";
    case Result::NotAllowed: return "not allowed";
  }
  return "unknown";
}

std::unique_ptr<TrajectoryPlanner> make_planner(const PlannerConfig& config, PlannerThreading threading) {
  check_config(config);
  return std::make_unique<LookaheadPlanner>(config, threading);
}

LookaheadPlanner::LookaheadPlanner(const PlannerConfig& config, PlannerThreading threading,
                                   std::size_t split_ring_spans)
    : cfg_(config), threading_(threading) {
  check_config(config);
  const std::size_t segs = segments_capacity(config);
  store_ = std::make_unique<PathStore>(segs, segs, 12 * segs + 64);
  builder_ = std::make_unique<PathBuilder>(config, *store_);
  exec_ = std::make_unique<Executor>(config, *store_, split_ring_spans);
  if (threading_ == PlannerThreading::OwnThread) {
    input_ = std::make_unique<SlotRing<Command>>(static_cast<std::size_t>(config.lookahead_segments) + 64);
    thread_ = std::thread([this] { thread_main(); });
  }
}

LookaheadPlanner::~LookaheadPlanner() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

// ---------------------------------------------------------------------------
// Builder thread

void LookaheadPlanner::process(const Command& c) noexcept {
  switch (c.kind) {
    case CommandKind::Line: builder_->add_line(c.pose, c.params); break;
    case CommandKind::Circle: builder_->add_circle(c.pose, c.center, c.normal, c.turns, c.params); break;
    case CommandKind::Dwell: builder_->add_dwell(c.seconds, c.params); break;
    case CommandKind::SetPosition: builder_->set_position(c.pose); break;
    case CommandKind::SetConfig:
      builder_->set_config(c.config);
      exec_->set_prepare_config(c.config, c.config_gen);
      break;
    case CommandKind::Flush: builder_->flush(); break;
    case CommandKind::Reset: builder_->reset(c.epoch); break;
  }
}

void LookaheadPlanner::thread_main() {
  const long nap_ns = static_cast<long>(std::min(2.5e5, cfg_.cycle_time_s * 0.25e9));
  uint32_t epoch = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    bool worked = false;
    while (input_->released() < input_->published()) {
      const uint64_t seq = input_->released();
      const Command& c = input_->at(seq);
      const bool motion = c.kind == CommandKind::Line || c.kind == CommandKind::Circle || c.kind == CommandKind::Dwell;
      if (c.kind == CommandKind::Reset) epoch = c.epoch;
      if (motion && c.epoch != epoch) {
        input_->release_upto(seq + 1);  // queued before an abort
        continue;
      }
      if (motion && !builder_->can_accept()) break;
      process(c);
      input_->release_upto(seq + 1);
      // The pieces' limit tables, as soon as they are published.
      exec_->prepare_published();
      worked = true;
    }
    if (builder_->has_held() && input_->released() == input_->published()) {
      const uint64_t now = cycle_pub_.load(std::memory_order_acquire);
      const bool idle = now - last_input_.load(std::memory_order_relaxed) >=
                            static_cast<uint64_t>(std::max(1, cfg_.flush_idle_cycles)) &&
                        !full_.load(std::memory_order_relaxed);
      if (idle || urgent_.load(std::memory_order_relaxed)) {
        builder_->flush();
        exec_->prepare_published();
        worked = true;
      }
    }
    if (!worked) {
      // Pieces whose splitting waited for room in the ring of split spans.
      exec_->prepare_published();
      timespec ts{0, nap_ns};
      nanosleep(&ts, nullptr);
    }
  }
}

// ---------------------------------------------------------------------------
// Servo thread

void LookaheadPlanner::prepare_inline() noexcept {
  if (threading_ == PlannerThreading::Inline) exec_->prepare_published();
}

bool LookaheadPlanner::push(const Command& c, bool control) noexcept {
  if (!input_->has_room(control ? 1 : 4)) return false;
  Command& slot = input_->push_slot();
  slot = c;
  slot.epoch = epoch_;
  input_->publish();
  return true;
}

bool LookaheadPlanner::pending_input() const noexcept {
  return input_ && input_->released() < input_->published();
}

Result LookaheadPlanner::check_move(const Curve& curve, const SegmentParams& params) const noexcept {
  if (!finite(params)) return Result::InvalidSegment;
  if (params.type != MotionType::Traverse && !(params.feed > 0)) return Result::InvalidSegment;
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const bool moves = curve.rate[k] != 0 || (curve.kind == CurveKind::Helix && i < 3 && curve.bound1[k] > 0);
    if (moves && !(cfg_.axis_mask & (1u << i))) return Result::InvalidSegment;
  }
  if (is_queue_full()) return Result::QueueFull;
  return Result::Ok;
}

void LookaheadPlanner::set_position(const Pose& pose) noexcept {
  if (!is_done()) return;
  end_pose_ = pose;
  exec_->set_position(pose);
  if (threading_ == PlannerThreading::Inline) {
    builder_->set_position(pose);
    prepare_inline();
  } else {
    Command c;
    c.kind = CommandKind::SetPosition;
    c.pose = pose;
    push(c, true);
  }
}

void LookaheadPlanner::reset(const Pose& pose) noexcept {
  exec_->reset(pose);
  uint32_t epoch = 0;
  exec_->take_abort_done(epoch);
  aborted_ = accepted_ - exec_->inputs_completed();
  epoch_ = epoch;
  end_pose_ = pose;
  if (threading_ == PlannerThreading::Inline) {
    builder_->reset(epoch);
    builder_->set_position(pose);
    prepare_inline();
  } else {
    reset_pending_ = true;
    position_pending_ = true;
  }
}

Result LookaheadPlanner::add_line(const Pose& end, const SegmentParams& params) noexcept {
  if (params.type == MotionType::Arc || params.type == MotionType::Dwell) return Result::InvalidSegment;
  if (reset_pending_ || position_pending_) return Result::QueueFull;
  Curve c;
  if (!make_line(end_pose_, end, cfg_.max_blend_half_width, c)) {
    for (double x : end.v) {
      if (!std::isfinite(x)) return Result::InvalidSegment;
    }
    return Result::Ok;  // nothing moves
  }
  const Result r = check_move(c, params);
  if (r != Result::Ok) return r;
  if (params.type == MotionType::Probe) exec_->clear_probe();
  if (threading_ == PlannerThreading::Inline) {
    const Result b = builder_->add_line(end, params);
    prepare_inline();
    if (b != Result::Ok) return b;
  } else {
    Command cmd;
    cmd.kind = CommandKind::Line;
    cmd.pose = end;
    cmd.params = params;
    if (!push(cmd, false)) return Result::QueueFull;
  }
  end_pose_ = end;
  ++accepted_;
  last_input_.store(cycle_, std::memory_order_relaxed);
  return Result::Ok;
}

Result LookaheadPlanner::add_circle(const Pose& end, const std::array<double, 3>& center,
                                    const std::array<double, 3>& normal, int turns,
                                    const SegmentParams& params) noexcept {
  if (params.type == MotionType::Traverse || params.type == MotionType::Dwell) return Result::InvalidSegment;
  if (reset_pending_ || position_pending_) return Result::QueueFull;
  Curve c;
  if (!make_helix(end_pose_, end, center, normal, turns, cfg_.max_blend_half_width, c)) return Result::InvalidSegment;
  const Result r = check_move(c, params);
  if (r != Result::Ok) return r;
  if (threading_ == PlannerThreading::Inline) {
    const Result b = builder_->add_circle(end, center, normal, turns, params);
    prepare_inline();
    if (b != Result::Ok) return b;
  } else {
    Command cmd;
    cmd.kind = CommandKind::Circle;
    cmd.pose = end;
    cmd.center = center;
    cmd.normal = normal;
    cmd.turns = turns;
    cmd.params = params;
    if (!push(cmd, false)) return Result::QueueFull;
  }
  end_pose_ = end;
  ++accepted_;
  last_input_.store(cycle_, std::memory_order_relaxed);
  return Result::Ok;
}

Result LookaheadPlanner::add_dwell(double seconds, const SegmentParams& params) noexcept {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return Result::InvalidSegment;
  if (reset_pending_ || position_pending_ || is_queue_full()) return Result::QueueFull;
  if (threading_ == PlannerThreading::Inline) {
    const Result b = builder_->add_dwell(seconds, params);
    prepare_inline();
    if (b != Result::Ok) return b;
  } else {
    Command cmd;
    cmd.kind = CommandKind::Dwell;
    cmd.seconds = seconds;
    cmd.params = params;
    if (!push(cmd, false)) return Result::QueueFull;
  }
  ++accepted_;
  last_input_.store(cycle_, std::memory_order_relaxed);
  return Result::Ok;
}

void LookaheadPlanner::run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept {
  ++cycle_;
  const bool full = is_queue_full();
  // A full queue whose published part is all executed while the machine
  // stands (the held moves are the whole queue: a short look-ahead, or
  // long merged chords) would wait forever: plan to the end of what is
  // held. The stop this bakes in costs nothing, the machine stands anyway.
  // Standing with path left ahead is not that: at a start the machine
  // waits a few cycles for the envelope (the whole look-ahead arrives at
  // once), and a flush then baked a stop into the end of the look-ahead
  // (and ran the builder's flush inside this cycle, inline).
  const bool stalled = full && !exec_->is_moving() && !exec_->is_paused() && in.feed_scale > 0 &&
                       exec_->distance_to_tail() <= kStallGap;
  stall_cycles_ = stalled ? stall_cycles_ + 1 : 0;
  const bool stall = stall_cycles_ >= static_cast<uint64_t>(std::max(1, cfg_.flush_idle_cycles));
  if (threading_ == PlannerThreading::Inline) {
    if (builder_->has_held()) {
      const bool idle = cycle_ - last_input_.load(std::memory_order_relaxed) >=
                            static_cast<uint64_t>(std::max(1, cfg_.flush_idle_cycles)) &&
                        !full;
      // A flush ends the held moves with a stop that stays when more moves
      // come: only worth it when the input has dried up (nothing queued this
      // cycle, room in the queue) and the machine is about to brake for the
      // end of what is planned. A full queue is the look-ahead limit, not a
      // starving interpreter: the executor brakes for its end by itself.
      const bool starving = cycle_ - last_input_.load(std::memory_order_relaxed) >= 2 && !full;
      const bool urgent = starving && exec_->is_moving() &&
                          exec_->distance_to_tail() < 1.5 * exec_->stop_distance() +
                                                          4 * exec_->path_velocity() * cfg_.cycle_time_s;
      if (idle || urgent || stall) {
        builder_->flush();
        prepare_inline();
      }
    }
  } else {
    // As in the inline case: only when the input has dried up.
    const bool starving = cycle_ - last_input_.load(std::memory_order_relaxed) >= 2 && !full;
    urgent_.store(stall || (starving && exec_->is_moving() &&
                            exec_->distance_to_tail() <
                                2 * exec_->stop_distance() + 8 * exec_->path_velocity() * cfg_.cycle_time_s),
                  std::memory_order_relaxed);
    full_.store(full, std::memory_order_relaxed);
    cycle_pub_.store(cycle_, std::memory_order_release);
  }
  exec_->run_cycle(in, out);
  uint32_t epoch = 0;
  if (exec_->take_abort_done(epoch)) {
    aborted_ = accepted_ - exec_->inputs_completed();
    epoch_ = epoch;
    // The next move starts where the abort stopped the machine, not at the
    // end of the moves it dropped (that was a jump of the command).
    end_pose_ = out.position;
    if (threading_ == PlannerThreading::Inline) {
      builder_->reset(epoch);
      builder_->set_position(end_pose_);
      prepare_inline();
    } else {
      reset_pending_ = true;
      position_pending_ = true;
    }
  }
  if (reset_pending_) {
    Command c;
    c.kind = CommandKind::Reset;
    c.epoch = epoch_;
    if (push(c, true)) reset_pending_ = false;
  }
  if (!reset_pending_ && position_pending_) {
    Command c;
    c.kind = CommandKind::SetPosition;
    c.pose = end_pose_;
    if (push(c, true)) position_pending_ = false;
  }
  out.done = is_done();
}

void LookaheadPlanner::pause() noexcept { exec_->pause(); }
void LookaheadPlanner::resume() noexcept { exec_->resume(); }
void LookaheadPlanner::step() noexcept { exec_->step(); }
void LookaheadPlanner::abort() noexcept { exec_->abort(); }

bool LookaheadPlanner::is_done() const noexcept { return queue_depth() == 0 && exec_->is_idle(); }
bool LookaheadPlanner::is_paused() const noexcept { return exec_->is_paused(); }

int LookaheadPlanner::queue_depth() const noexcept {
  const uint64_t finished = exec_->inputs_completed() + aborted_;
  return accepted_ > finished ? static_cast<int>(accepted_ - finished) : 0;
}

bool LookaheadPlanner::is_queue_full() const noexcept {
  if (queue_depth() >= cfg_.lookahead_segments) return true;
  return input_ && !input_->has_room(4);
}

void LookaheadPlanner::set_config(const PlannerConfig& config) noexcept {
  PlannerConfig c = config;
  // Queue sizes and the holdback geometry are fixed at construction.
  c.lookahead_segments = std::min(c.lookahead_segments, cfg_.lookahead_segments);
  c.blend_span_segments = cfg_.blend_span_segments;
  if (!(c.cycle_time_s > 0)) c.cycle_time_s = cfg_.cycle_time_s;
  cfg_ = c;
  ++config_gen_;
  exec_->set_config(c, config_gen_);
  if (threading_ == PlannerThreading::Inline) {
    builder_->set_config(c);
    exec_->set_prepare_config(c, config_gen_);
  } else {
    Command cmd;
    cmd.kind = CommandKind::SetConfig;
    cmd.config = c;
    cmd.config_gen = config_gen_;
    push(cmd, true);
  }
}

void LookaheadPlanner::flush() noexcept {
  if (threading_ == PlannerThreading::Inline) {
    builder_->flush();
    prepare_inline();
  } else {
    Command c;
    c.kind = CommandKind::Flush;
    push(c, true);
  }
}

}  // namespace cnc::tp
