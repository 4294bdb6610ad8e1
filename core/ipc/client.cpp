#include "core/ipc/client.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include "core/util/time.hpp"

namespace cnc::ipc {

Client::Client(const std::string& instance) : instance_(instance) {
  validate_instance_name(instance);
  fd_ = ::shm_open(shm_name(instance).c_str(), O_RDWR | O_CLOEXEC, 0);
  if (fd_ < 0) {
    if (errno == ENOENT) throw ClientError("controller not running (instance \"" + instance + "\")");
    throw ClientError("cannot open the controller's shared segment " + shm_name(instance) + ": " + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || st.st_size < static_cast<off_t>(sizeof(SegmentHeader))) {
    ::close(fd_);
    throw ClientError("controller not running (instance \"" + instance + "\": segment is empty or being created)");
  }
  if (static_cast<std::size_t>(st.st_size) != sizeof(Segment)) {
    // Read the header alone to say which version it is.
    void* hm = ::mmap(nullptr, sizeof(SegmentHeader), PROT_READ, MAP_SHARED, fd_, 0);
    uint32_t version = 0;
    if (hm != MAP_FAILED) {
      version = static_cast<SegmentHeader*>(hm)->layout_version;
      ::munmap(hm, sizeof(SegmentHeader));
    }
    ::close(fd_);
    throw ClientError("the controller on instance \"" + instance + "\" uses shared-segment layout version " +
                      std::to_string(version) + " (" + std::to_string(st.st_size) + " bytes); this client expects version " +
                      std::to_string(kLayoutVersion) + " (" + std::to_string(sizeof(Segment)) +
                      " bytes): use the client programs built with that controller");
  }
  void* mem = ::mmap(nullptr, sizeof(Segment), PROT_READ | PROT_WRITE, MAP_SHARED, fd_, 0);
  if (mem == MAP_FAILED) {
    ::close(fd_);
    throw ClientError("cannot map the controller's shared segment: " + std::string(std::strerror(errno)));
  }
  seg_ = static_cast<Segment*>(mem);
  const SegmentHeader& h = seg_->header;
  if (h.magic != kSegmentMagic || h.layout_version != kLayoutVersion) {
    const uint32_t v = h.layout_version;
    ::munmap(seg_, sizeof(Segment));
    ::close(fd_);
    seg_ = nullptr;
    throw ClientError("the controller on instance \"" + instance + "\" uses shared-segment layout version " +
                      std::to_string(v) + "; this client expects version " + std::to_string(kLayoutVersion));
  }
  try {
    check_alive();
  } catch (...) {
    ::munmap(seg_, sizeof(Segment));
    ::close(fd_);
    seg_ = nullptr;
    throw;
  }
  results_cursor_ = seg_->results.head();
  messages_cursor_ = seg_->messages.head();
}

int32_t Client::owner_pid() const { return seg_->header.owner_pid.load(std::memory_order_acquire); }

Client::~Client() {
  if (seg_) {
    if (channel_ >= 0) {
      // Let the controller take what is queued before the channel is freed.
      ClientChannel& ch = seg_->clients[channel_];
      for (int i = 0; i < 100 && ch.ring.size() > 0 && controller_alive(); ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      ch.owner_start.store(0, std::memory_order_release);
      ch.owner_pid.store(0, std::memory_order_release);
    }
    ::munmap(seg_, sizeof(Segment));
  }
  if (fd_ >= 0) ::close(fd_);
}

bool Client::controller_alive() const {
  const int32_t pid = seg_->header.owner_pid.load(std::memory_order_acquire);
  return pid != 0 && process_alive(pid, seg_->header.owner_start);
}

bool Client::controller_ready() const {
  return controller_alive() && seg_->header.ready.load(std::memory_order_acquire) == 1;
}

void Client::check_alive() const {
  const int32_t pid = seg_->header.owner_pid.load(std::memory_order_acquire);
  if (pid == 0) throw ClientError("controller not running (instance \"" + instance_ + "\" has shut down)");
  if (!process_alive(pid, seg_->header.owner_start)) {
    throw ClientError("controller not running (instance \"" + instance_ + "\": its process " + std::to_string(pid) +
                      " is gone and left a stale segment)");
  }
}

Status Client::status() const {
  Status s;
  if (!seg_->status.try_read(s)) {
    check_alive();
    throw ClientError("controller not responding (status block stays busy)");
  }
  return s;
}

void Client::claim_channel() {
  const int32_t pid = ::getpid();
  const uint64_t start = process_start_time(pid).value_or(0);
  for (int i = 0; i < kMaxClients; ++i) {
    ClientChannel& ch = seg_->clients[i];
    int32_t expected = 0;
    if (ch.ring.size() == 0 && ch.owner_pid.compare_exchange_strong(expected, pid)) {
      ch.owner_start.store(start);
      channel_ = i;
      return;
    }
  }
  throw ClientError("too many clients connected to the controller (" + std::to_string(kMaxClients) + ")");
}

bool Client::try_send(Command cmd, uint32_t& serial) {
  check_alive();
  if (channel_ < 0) claim_channel();
  if (seg_->clients[channel_].ring.size() >= kClientQueueDepth) return false;
  cmd.serial = seg_->header.next_serial.fetch_add(1);
  cmd.client_pid = ::getpid();
  cmd.time_ns = realtime_ns();
  if (!seg_->clients[channel_].ring.push(cmd)) return false;
  serial = cmd.serial;
  return true;
}

uint32_t Client::send(Command cmd) {
  uint32_t serial = 0;
  if (!try_send(cmd, serial)) {
    throw ClientError("command queue full (" + std::to_string(kClientQueueDepth) +
                      " commands not yet taken by the controller)");
  }
  return serial;
}

void Client::drain_results() {
  CommandResult r;
  for (;;) {
    const auto rr = seg_->results.read(results_cursor_, r);
    if (rr == BroadcastRing<CommandResult, 256>::ReadResult::Empty) break;
    if (rr == BroadcastRing<CommandResult, 256>::ReadResult::Ok) results_[r.serial] = r;
  }
}

CommandResult Client::wait(uint32_t serial, std::chrono::milliseconds timeout) {
  const int64_t deadline = monotonic_ns() + static_cast<int64_t>(timeout.count()) * 1'000'000;
  for (;;) {
    drain_results();
    const auto it = results_.find(serial);
    if (it != results_.end() &&
        (it->second.state == CommandState::Done || it->second.state == CommandState::Rejected)) {
      CommandResult r = it->second;
      results_.erase(it);
      return r;
    }
    if (monotonic_ns() > deadline || !controller_alive()) {
      if (it != results_.end()) return it->second;
      CommandResult none;
      none.serial = serial;
      if (!controller_alive()) none.reason.assign("controller stopped before answering");
      return none;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
}

CommandResult Client::execute(const Command& cmd, std::chrono::milliseconds timeout) {
  return wait(send(cmd), timeout);
}

bool Client::next_message(Message& out, uint64_t* lost) {
  for (;;) {
    uint64_t n = 0;
    const auto rr = seg_->messages.read(messages_cursor_, out, &n);
    if (rr == BroadcastRing<Message, 256>::ReadResult::Ok) return true;
    if (rr == BroadcastRing<Message, 256>::ReadResult::Empty) return false;
    if (lost) *lost += n;
  }
}

void Client::rewind_messages() {
  const uint64_t h = seg_->messages.head();
  const uint64_t n = BroadcastRing<Message, 256>::capacity();
  messages_cursor_ = h > n ? h - n : 0;
}

uint64_t Client::request_estop() {
  check_alive();
  return bump_estop_request(seg_->header.estop, ::getpid());
}

bool Client::wait_estop_acknowledged(uint64_t request, std::chrono::milliseconds timeout) const {
  const int64_t deadline = monotonic_ns() + static_cast<int64_t>(timeout.count()) * 1'000'000;
  for (;;) {
    if (estop_acknowledges(seg_->header.estop.acknowledged.load(std::memory_order_acquire), request)) return true;
    if (monotonic_ns() > deadline || !controller_alive()) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
}

Liveness Client::liveness(const Status& s) const {
  return assess_liveness(monotonic_ns(), seg_->header.heartbeat_ns.load(std::memory_order_acquire),
                         seg_->header.estop.servo_heartbeat_ns.load(std::memory_order_acquire), s.health.task_cycle_ns,
                         s.motion.cycle_time_s);
}

Command make_command(CommandType type) {
  Command c;
  c.type = type;
  return c;
}

}  // namespace cnc::ipc
