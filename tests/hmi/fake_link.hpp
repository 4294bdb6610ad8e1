// A fake controller for the screen's tests: a status the test writes, a
// recording command sink whose answers the test scripts (by default every
// command is Done at the next poll), and a message queue.
#pragma once

#include <deque>
#include <map>
#include <string>
#include <vector>

#include "hmi/link.hpp"

namespace cnc::hmi::testing {

class FakeLink : public MachineLink {
 public:
  ipc::Status status{};
  bool connected = true;
  bool accept_sends = true;
  // Answer given to every new command unless `answers` says otherwise.
  ipc::CommandState default_answer = ipc::CommandState::Done;
  std::map<ipc::CommandType, std::pair<ipc::CommandState, std::string>> answers;
  std::vector<ipc::Command> sent;
  std::deque<Message> messages;
  int estop_requests = 0;         // E-stops through the segment's word
  ipc::Liveness live{};           // what liveness() reports

  FakeLink() {
    status.task.available = true;
    status.motion.joints = 3;
    status.motion.linear_units = 1;
    status.motion.axis_mask = 0x7;
    status.io.estop_chain_ok = true;
    for (int j = 0; j < 3; ++j) status.joints[j].axis = static_cast<int8_t>(j);
    status.motion.feed_scale = status.motion.rapid_scale = 1;
    status.spindles[0].override_scale = 1;
    status.task.program_units = 2;
  }

  void set_on(bool homed = true, ipc::TaskMode mode = ipc::TaskMode::Manual) {
    status.task.state = ipc::TaskState::On;
    status.task.mode = mode;
    status.motion.enabled = true;
    for (int j = 0; j < 3; ++j) status.joints[j].homed = homed;
  }

  bool read_status(ipc::Status& out, std::string& why) override {
    if (!connected) {
      why = "controller not running (fake)";
      return false;
    }
    out = status;
    return true;
  }
  std::optional<uint32_t> send(const ipc::Command& cmd, std::string& why) override {
    if (!connected || !accept_sends) {
      why = "refused by the fake";
      return std::nullopt;
    }
    ipc::Command c = cmd;
    c.serial = next_serial_++;
    sent.push_back(c);
    const auto it = answers.find(c.type);
    ipc::CommandResult r;
    r.serial = c.serial;
    r.type = c.type;
    r.state = it != answers.end() ? it->second.first : default_answer;
    if (it != answers.end()) r.reason.assign(it->second.second);
    results_[c.serial] = r;
    return c.serial;
  }
  ipc::CommandResult poll_result(uint32_t serial) override {
    ipc::CommandResult r;
    r.serial = serial;
    const auto it = results_.find(serial);
    if (it == results_.end()) return r;
    r = it->second;
    if (r.state == ipc::CommandState::Done || r.state == ipc::CommandState::Rejected) results_.erase(it);
    return r;
  }
  bool next_message(Message& out, uint64_t& lost) override {
    lost = 0;
    if (messages.empty()) return false;
    out = messages.front();
    messages.pop_front();
    return true;
  }

  bool request_estop(std::string& why) override {
    if (!connected) {
      why = "controller not running (fake)";
      return false;
    }
    ++estop_requests;
    return true;
  }
  ipc::Liveness liveness(const ipc::Status&) override { return live; }

  // Finishes a command left Executing/None.
  void answer(uint32_t serial, ipc::CommandState state, const std::string& reason = {}) {
    results_[serial].serial = serial;
    results_[serial].state = state;
    results_[serial].reason.assign(reason);
  }
  void post(MessageKind kind, const std::string& text, const std::string& source = "test") {
    Message m;
    m.kind = kind;
    m.text.assign(text);
    m.source.assign(source);
    m.time_ns = 1'700'000'000'000'000'000;
    messages.push_back(m);
  }
  std::vector<ipc::Command> sent_of(ipc::CommandType t) const {
    std::vector<ipc::Command> out;
    for (const auto& c : sent) {
      if (c.type == t) out.push_back(c);
    }
    return out;
  }
  void clear_sent() { sent.clear(); }

 private:
  uint32_t next_serial_ = 1;
  std::map<uint32_t, ipc::CommandResult> results_;
};

}  // namespace cnc::hmi::testing
