// Turning the status block into text a person reads and into JSON, for the
// command-line client (and its tests).
#pragma once

#include <string>

#include "core/ipc/estop.hpp"
#include "core/ipc/status.hpp"

namespace cnc::cli {

// `live` (optional): how fresh the status is; a stalled task cycle or servo
// heartbeat is shown as a warning first.
std::string format_status(const ipc::Status& s, const ipc::Liveness* live = nullptr);
std::string status_json(const ipc::Status& s, int indent = 2, const ipc::Liveness* live = nullptr);
// The controller's alarms (`cnc alarms`, and in format_status): the active
// ones, or with `all` the acknowledged ones still in the table too.
std::string format_alarms(const ipc::AlarmStatus& a, bool all = false);

}  // namespace cnc::cli
