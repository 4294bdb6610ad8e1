#include "hmi/alarms.hpp"

#include <cstdio>
#include <ctime>

#include "cia402/error_codes.hpp"

namespace cnc::hmi {

std::string decode_drive_error(uint16_t code) { return cia402::error_code_text(code); }

const char* drive_state_name(uint8_t state) noexcept {
  switch (state) {
    case 0: return "not ready to switch on";
    case 1: return "switch on disabled";
    case 2: return "ready to switch on";
    case 3: return "switched on";
    case 4: return "operation enabled";
    case 5: return "quick stop active";
    case 6: return "fault reaction active";
    case 7: return "fault";
    default: return "invalid statusword";
  }
}

const char* to_string(LogLevel l) noexcept {
  switch (l) {
    case LogLevel::Error: return "error";
    case LogLevel::Warning: return "warning";
    case LogLevel::Info: return "info";
    case LogLevel::Display: return "display";
    case LogLevel::Operator: return "operator";
  }
  return "?";
}

AlarmLog::AlarmLog(std::size_t max_log, std::size_t max_alarms) : max_log_(max_log), max_alarms_(max_alarms) {}

std::string AlarmLog::format_time(int64_t time_ns, bool with_date) {
  const time_t secs = static_cast<time_t>(time_ns / 1'000'000'000);
  tm local{};
  localtime_r(&secs, &local);
  char buf[48];
  std::strftime(buf, sizeof buf, with_date ? "%Y-%m-%d %H:%M:%S" : "%H:%M:%S", &local);
  char out[64];
  std::snprintf(out, sizeof out, "%s.%03d", buf, static_cast<int>((time_ns / 1'000'000) % 1000));
  return out;
}

void AlarmLog::add_log(const LogEntry& e) {
  log_.push_back(e);
  while (log_.size() > max_log_) log_.pop_front();
  ++revision_;
  if (on_log) on_log(e);
}

void AlarmLog::raise(const std::string& source, const std::string& text, int64_t time_ns) {
  Alarm a;
  a.id = next_id_++;
  a.time_ns = time_ns;
  a.source = source;
  a.text = text;
  alarms_.push_back(a);
  ++local_active_;
  active_count_ = local_active_ + controller_alarms_.size();
  // Only acknowledged alarms are dropped when the list is full.
  while (alarms_.size() > max_alarms_) {
    auto it = alarms_.begin();
    while (it != alarms_.end() && !it->acknowledged) ++it;
    if (it == alarms_.end()) break;
    alarms_.erase(it);
  }
  ++revision_;
}

void AlarmLog::post(const Message& m) {
  LogLevel level = LogLevel::Info;
  if (m.kind == MessageKind::Error) level = LogLevel::Error;
  if (m.kind == MessageKind::Display) level = LogLevel::Display;
  add_log(LogEntry{m.time_ns, level, std::string(m.source.view()), std::string(m.text.view())});
  // A controller that keeps alarms raised this one in its table.
  if (m.kind == MessageKind::Error && !controller_) {
    raise(std::string(m.source.view()), std::string(m.text.view()), m.time_ns);
  }
}

void AlarmLog::update_controller(const ipc::AlarmStatus& a) {
  if (!a.available) {
    if (controller_) {
      controller_ = false;
      controller_alarms_.clear();
      active_count_ = local_active_;
      ++revision_;
    }
    return;
  }
  if (controller_ && a.revision == controller_revision_) return;
  controller_ = true;
  controller_revision_ = a.revision;
  controller_alarms_.clear();
  for (const ipc::AlarmEntry& e : a.list) {
    if (e.id == 0 || e.acknowledged) continue;
    Alarm m;
    m.id = (uint64_t{1} << 40) + e.id;  // apart from the screen's own ids
    m.controller_id = e.id;
    m.time_ns = e.last_ns;
    m.source = std::string(e.source.view());
    m.text = std::string(e.text.view());
    m.count = e.count;
    controller_alarms_.push_back(std::move(m));
  }
  active_count_ = local_active_ + controller_alarms_.size();
  ++revision_;
}

void AlarmLog::post_local(LogLevel level, const std::string& source, const std::string& text, int64_t time_ns) {
  add_log(LogEntry{time_ns, level, source, text});
  if (level == LogLevel::Error) raise(source, text, time_ns);
}

void AlarmLog::update_drives(const ipc::Status& s, int64_t time_ns) {
  for (int i = 0; i < kMaxJoints + 1; ++i) {
    const ipc::DriveStatus& d = s.drives[i];
    DriveSeen& seen = drives_[i];
    const bool faulted = d.present && (d.state == kDriveStateFault || d.state == kDriveStateFaultReaction);
    std::string name = d.name.empty() ? "drive " + std::to_string(i) : std::string(d.name.view());
    if (d.joint >= 0) name += " (joint " + std::to_string(d.joint) + ")";
    if (faulted && (!seen.faulted || d.error_code != seen.code)) {
      char code[16];
      std::snprintf(code, sizeof code, "0x%04X", d.error_code);
      const std::string text = d.fault_text.empty() ? decode_drive_error(d.error_code) : std::string(d.fault_text.view());
      const std::string msg = name + ": fault " + code + " " + text;
      add_log(LogEntry{time_ns, LogLevel::Error, "drive", msg});
      // A controller that keeps alarms has one for the fault's cause (the
      // joint motion disabled for it, with this drive's text).
      if (!controller_) raise("drive", msg, time_ns);
    } else if (!faulted && seen.faulted) {
      add_log(LogEntry{time_ns, LogLevel::Info, "drive", name + ": fault cleared (" + drive_state_name(d.state) + ")"});
    }
    seen.faulted = faulted;
    seen.code = faulted ? d.error_code : 0;
  }
}

bool AlarmLog::acknowledge(uint64_t id, int64_t time_ns) {
  for (const auto& a : controller_alarms_) {
    if (a.id == id) {
      if (acknowledge_in_controller) acknowledge_in_controller(a.controller_id);
      add_log(LogEntry{time_ns, LogLevel::Operator, "operator", "acknowledged: " + a.text});
      return true;
    }
  }
  for (auto& a : alarms_) {
    if (a.id == id && !a.acknowledged) {
      a.acknowledged = true;
      a.acknowledged_ns = time_ns;
      --local_active_;
      active_count_ = local_active_ + controller_alarms_.size();
      ++revision_;
      add_log(LogEntry{time_ns, LogLevel::Operator, "operator", "acknowledged: " + a.text});
      return true;
    }
  }
  return false;
}

int AlarmLog::acknowledge_all(int64_t time_ns) {
  int n = 0;
  for (auto& a : alarms_) {
    if (!a.acknowledged) {
      a.acknowledged = true;
      a.acknowledged_ns = time_ns;
      ++n;
    }
  }
  local_active_ = 0;
  if (!controller_alarms_.empty() && acknowledge_in_controller) {
    acknowledge_in_controller(0);
    n += static_cast<int>(controller_alarms_.size());
  }
  active_count_ = local_active_ + controller_alarms_.size();
  ++revision_;
  if (n) add_log(LogEntry{time_ns, LogLevel::Operator, "operator", "acknowledged " + std::to_string(n) + " alarm(s)"});
  return n;
}

std::vector<const Alarm*> AlarmLog::active() const {
  std::vector<const Alarm*> out;
  for (const auto& a : controller_alarms_) out.push_back(&a);
  for (const auto& a : alarms_) {
    if (!a.acknowledged) out.push_back(&a);
  }
  return out;
}

}  // namespace cnc::hmi
