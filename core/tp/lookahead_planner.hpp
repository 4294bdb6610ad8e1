// cnc::tp::LookaheadPlanner: the project's coordinated-mode planner (deep
// look-ahead, tolerance-bounded corner smoothing, jerk-limited motion along
// the path). See docs/trajectory-planner.md.
//
// Threads: every TrajectoryPlanner method is called from the servo thread
// and is realtime-safe. With PlannerThreading::OwnThread the planning that is
// not per cycle (geometry, smoothing, limits) runs on a thread the planner
// starts, fed and read through lock-free rings; the servo thread never waits
// for it. With PlannerThreading::Inline that work runs inside add_line() and
// friends (deterministic: tests and benchmarks). Construction and
// destruction allocate and are not realtime.
#pragma once

#include <atomic>
#include <memory>
#include <thread>

#include "core/tp/executor.hpp"
#include "core/tp/path_builder.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

enum class PlannerThreading : uint8_t { Inline, OwnThread };

// Checks the configuration (throws std::invalid_argument naming the field)
// and builds the planner with queues sized for config.lookahead_segments.
std::unique_ptr<TrajectoryPlanner> make_planner(const PlannerConfig& config,
                                                PlannerThreading threading = PlannerThreading::OwnThread);

class LookaheadPlanner final : public TrajectoryPlanner {
 public:
  // `split_ring_spans`: the executor's hand-over ring of split spans
  // (Executor's constructor; 0: its production size).
  LookaheadPlanner(const PlannerConfig& config, PlannerThreading threading, std::size_t split_ring_spans = 0);
  ~LookaheadPlanner() override;
  LookaheadPlanner(const LookaheadPlanner&) = delete;
  LookaheadPlanner& operator=(const LookaheadPlanner&) = delete;

  void set_position(const Pose& pose) noexcept override;
  void reset(const Pose& pose) noexcept override;
  Result add_line(const Pose& end, const SegmentParams& params) noexcept override;
  Result add_circle(const Pose& end, const std::array<double, 3>& center, const std::array<double, 3>& normal,
                    int turns, const SegmentParams& params) noexcept override;
  Result add_dwell(double seconds, const SegmentParams& params) noexcept override;
  void run_cycle(const CycleInputs& in, CycleOutputs& out) noexcept override;
  void pause() noexcept override;
  void resume() noexcept override;
  void step() noexcept override;
  void abort() noexcept override;
  bool is_done() const noexcept override;
  bool is_paused() const noexcept override;
  int queue_depth() const noexcept override;
  bool is_queue_full() const noexcept override;
  void set_config(const PlannerConfig& config) noexcept override;
  void flush() noexcept override;

  // For tests and benchmarks (servo thread only).
  const Executor& executor() const noexcept { return *exec_; }
  PlannerThreading threading() const noexcept { return threading_; }

 private:
  void thread_main();
  void process(const Command& c) noexcept;
  // Inline: the producer's share after the builder may have published.
  void prepare_inline() noexcept;
  bool push(const Command& c, bool control) noexcept;
  bool pending_input() const noexcept;
  Result check_move(const Curve& curve, const SegmentParams& params) const noexcept;

  PlannerConfig cfg_;
  PlannerThreading threading_;
  std::unique_ptr<PathStore> store_;
  std::unique_ptr<PathBuilder> builder_;
  std::unique_ptr<Executor> exec_;
  std::unique_ptr<SlotRing<Command>> input_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  uint64_t accepted_ = 0;      // input moves accepted (servo thread)
  uint64_t aborted_ = 0;       // input moves dropped by aborts
  uint64_t cycle_ = 0;
  uint64_t stall_cycles_ = 0;  // cycles standing with a full queue
  uint32_t epoch_ = 0;
  uint64_t config_gen_ = 0;    // set_config calls so far (servo thread)
  bool reset_pending_ = false;
  bool position_pending_ = false;
  Pose end_pose_;              // where the next move starts
  std::atomic<uint64_t> cycle_pub_{0};   // servo cycle count, for the builder thread
  std::atomic<uint64_t> last_input_{0};  // cycle of the last accepted move
  std::atomic<bool> urgent_{false};      // the servo side is about to brake for the end
  std::atomic<bool> full_{false};
};

}  // namespace cnc::tp
