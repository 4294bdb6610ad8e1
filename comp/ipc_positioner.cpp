#include "comp/ipc_positioner.hpp"

#include <chrono>
#include <cstdio>
#include <thread>

namespace cnc::comp {

std::string IpcPositioner::move_to(double target_mm) {
  char line[96];
  std::snprintf(line, sizeof line, "G53 G1 %c%.4f F%.1f", axis_, target_mm, feed_);
  ipc::Command cmd;
  cmd.type = ipc::CommandType::TaskPlanExecute;
  cmd.i[0] = -1;
  cmd.text.assign(line);
  const int errors_before = c_.status().task.errors_since_start;
  ipc::CommandResult r;
  try {
    r = c_.execute(cmd, std::chrono::seconds(10));
  } catch (const std::exception& e) {
    return std::string(line) + ": " + e.what();
  }
  if (r.state != ipc::CommandState::Done) {
    return std::string(line) + ": " + (r.reason.empty() ? "no answer from the controller within 10 s" : r.reason.c_str());
  }
  const auto start = std::chrono::steady_clock::now();
  bool seen_busy = false;
  for (;;) {
    if (!c_.controller_alive()) return std::string(line) + ": the controller stopped";
    const ipc::Status s = c_.status();
    if (s.task.state != ipc::TaskState::On) return std::string(line) + ": the machine is off or in E-stop";
    if (s.task.errors_since_start > errors_before) return std::string(line) + ": the controller reported an error";
    const bool busy = s.task.interp_state != ipc::InterpState::Idle || s.task.queued_mdi > 0 || s.motion.queue > 0 ||
                      !s.motion.inpos;
    seen_busy = seen_busy || busy;
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // Idle: done once the move was seen, or after a moment for a move of nothing.
    if (!busy && (seen_busy || waited > 0.2)) return "";
    if (waited > timeout_s_) {
      return std::string(line) + ": not in position after " + std::to_string(static_cast<int>(timeout_s_)) + " s";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

void IpcPositioner::settle(double seconds) {
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
}

}  // namespace cnc::comp
