// Alarms and the message log of the screen. Errors from the controller's
// error channel (and drive faults seen in the status) are alarms that stay
// until the operator acknowledges them; every message, alarm and screen
// event also goes to a time-stamped log. Repeats are never merged. CiA-402
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
};

}  // namespace cnc::hmi
