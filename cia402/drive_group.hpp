// The drives of one fieldbus as a group: their configuration from INI, the
// start-up checks and parameter writes (non-realtime, before the servo
// thread starts), the servo-thread read/write of every drive, the motion
// watchdog that reaches the drives, and shutdown. Usable without a HAL
// (tests, benchmarks): commands and feedback are plain structs.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "cia402/drive.hpp"
#include "cia402/link.hpp"

namespace cnc {
class MessageQueue;
namespace ini {
class IniFile;
}
}  // namespace cnc

namespace cnc::cia402 {

struct DriveEntry {
  int number = 0;  // the drive's number in HAL names: cia402.0.drive.<NN>
  DriveConfig config;
};

struct GroupConfig {
  std::string name = "cia402.0";  // HAL prefix and message source
  std::string section = "CIA402";
  std::string bus = "canopen.0";  // the fieldbus master's HAL prefix
  int watchdog_cycles = 3;        // motion.watchdog may hold still this long
  std::vector<DriveEntry> drives;
};

// Reads [<section>] (BUS, DRIVE = n ..., WATCHDOG_CYCLES) and each
// [<section>_DRIVE_<n>]; joint keys (HOME_OFFSET) come from [JOINT_<j>].
// Throws ConfigError naming the file, line and key. See docs/cia402.md.
GroupConfig load_group_config(const ini::IniFile& ini, const std::string& section, const std::string& name);

class DriveGroup {
 public:
  DriveGroup(GroupConfig config, DriveLink& link, MessageQueue* messages);

  const GroupConfig& config() const noexcept { return config_; }
  DriveLink& link() noexcept { return link_; }
  std::size_t size() const noexcept { return drives_.size(); }
  Drive& drive(std::size_t i) noexcept { return *drives_[i]; }
  DriveCommand& command(std::size_t i) noexcept { return commands_[i]; }
  const DriveFeedback& feedback(std::size_t i) const noexcept { return feedback_[i]; }

  // Start-up (non-realtime, the bus running): checks the profile (0x1000)
  // and the supported modes (0x6502), writes the configured parameters.
  // Throws std::runtime_error "<drive>: <object>: <reason>".
  void configure();

  // Servo thread.
  void read(int64_t now_ns) noexcept;
  void write(int64_t now_ns) noexcept;
  // motion.watchdog and motion.watchdog-enabled, before write().
  void set_watchdog(bool level, bool enabled) noexcept {
    watchdog_level_ = level;
    watchdog_enabled_ = enabled;
  }
  // False once the watchdog stopped toggling: the bus outputs should stop
  // (net it to the bus's enable) so that the drives stop by themselves.
  bool watchdog_ok() const noexcept { return !watchdog_tripped_; }

  // Shutdown: every drive is quick-stopped and disabled.
  void request_shutdown() noexcept { shutdown_.store(true, std::memory_order_relaxed); }
  bool is_safe() const noexcept;

 private:
  GroupConfig config_;
  DriveLink& link_;
  MessageQueue* messages_;
  std::vector<std::unique_ptr<Drive>> drives_;
  std::vector<DriveCommand> commands_;
  std::vector<DriveFeedback> feedback_;
  bool watchdog_level_ = false, watchdog_enabled_ = false, watchdog_last_ = false;
  int watchdog_still_ = 0;
  bool watchdog_tripped_ = false;
  std::atomic<bool> shutdown_{false};
};

}  // namespace cnc::cia402
