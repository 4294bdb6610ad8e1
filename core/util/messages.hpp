// The in-process side of the error channel: any thread (the servo thread
// included) posts operator errors, texts and display messages; the daemon
// drains them into the shared segment's message ring. post() never
// allocates and never blocks; when the queue is full the message is counted
// as dropped instead.
#pragma once

#include <atomic>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <string_view>

#include "core/util/fixed_string.hpp"
#include "core/util/mpmc_ring.hpp"
#include "core/util/time.hpp"

namespace cnc {

// LinuxCNC's kinds: errors need acknowledging; texts inform; display
// messages are for a dialog ((DEBUG,...), (PRINT,...), MESSAGE_* pins).
enum class MessageKind : uint8_t { Error = 0, Text = 1, Display = 2 };

const char* to_string(MessageKind kind) noexcept;

struct Message {
  int64_t time_ns = 0;            // CLOCK_REALTIME
  MessageKind kind = MessageKind::Error;
  FixedString<48> source;         // "motion", "cia402.0.drive.01", "interp", ...
  FixedString<256> text;
};

class MessageQueue {
 public:
  static constexpr std::size_t kCapacity = 256;

  bool post(MessageKind kind, std::string_view source, std::string_view text) noexcept {
    Message m;
    m.time_ns = realtime_ns();
    m.kind = kind;
    m.source.assign(source);
    m.text.assign(text);
    return push(m);
  }

  __attribute__((format(printf, 4, 5))) bool postf(MessageKind kind, std::string_view source, const char* fmt,
                                                     ...) noexcept {
    Message m;
    m.time_ns = realtime_ns();
    m.kind = kind;
    m.source.assign(source);
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(m.text.data, sizeof m.text.data, fmt, ap);
    va_end(ap);
    return push(m);
  }

  bool pop(Message& out) noexcept { return ring_.pop(out); }
  uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  bool push(const Message& m) noexcept {
    if (ring_.push(m)) return true;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  MpmcRing<Message, kCapacity> ring_;
  std::atomic<uint64_t> dropped_{0};
};

inline const char* to_string(MessageKind kind) noexcept {
  switch (kind) {
    case MessageKind::Error: return "error";
    case MessageKind::Text: return "text";
    case MessageKind::Display: return "display";
  }
  return "?";
}

}  // namespace cnc
