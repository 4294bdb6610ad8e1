// Single-writer sequence lock for trivially copyable blocks, usable inside
// shared memory. Readers never block the writer and never return a torn copy.
// Realtime-safe on the writer side: no allocation, no system call, no lock.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

#include "core/util/time.hpp"

namespace cnc {

template <class T>
class SeqLock {
  static_assert(std::is_trivially_copyable_v<T>, "SeqLock holds trivially copyable blocks only");
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

 public:
  SeqLock() { for (auto& w : words_) w.store(0, std::memory_order_relaxed); }

  // Writer (one thread only).
  void write(const T& value) noexcept {
    const uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_release);
    uint64_t buf[kWords] = {};
    std::memcpy(buf, &value, sizeof(T));
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(buf[i], std::memory_order_relaxed);
    seq_.store(s + 2, std::memory_order_release);
  }

  // Reader (not for the servo thread: it may yield): copies a consistent
  // block. Returns false only if the writer kept the block busy for longer
  // than `timeout_ns` (a writer that died in the middle of a write).
  bool try_read(T& out, int64_t timeout_ns = 500'000'000) const noexcept {
    uint64_t buf[kWords];
    int64_t deadline = 0;
    for (unsigned attempt = 0;; ++attempt) {
      if (attempt >= 64) {
        // The writer is busy or was preempted in a write: give it the CPU.
        const int64_t now = monotonic_ns();
        if (deadline == 0) deadline = now + timeout_ns;
        else if (now > deadline) return false;
        std::this_thread::yield();
      }
      const uint64_t s1 = seq_.load(std::memory_order_acquire);
      if (s1 & 1U) continue;
      for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s1) {
        std::memcpy(&out, buf, sizeof(T));
        return true;
      }
    }
    return false;
  }

  // Reader for the servo thread: one attempt, never waits. Returns false
  // (and leaves `out` alone) when the writer is in the middle of a write;
  // the caller keeps its previous copy and tries again next cycle.
  bool try_read_once(T& out) const noexcept {
    uint64_t buf[kWords];
    const uint64_t s1 = seq_.load(std::memory_order_acquire);
    if (s1 & 1U) return false;
    for (std::size_t i = 0; i < kWords; ++i) buf[i] = words_[i].load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (seq_.load(std::memory_order_relaxed) != s1) return false;
    std::memcpy(&out, buf, sizeof(T));
    return true;
  }

  T read() const noexcept {
    T out{};
    try_read(out);
    return out;
  }

  // Number of completed writes (even values only); changes on every write.
  uint64_t generation() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  alignas(64) std::atomic<uint64_t> seq_{0};
  std::atomic<uint64_t> words_[kWords];
};

}  // namespace cnc
