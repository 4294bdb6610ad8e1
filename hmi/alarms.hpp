// Alarms and the message log of the screen. A controller that keeps alarms
// (status `alarms.available`: core/ipc/alarms.hpp) is the one source of the
// controller's alarms: they are mirrored from its status, de-duplicated per
// cause there, and acknowledging one sends AlarmAcknowledge, so every
// screen agrees and a screen started later shows no old acknowledged
// alarm. The screen's own errors (command rejections, lost connection) are
// local alarms. With an older controller, errors from the error channel and
// drive faults seen in the status are local alarms as before. Every
// message, alarm and screen event also goes to a time-stamped log. CiA-402
// drive faults are decoded (0x603F classes of CiA 301/402) and name the
// drive. No Qt.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"

namespace cnc::hmi {

// Text for a CiA 301/402 error code (0x603F, EMCY), e.g. 0x2310
// "continuous over-current": the one table of cia402/error_codes.hpp.
std::string decode_drive_error(uint16_t code);
// Name of a CiA-402 state as numbered in the status (cia402::State).
const char* drive_state_name(uint8_t state) noexcept;
inline constexpr uint8_t kDriveStateFault = 7;
inline constexpr uint8_t kDriveStateFaultReaction = 6;

enum class LogLevel : uint8_t { Error, Warning, Info, Display, Operator };
const char* to_string(LogLevel l) noexcept;

struct LogEntry {
  int64_t time_ns = 0;  // CLOCK_REALTIME
  LogLevel level = LogLevel::Info;
  std::string source;
  std::string text;
};

struct Alarm {
  uint64_t id = 0;
  int64_t time_ns = 0;
  std::string source;
  std::string text;
  bool acknowledged = false;
  int64_t acknowledged_ns = 0;
  uint32_t count = 1;          // messages merged into it (controller alarms)
  uint32_t controller_id = 0;  // != 0: the controller's alarm of this id
};

class AlarmLog {
 public:
  explicit AlarmLog(std::size_t max_log = 5000, std::size_t max_alarms = 1000);

  // A message from the controller: errors become alarms; all are logged.
  void post(const Message& m);
  // The screen's own events (command rejections, connection changes).
  // Errors raised here become alarms too.
  void post_local(LogLevel level, const std::string& source, const std::string& text, int64_t time_ns);
  // Watches the drives: a drive entering fault (or changing its error
  // code) raises an alarm naming the drive; leaving fault is logged.
  void update_drives(const ipc::Status& s, int64_t time_ns);
  // Mirrors the controller's alarm table (from each status).
  void update_controller(const ipc::AlarmStatus& a);
  bool controller_keeps_alarms() const noexcept { return controller_; }
  // Sends AlarmAcknowledge for a controller alarm (id, 0: all); set by the
  // window. The alarm stays active here until the controller's status says
  // it is acknowledged.
  std::function<void(uint32_t)> acknowledge_in_controller;

  bool acknowledge(uint64_t id, int64_t time_ns);
  int acknowledge_all(int64_t time_ns);

  // Unacknowledged alarms, oldest first.
  std::vector<const Alarm*> active() const;
  std::size_t active_count() const noexcept { return active_count_; }
  const std::deque<Alarm>& alarms() const noexcept { return alarms_; }
  const std::deque<LogEntry>& log() const noexcept { return log_; }
  // Grows with every change: views refresh only when it moved.
  uint64_t revision() const noexcept { return revision_; }
  // Called with every new log entry (the LOG_FILE writer).
  std::function<void(const LogEntry&)> on_log;

  static std::string format_time(int64_t time_ns, bool with_date = false);

 private:
  void add_log(const LogEntry& e);
  void raise(const std::string& source, const std::string& text, int64_t time_ns);

  std::size_t max_log_, max_alarms_;
  std::deque<LogEntry> log_;
  std::deque<Alarm> alarms_;
  std::size_t active_count_ = 0;
  uint64_t next_id_ = 1;
  uint64_t revision_ = 0;
  struct DriveSeen {
    bool faulted = false;
    uint16_t code = 0;
  };
  DriveSeen drives_[kMaxJoints + 1] = {};
  bool controller_ = false;
  uint32_t controller_revision_ = 0;
  std::vector<Alarm> controller_alarms_;  // active ones of the controller's table
  std::size_t local_active_ = 0;
};

}  // namespace cnc::hmi
