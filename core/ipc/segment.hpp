// The shared segment of one controller instance: header, status block,
// per-client command channels, command results and the message channel.
// One POSIX shared-memory object per instance (/dev/shm/cnc-<instance>),
// created mode 0660 by the controller; clients map it read-write to send
// commands. The layout is versioned: a client of another version is refused.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>

#include "core/ipc/broadcast_ring.hpp"
#include "core/ipc/command.hpp"
#include "core/ipc/estop.hpp"
#include "core/ipc/status.hpp"
#include "core/util/messages.hpp"
#include "core/util/seqlock.hpp"
#include "core/util/spsc_ring.hpp"

namespace cnc::ipc {

inline constexpr uint64_t kSegmentMagic = 0x31474553434e43ULL;  // "CNCSEG1"
// Bump whenever any structure in the segment changes.
inline constexpr uint32_t kLayoutVersion = 6;
inline constexpr int kMaxClients = 32;
inline constexpr std::size_t kClientQueueDepth = 16;

struct ClientChannel {
  std::atomic<int32_t> owner_pid{0};    // 0: free
  std::atomic<uint64_t> owner_start{0}; // process start time, guards against pid reuse
  SpscRing<Command, kClientQueueDepth> ring;
};

struct SegmentHeader {
  uint64_t magic = 0;
  uint32_t layout_version = 0;
  uint32_t reserved = 0;
  uint64_t segment_size = 0;
  std::atomic<int32_t> owner_pid{0};
  uint64_t owner_start = 0;
  std::atomic<uint32_t> ready{0};        // 1 once the controller is up
  std::atomic<uint32_t> next_serial{1};
  std::atomic<int64_t> heartbeat_ns{0};  // CLOCK_MONOTONIC of the last status publication (task cycle)
  EstopWords estop;                      // E-stop requests and the servo thread's heartbeat
  FixedString<64> instance;
};

struct Segment {
  SegmentHeader header;
  SeqLock<Status> status;
  ClientChannel clients[kMaxClients];
  BroadcastRing<CommandResult, 256> results;
  BroadcastRing<Message, 256> messages;
};

// Instance names: letters, digits, '-' and '_', 1 to 48 characters. Throws
// std::invalid_argument naming the problem.
void validate_instance_name(const std::string& instance);
std::string shm_name(const std::string& instance);          // "/cnc-<instance>"
std::string lock_path(const std::string& instance);         // /dev/shm/cnc-<instance>.lock
std::string admin_socket_path(const std::string& instance); // /dev/shm/cnc-<instance>.hal
// The instance from --instance, else $CNC_INSTANCE, else "default".
std::string default_instance();

// Start time of a process (from /proc/<pid>/stat), to tell a live owner from
// a reused pid; nullopt when the process does not exist.
std::optional<uint64_t> process_start_time(int pid);
bool process_alive(int pid, uint64_t start_time);

}  // namespace cnc::ipc
