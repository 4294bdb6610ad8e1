#include "core/ipc/server.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <new>
#include <stdexcept>

#include "core/util/time.hpp"

namespace cnc::ipc {

namespace {

std::string user_name(uid_t uid) {
  char buf[4096];
  passwd pw{};
  passwd* found = nullptr;
  if (::getpwuid_r(uid, &pw, buf, sizeof buf, &found) == 0 && found) {
    return std::string(found->pw_name) + " (uid " + std::to_string(uid) + ")";
  }
  return "uid " + std::to_string(uid);
}

// /dev/shm is writable by everyone: a file another user put where the lock
// belongs (a symbolic link to make us create a file elsewhere, or a plain
// file to keep the controller from starting) is removed when we may (root),
// and named otherwise.
void clear_foreign_file(const std::string& path, const char* what) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return;
  const bool ours = S_ISREG(st.st_mode) && st.st_uid == ::geteuid();
  if (ours) return;
  if (::geteuid() == 0 && ::unlink(path.c_str()) == 0) return;
  throw std::runtime_error(std::string("cannot use ") + what + " " + path + ": it is " +
                           (S_ISLNK(st.st_mode) ? "a symbolic link" : S_ISREG(st.st_mode) ? "a file" : "a special file") +
                           " of " + user_name(st.st_uid) + ", not of this user; only that user or root can remove it");
}

}  // namespace

Server::Server(const std::string& instance, const AccessPolicy& access) : instance_(instance) {
  validate_instance_name(instance);
  const std::string lock = lock_path(instance);
  clear_foreign_file(lock, "the instance lock");
  lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (lock_fd_ < 0) throw std::runtime_error("cannot create lock file " + lock + ": " + std::strerror(errno));
  struct stat lst {};
  if (::fstat(lock_fd_, &lst) != 0 || !S_ISREG(lst.st_mode) || lst.st_uid != ::geteuid()) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw std::runtime_error("lock file " + lock + " changed owner while it was opened: refusing to start");
  }
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw std::runtime_error("another controller is already running on instance \"" + instance +
                             "\" (lock " + lock + " is held)");
  }
  // We hold the lock: any existing segment is a crashed controller's.
  ::shm_unlink(shm_name(instance).c_str());
  shm_fd_ = ::shm_open(shm_name(instance).c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (shm_fd_ < 0) {
    const int err = errno;
    struct stat sst {};
    const std::string path = "/dev/shm" + shm_name(instance);
    if (err == EEXIST && ::lstat(path.c_str(), &sst) == 0 && sst.st_uid != ::geteuid()) {
      throw std::runtime_error("cannot create shared segment " + path + ": it exists and belongs to " +
                               user_name(sst.st_uid) + "; only that user or root can remove it");
    }
    throw std::runtime_error("cannot create shared segment " + shm_name(instance) + ": " + std::strerror(err));
  }
  access.apply(shm_fd_, "the shared segment");  // whatever the umask
  if (::ftruncate(shm_fd_, sizeof(Segment)) != 0) {
    throw std::runtime_error("cannot size shared segment: " + std::string(std::strerror(errno)));
  }
  void* mem = ::mmap(nullptr, sizeof(Segment), PROT_READ | PROT_WRITE, MAP_SHARED, shm_fd_, 0);
  if (mem == MAP_FAILED) throw std::runtime_error("cannot map shared segment: " + std::string(std::strerror(errno)));
  seg_ = new (mem) Segment();
  SegmentHeader& h = seg_->header;
  h.layout_version = kLayoutVersion;
  h.segment_size = sizeof(Segment);
  h.owner_pid.store(::getpid());
  h.owner_start = process_start_time(::getpid()).value_or(0);
  h.instance.assign(instance);
  h.heartbeat_ns.store(monotonic_ns());
  std::atomic_thread_fence(std::memory_order_release);
  h.magic = kSegmentMagic;  // last: a client that sees the magic sees the rest
}

Server::~Server() {
  if (seg_) {
    seg_->header.ready.store(0);
    seg_->header.owner_pid.store(0);
    ::munmap(seg_, sizeof(Segment));
  }
  if (shm_fd_ >= 0) {
    ::close(shm_fd_);
    ::shm_unlink(shm_name(instance_).c_str());
  }
  if (lock_fd_ >= 0) {
    ::unlink(lock_path(instance_).c_str());
    ::close(lock_fd_);
  }
}

void Server::set_ready(bool ready) noexcept { seg_->header.ready.store(ready ? 1 : 0, std::memory_order_release); }

void Server::publish(const Status& status) noexcept {
  Status copy = status;
  copy.echo = echo_;
  seg_->status.write(copy);
  seg_->header.heartbeat_ns.store(monotonic_ns(), std::memory_order_release);
}

bool Server::poll_command(Command& out) noexcept {
  const int64_t now = monotonic_ns();
  if (now - last_reap_ns_ > 500'000'000) {
    reap_dead_clients();
    last_reap_ns_ = now;
  }
  for (int k = 0; k < kMaxClients; ++k) {
    const int i = (next_client_ + k) % kMaxClients;
    ClientChannel& ch = seg_->clients[i];
    if (ch.owner_pid.load(std::memory_order_acquire) == 0 && ch.ring.size() == 0) continue;
    if (ch.ring.pop(out)) {
      next_client_ = (i + 1) % kMaxClients;
      report(out, CommandState::Received);
      return true;
    }
  }
  return false;
}

void Server::reap_dead_clients() noexcept {
  for (ClientChannel& ch : seg_->clients) {
    const int32_t pid = ch.owner_pid.load(std::memory_order_acquire);
    const uint64_t start = ch.owner_start.load(std::memory_order_acquire);
    if (pid == 0 || start == 0) continue;  // free, or being claimed right now
    if (!process_alive(pid, start)) {
      // Commands a dead client left behind are still taken: they were sent.
      if (ch.ring.size() == 0) {
        ch.owner_start.store(0, std::memory_order_release);
        ch.owner_pid.store(0, std::memory_order_release);
      }
    }
  }
}

int Server::clients_connected() const noexcept {
  int n = 0;
  for (const ClientChannel& ch : seg_->clients) n += ch.owner_pid.load() != 0 ? 1 : 0;
  return n;
}

void Server::report(const Command& cmd, CommandState state, std::string_view reason) noexcept {
  CommandResult r;
  r.serial = cmd.serial;
  r.type = cmd.type;
  r.state = state;
  r.time_ns = realtime_ns();
  r.reason.assign(reason);
  seg_->results.write(r);
  if (cmd.serial >= echo_.serial) {
    echo_.serial = cmd.serial;
    echo_.state = state;
    echo_.type = cmd.type;
  }
}

void Server::post(const Message& m) noexcept { seg_->messages.write(m); }

}  // namespace cnc::ipc
