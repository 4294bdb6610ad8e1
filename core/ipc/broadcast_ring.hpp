// One writer, any number of readers that each keep their own cursor: the
// message channel and the command-result channel of the shared segment.
// A reader that falls more than N entries behind learns how many it lost
// and continues with the oldest entry still held. Lives in shared memory.
#pragma once

#include <atomic>
#include <cstdint>

#include "core/util/seqlock.hpp"

namespace cnc::ipc {

template <class T, std::size_t N>
class BroadcastRing {
  static_assert((N & (N - 1)) == 0, "capacity must be a power of two");

 public:
  enum class ReadResult { Ok, Empty, Lost };

  // Writer (one thread of one process).
  void write(const T& value) noexcept {
    const uint64_t index = head_.load(std::memory_order_relaxed);
    slots_[index & (N - 1)].write(Entry{index, value});
    head_.store(index + 1, std::memory_order_release);
  }

  // Index the next write will get: a new reader starts here to see only
  // what comes after it.
  uint64_t head() const noexcept { return head_.load(std::memory_order_acquire); }

  // Reads the entry at `cursor` and advances it. Lost: entries were
  // overwritten before they were read; `lost` says how many, and the cursor
  // has moved to the oldest entry still available (call again to read it).
  ReadResult read(uint64_t& cursor, T& out, uint64_t* lost = nullptr) const noexcept {
    const uint64_t h = head_.load(std::memory_order_acquire);
    if (cursor >= h) return ReadResult::Empty;
    if (h - cursor > N) {
      if (lost) *lost = h - N - cursor;
      cursor = h - N;
      return ReadResult::Lost;
    }
    Entry e;
    if (!slots_[cursor & (N - 1)].try_read(e) || e.index != cursor) {
      // Overwritten while we were reading: the writer lapped us.
      if (lost) *lost = 1;
      ++cursor;
      return ReadResult::Lost;
    }
    out = e.value;
    ++cursor;
    return ReadResult::Ok;
  }

  static constexpr std::size_t capacity() noexcept { return N; }

 private:
  struct Entry {
    uint64_t index;
    T value;
  };
  std::atomic<uint64_t> head_{0};
  SeqLock<Entry> slots_[N];
};

}  // namespace cnc::ipc
