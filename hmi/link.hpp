// The screen's only way to the controller: a status source, a command sink
// and the message channel, behind an interface so that widget tests run
// against a fake. ClientLink is the real one over ipc::Client (the shared
// segment); it never blocks: send() queues on the client's own channel and
// poll_result() only looks at answers already published. It reconnects when
// the controller restarts.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "core/ipc/estop.hpp"
#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"

namespace cnc::ipc {
class Client;
}

namespace cnc::hmi {

class MachineLink {
 public:
  virtual ~MachineLink() = default;
  // A consistent status copy; false (with the reason) when no controller
  // answers.
  virtual bool read_status(ipc::Status& out, std::string& why) = 0;
  // Queues a command; its serial, or nullopt with the reason.
  virtual std::optional<uint32_t> send(const ipc::Command& cmd, std::string& why) = 0;
  // The newest state of a command sent by this link (state None: no answer
  // yet). Done and Rejected are reported once.
  virtual ipc::CommandResult poll_result(uint32_t serial) = 0;
  // The next message of the error channel, in order.
  virtual bool next_message(Message& out, uint64_t& lost) = 0;
  // E-stop through the segment's E-stop word: acted on by motion in the
  // servo thread, without a command channel or the task cycle. False (with
  // the reason) when no controller is connected.
  virtual bool request_estop(std::string& why) = 0;
  // How fresh `s` (just read) is: task cycle and servo heartbeat.
  virtual ipc::Liveness liveness(const ipc::Status& s) = 0;
};

class ClientLink final : public MachineLink {
 public:
  explicit ClientLink(std::string instance);
  ~ClientLink() override;
  bool read_status(ipc::Status& out, std::string& why) override;
  std::optional<uint32_t> send(const ipc::Command& cmd, std::string& why) override;
  ipc::CommandResult poll_result(uint32_t serial) override;
  bool next_message(Message& out, uint64_t& lost) override;
  bool request_estop(std::string& why) override;
  ipc::Liveness liveness(const ipc::Status& s) override;
  const std::string& instance() const noexcept { return instance_; }

 private:
  bool connect(std::string& why);
  void drop();

  std::string instance_;
  std::unique_ptr<ipc::Client> client_;
  int64_t next_attempt_ns_ = 0;
  std::string last_error_;
};

}  // namespace cnc::hmi
