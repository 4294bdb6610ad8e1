#include "hmi/link.hpp"

#include "core/ipc/client.hpp"
#include "core/util/time.hpp"

namespace cnc::hmi {

ClientLink::ClientLink(std::string instance) : instance_(std::move(instance)) {}
ClientLink::~ClientLink() = default;

bool ClientLink::connect(std::string& why) {
  if (client_) return true;
  const int64_t now = monotonic_ns();
  if (now < next_attempt_ns_) {
    why = last_error_;
    return false;
  }
  next_attempt_ns_ = now + 500'000'000;  // retry twice a second
  try {
    auto c = std::make_unique<ipc::Client>(instance_);
    if (!c->controller_ready()) {
      last_error_ = why = "controller starting";
      return false;
    }
    c->rewind_messages();  // show what was posted before the screen started
    client_ = std::move(c);
    return true;
  } catch (const std::exception& e) {
    last_error_ = why = e.what();
    return false;
  }
}

void ClientLink::drop() {
  client_.reset();
  next_attempt_ns_ = monotonic_ns() + 500'000'000;
}

bool ClientLink::read_status(ipc::Status& out, std::string& why) {
  if (!connect(why)) return false;
  try {
    if (!client_->controller_alive()) {
      why = "controller stopped";
      drop();
      return false;
    }
    out = client_->status();
    return true;
  } catch (const std::exception& e) {
    why = e.what();
    drop();
    return false;
  }
}

std::optional<uint32_t> ClientLink::send(const ipc::Command& cmd, std::string& why) {
  if (!connect(why)) return std::nullopt;
  try {
    uint32_t serial = 0;
    if (!client_->try_send(cmd, serial)) {
      why = "the command queue to the controller is full";
      return std::nullopt;
    }
    return serial;
  } catch (const std::exception& e) {
    why = e.what();
    drop();
    return std::nullopt;
  }
}

ipc::CommandResult ClientLink::poll_result(uint32_t serial) {
  if (!client_) {
    ipc::CommandResult r;
    r.serial = serial;
    r.reason.assign("controller not connected");
    return r;
  }
  return client_->wait(serial, std::chrono::milliseconds(0));
}

bool ClientLink::next_message(Message& out, uint64_t& lost) {
  if (!client_) return false;
  return client_->next_message(out, &lost);
}

bool ClientLink::request_estop(std::string& why) {
  if (!connect(why)) return false;
  try {
    client_->request_estop();
    return true;
  } catch (const std::exception& e) {
    why = e.what();
    drop();
    return false;
  }
}

ipc::Liveness ClientLink::liveness(const ipc::Status& s) {
  if (!client_) return {};
  return client_->liveness(s);
}

}  // namespace cnc::hmi
