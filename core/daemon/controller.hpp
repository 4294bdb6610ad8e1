// The controller daemon's core: reads the INI, builds the HAL from the HAL
// files, starts the periodic threads, runs the task cycle (commands in,
// services updated, status and messages out) and shuts everything down in
// order, drives first. One Controller per process and instance.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/daemon/plugins.hpp"
#include "core/hal/commands.hpp"
#include "core/ini/ini_file.hpp"
#include "core/ipc/admin.hpp"
#include "core/ipc/alarms.hpp"
#include "core/ipc/server.hpp"
#include "core/ipc/service.hpp"
#include "core/util/messages.hpp"

namespace cnc::daemon {

struct Options {
  std::filesystem::path ini_file;
  std::string instance = "default";
  bool verbose = false;
  // Unknown and unused INI keys stop the start-up (as [EMC]UNKNOWN_KEYS = ERROR).
  bool strict = false;
  // Load and check everything (INI, HAL files, components, the INI key
  // check), then stop: no instance segment, no threads started.
  bool check_only = false;
  // Registered after the product's components: the build's plug-ins
  // (plugins.hpp), e.g. the simulators.
  std::vector<Registrar> extra_components;
};

class Controller : private ipc::CommandReporter {
 public:
  // Loads everything and starts the threads; throws with a clear message
  // (ConfigError naming file and line, or std::runtime_error).
  explicit Controller(const Options& options);
  ~Controller();

  // Runs the task cycle until stop() or SIGINT/SIGTERM (when `handle_signals`).
  void run(bool handle_signals);
  void stop() noexcept { stop_requested_.store(true); }
  // One task cycle; public for tests that step the controller.
  void cycle();

  hal::Hal& hal() noexcept { return hal_; }
  MessageQueue& messages() noexcept { return messages_; }
  const ini::IniFile& ini() const noexcept { return ini_; }

 private:
  void report(const ipc::Command& cmd, ipc::CommandState state, std::string_view reason) override;
  void dispatch(const ipc::Command& cmd);
  // `cnc inject "task ..."` on a simulated machine; false: not ours.
  bool inject(const ipc::Command& cmd);
  void wire_estop();
  // Reports the INI keys nobody read (ini_check.hpp); throws in strict mode.
  void check_ini_keys();
  void publish_status();
  void drain_messages();
  void shutdown();
  ipc::AdminReply admin_request(const std::string& line);

  Options options_;
  ini::IniFile ini_;
  MessageQueue messages_;
  ipc::AlarmTable alarms_;  // errors of the message channel, de-duplicated, acknowledged by clients
  ipc::AccessPolicy access_;
  std::unique_ptr<ipc::Server> server_;
  hal::Hal hal_;
  hal::ComponentRegistry registry_;
  std::unique_ptr<hal::CommandInterpreter> interp_;
  std::unique_ptr<ipc::AdminServer> admin_;
  std::vector<ipc::ControllerService*> services_;
  std::unique_ptr<ipc::ControllerService> task_;  // the task controller, when motion is loaded
  std::unique_ptr<ipc::Status> status_;  // large: kept off the stack
  std::atomic<bool> stop_requested_{false};
  bool shut_down_ = false;
  bool threads_started_ = false;
  std::filesystem::path shutdown_hal_;  // [HAL]SHUTDOWN, read at start-up
  std::string machine_;                 // [EMC]MACHINE, for the status
  int64_t cycle_ns_ = 1'000'000;
  int64_t started_ns_ = 0;
  uint64_t heartbeat_ = 0;
  int64_t stall_ns_ = 0;  // an injected task-cycle stall, taken at the end of this cycle
};

// Every component the controller can load by name (core blocks, kinematics,
// motion, task, I/O, fieldbus, drives), in one registry.
void register_all_components(hal::ComponentRegistry& registry);

}  // namespace cnc::daemon
