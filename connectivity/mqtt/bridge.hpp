// The MQTT bridge's logic (docs/connectivity.md), apart from the broker
// connection: what it publishes for a status (state, positions, program
// events) and how it checks and turns a command message into a command.
#pragma once

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"

namespace cnc::mqtt {

// The retained machine state: published when it changes.
std::string state_json(const ipc::Status& s);
// Positions (commanded and actual, machine coordinates) and velocity.
std::string position_json(const ipc::Status& s, uint32_t axis_mask);
std::string message_json(const Message& m);

// Program events from one status to the next: "opened", "started",
// "paused", "resumed", "finished" (with the line and the elapsed time).
std::vector<std::string> program_events(const ipc::Status* before, const ipc::Status& now);

// The commands a command message may name (the whitelist picks among them).
const std::vector<std::string>& command_names();

struct CommandRequest {
  std::string id;       // echoed in the result
  std::string name;
  ipc::Command command;
  bool estop = false;   // goes through the segment's E-stop word first
};

// Checks a command message {"token", "command", "args", "id"} against the
// token and the whitelist and builds the command. Throws
// std::invalid_argument with the reason when it is refused.
CommandRequest parse_command(const std::string& payload, const std::string& token,
                             const std::set<std::string>& allowed);

}  // namespace cnc::mqtt
