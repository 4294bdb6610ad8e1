// The controller's alarm table (status block `alarms`): error messages
// become alarms, de-duplicated per cause, and stay until acknowledged
// through the AlarmAcknowledge command. Kept by the controller, not by each
// screen, so that every screen and `cnc alarms` agree and a screen started
// later does not show old acknowledged alarms as active. Non-realtime: the
// daemon feeds it from its message drain.
//
// Cause of a message: the first "joint N" or "spindle N" it names (a drive
// fault reported by motion, then explained by the task naming the drive,
// is one alarm), else the message itself (source and text: identical
// messages are one alarm). A message whose cause has an unacknowledged
// alarm is merged into it: the count grows and the alarm shows the more
// explicit (longer) text.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"

namespace cnc::ipc {

class AlarmTable {
 public:
  // Errors only; other kinds are ignored (they inform, LinuxCNC's texts).
  void post(const Message& m);
  // id 0: all. Returns the number acknowledged now; 0 when `id` is unknown
  // or already acknowledged.
  int acknowledge(uint32_t id, int64_t now_ns);
  const AlarmStatus& status() const noexcept { return s_; }

  // "joint 2" for "joint 2 following error ...", "" when none.
  static std::string cause_of(std::string_view text);

 private:
  AlarmEntry* find_active(std::string_view cause);
  AlarmEntry& new_slot();
  void count_active();

  AlarmStatus s_ = [] {
    AlarmStatus a;
    a.available = true;
    return a;
  }();
  uint32_t next_id_ = 1;
};

}  // namespace cnc::ipc
