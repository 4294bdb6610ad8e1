// The motion controller as a HAL component, loaded like LinuxCNC's motmod:
//   loadrt motmod servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
// It exports LinuxCNC's motion pins (motion.*, joint.N.*, axis.L.*,
// spindle.N.*) and the functions motion-command-handler and
// motion-controller for the servo thread. The task side talks to it through
// submit()/poll_result()/status(): lock-free queues and a sequence lock, so
// the servo thread never waits for it.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "core/hal/component.hpp"
#include "core/ipc/estop.hpp"
#include "core/ipc/service.hpp"
#include "core/motion/motion_controller.hpp"
#include "core/util/seqlock.hpp"
#include "core/util/spsc_ring.hpp"

namespace cnc::motion {

// Makes the coordinated-mode planner (core/tp's, or a test planner).
using PlannerFactory = std::function<std::unique_ptr<tp::TrajectoryPlanner>(const tp::PlannerConfig&)>;

class MotionComponent : public hal::Component, public ipc::ControllerService {
 public:
  static constexpr std::size_t kQueueDepth = 1024;

  MotionComponent(hal::ComponentContext& ctx, const hal::LoadArgs& args, PlannerFactory planner_factory);
  ~MotionComponent() override;

  void on_ready() override;
  void on_shutdown() override;

  // --- task side (one thread) ---
  // Queues a command; returns its serial, or 0 when the queue is full.
  uint64_t submit(MotionCommand cmd);
  bool poll_result(MotionResult& out) { return results_.pop(out); }
  MotionStatus status() const { return status_.read(); }
  // The configuration as loaded (the INI's, with the servo period of the
  // thread that runs motion-controller): the machine's limits. What is in
  // force now, run-time changes included, is in status().
  const MotionConfig& config() const noexcept { return config_; }
  bool ready() const noexcept { return controller_ != nullptr; }
  int free_queue_slots() const noexcept { return static_cast<int>(kQueueDepth - commands_.size()); }
  // Screw compensation for a joint; only before the threads start.
  void set_compensation(int joint, JointCompensation* comp);
  // Only before the threads start (the daemon does it for every
  // configuration, no HAL file needed): the shared segment's E-stop words
  // (requests read, acknowledgement and servo heartbeat written every
  // cycle) and the E-stop chain input, iocontrol.0.emc-enable-in. Either
  // may be absent (null / an invalid pin).
  void set_estop_inputs(ipc::EstopWords* words, hal::BitPin chain);
  // Task side: motion-controller has not advanced its status for at least
  // servo_stall_threshold_ns and a few task cycles (delf, or a stalled
  // servo thread); the reason names the function and what happened to it.
  bool servo_stalled() const noexcept { return stalled_; }
  const std::string& stall_reason() const noexcept { return stall_reason_; }

  // --- ControllerService ---
  int service_order() const noexcept override { return 10; }
  void update(int64_t now_ns) override;
  void contribute_status(ipc::Status& status) override;
  bool is_safe_to_stop() const override;

  // --- servo thread ---
  void command_handler(const rt::CycleInfo& info) noexcept;
  void controller(const rt::CycleInfo& info) noexcept;

 private:
  struct JointPins;
  struct AxisPins;
  struct SpindlePins;
  void make_pins();
  void read_pins() noexcept;
  void write_pins() noexcept;

  hal::ComponentContext ctx_;
  MotionConfig config_;
  PlannerFactory planner_factory_;
  std::unique_ptr<tp::TrajectoryPlanner> planner_;
  std::unique_ptr<MotionController> controller_;
  // A gap this long between two runs of the command handler makes the
  // commands queued before it stale (see command_handler).
  static constexpr int64_t kStaleCommandGapNs = 250'000'000;
  int64_t handler_ran_ns_ = 0;
  SpscRing<MotionCommand, kQueueDepth> commands_;
  SpscRing<MotionResult, kQueueDepth> results_;
  SeqLock<MotionStatus> status_;
  MotionStatus scratch_status_;
  uint64_t next_serial_ = 1;
  std::vector<std::unique_ptr<JointPins>> joint_pins_;
  std::vector<std::unique_ptr<AxisPins>> axis_pins_;
  std::vector<std::unique_ptr<SpindlePins>> spindle_pins_;
  struct MotionPins;
  std::unique_ptr<MotionPins> pins_;
  std::vector<hal::BitPin> din_, dout_;
  std::vector<hal::FloatPin> ain_, aout_;
  ipc::EstopWords* estop_words_ = nullptr;
  hal::BitPin estop_chain_;
  // stall detection (task side)
  uint64_t last_cycles_ = 0;
  int64_t last_advance_ns_ = 0;
  int stale_updates_ = 0;
  bool stalled_ = false;
  std::string stall_reason_;
};

// Registers motmod (the simulated joint, sim_joint, is in sim/machine).
void register_components(hal::ComponentRegistry& registry, PlannerFactory planner_factory);

}  // namespace cnc::motion
