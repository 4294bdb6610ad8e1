// Hold-to-run on a terminal: a commissioning motion runs while a key is held
// and stops when it is let go. A terminal reports no key release, only the
// key's auto-repeat; the motion stops when the repeats stop arriving.
// Never moves anything itself: on release it calls request_abort(), as
// Ctrl-C does.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include <termios.h>

namespace cnc::commission {

// When a held key counts as let go, from the times its characters arrived.
// The first repeat comes after the terminal's auto-repeat delay (250 ms on
// the Linux console, 660 ms under X by default), the next ones at its rate
// (25-30 a second): a key is let go when no character came for
// `first_gap_ns` after the first one, or for `repeat_gap_ns` after a repeat.
class HoldWatch {
 public:
  static constexpr int64_t kFirstGapNs = 1'000'000'000;
  static constexpr int64_t kRepeatGapNs = 250'000'000;
  HoldWatch(int64_t first_gap_ns = kFirstGapNs, int64_t repeat_gap_ns = kRepeatGapNs) noexcept
      : first_gap_ns_(first_gap_ns), repeat_gap_ns_(repeat_gap_ns) {}
  void key(int64_t t_ns) noexcept;
  bool is_held() const noexcept { return keys_ > 0; }
  // Whether the key was let go by `now_ns` (false before the first key).
  bool is_released(int64_t now_ns) const noexcept;

 private:
  int64_t first_gap_ns_, repeat_gap_ns_;
  int64_t last_ns_ = 0;
  int64_t keys_ = 0;
};

// How long a hold-to-run command waits for the first key before it gives up.
inline constexpr int64_t kHoldFirstKeyNs = 10'000'000'000;

// Puts the terminal `fd` in non-canonical, no-echo mode (restored by the
// destructor), waits for a key to be pressed, then watches it on a thread
// of its own and calls request_abort() once the key is let go (and again
// at each check after, until stopped). Throws std::runtime_error naming
// the problem when `fd` is no terminal or no key came within
// `wait_first_ns`.
class HoldToRun {
 public:
  HoldToRun(int fd, int64_t wait_first_ns, HoldWatch watch = HoldWatch());
  ~HoldToRun();
  HoldToRun(const HoldToRun&) = delete;
  HoldToRun& operator=(const HoldToRun&) = delete;
  // Whether the key was let go before the motion ended.
  bool was_released() const noexcept { return released_.load(); }

 private:
  void run() noexcept;
  int fd_;
  HoldWatch watch_;
  bool restore_ = false;
  termios saved_{};
  std::atomic<bool> stop_{false}, released_{false};
  std::thread thread_;
};

}  // namespace cnc::commission
