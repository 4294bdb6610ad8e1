// Turning the status block into text a person reads and into JSON, for the
// command-line client (and its tests).
#pragma once

#include <string>

#include "core/ipc/status.hpp"

namespace cnc::cli {

std::string format_status(const ipc::Status& s);
std::string status_json(const ipc::Status& s, int indent = 2);

}  // namespace cnc::cli
