// How a part of the controller (a HAL component such as the motion or task
// controller) takes part in the controller's non-realtime task cycle: it may
// take commands from the command channel, do periodic work, and fill its
// part of the status block. The daemon finds services among the loaded
// components. Nothing here runs in the servo thread.
#pragma once

#include <cstdint>
#include <string_view>

#include "core/ipc/command.hpp"
#include "core/ipc/status.hpp"

namespace cnc::ipc {

// Reports a command's outcome (now, or later for commands that take time).
class CommandReporter {
 public:
  virtual ~CommandReporter() = default;
  virtual void report(const Command& cmd, CommandState state, std::string_view reason = {}) = 0;
};

class ControllerService {
 public:
  virtual ~ControllerService() = default;
  // Services are updated in ascending order (motion before task...).
  virtual int service_order() const noexcept { return 0; }
  // True when this service took the command; it then reports the outcome
  // through `reporter` (Done/Rejected now, or Executing now and Done later).
  virtual bool handle_command(const Command& cmd, CommandReporter& reporter) {
    (void)cmd;
    (void)reporter;
    return false;
  }
  // Once per task cycle.
  virtual void update(int64_t now_ns) { (void)now_ns; }
  // Fill this service's part of the status block.
  virtual void contribute_status(Status& status) { (void)status; }
  // The controller is stopping: end what this service runs (a program,
  // motion) and say so, before the HAL components make their outputs safe.
  virtual void on_controller_shutdown() {}
  // During shutdown, after on_shutdown(): true once outputs are safe.
  virtual bool is_safe_to_stop() const { return true; }
  // This service simulates machine hardware (simulated drives): the
  // controller then accepts fault injections of its own (`cnc inject "task
  // stall S"`), which a real machine refuses.
  virtual bool is_simulator() const { return false; }
};

}  // namespace cnc::ipc
