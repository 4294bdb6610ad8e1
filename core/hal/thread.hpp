// A HAL thread: an ordered list of realtime functions run once per period by
// an rt::PeriodicTask. The list is double-buffered so that addf/delf from
// another thread never make the servo thread wait or see a half-built list.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/hal/objects.hpp"
#include "core/rt/periodic_task.hpp"

namespace cnc::hal {

class Thread {
 public:
  static constexpr std::size_t kMaxFunctions = 128;

  Thread(std::string name, int64_t period_ns, bool uses_fp);
  Thread(const Thread&) = delete;
  Thread& operator=(const Thread&) = delete;

  const std::string& name() const noexcept { return name_; }
  int64_t period_ns() const noexcept { return period_ns_; }
  bool uses_fp() const noexcept { return uses_fp_; }

  // One cycle: every function in order, each timed. Realtime-safe. Public so
  // that tests and simulations can step a thread without a periodic task.
  void run_cycle(const rt::CycleInfo& info) noexcept;

  // Non-realtime, called with the HAL mutex held.
  std::vector<Function*> functions() const;
  void set_functions(const std::vector<Function*>& list);

  void start();
  void stop();
  bool is_running() const noexcept { return task_.is_running(); }
  rt::PeriodicTask& task() noexcept { return task_; }
  const rt::PeriodicTask& task() const noexcept { return task_; }

  // Thread parameters <name>.time and <name>.tmax, set by the HAL.
  void set_params(detail::ParamObj* time, detail::ParamObj* tmax) { time_ = time; tmax_ = tmax; }

 private:
  struct List {
    std::array<Function*, kMaxFunctions> items{};
    std::size_t count = 0;
  };
  static void trampoline(void* self, const rt::CycleInfo& info);

  std::string name_;
  int64_t period_ns_;
  bool uses_fp_;
  List lists_[2];
  std::atomic<int> active_{0};
  std::atomic<uint64_t> cycle_state_{0};  // odd while a cycle runs
  detail::ParamObj* time_ = nullptr;
  detail::ParamObj* tmax_ = nullptr;
  rt::PeriodicTask task_;
};

}  // namespace cnc::hal
