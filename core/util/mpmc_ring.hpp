// Bounded lock-free multi-producer multi-consumer ring (Vyukov's algorithm)
// for trivially copyable messages. Works between threads and, placed in
// shared memory, between processes. push/pop never allocate and never block:
// they return false when the ring is full or empty.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace cnc {

template <class T, std::size_t N>
class MpmcRing {
  static_assert((N & (N - 1)) == 0 && N >= 2, "capacity must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>);
  static_assert(std::atomic<uint64_t>::is_always_lock_free);

 public:
  MpmcRing() { reset(); }

  // Not thread-safe: only before the ring is shared.
  void reset() noexcept {
    for (std::size_t i = 0; i < N; ++i) cells_[i].seq.store(i, std::memory_order_relaxed);
    enqueue_.store(0, std::memory_order_relaxed);
    dequeue_.store(0, std::memory_order_relaxed);
  }

  bool push(const T& value) noexcept {
    uint64_t pos = enqueue_.load(std::memory_order_relaxed);
    for (;;) {
      Cell& cell = cells_[pos & (N - 1)];
      const uint64_t seq = cell.seq.load(std::memory_order_acquire);
      const auto diff = static_cast<int64_t>(seq) - static_cast<int64_t>(pos);
      if (diff == 0) {
        if (enqueue_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) {
          cell.value = value;
          cell.seq.store(pos + 1, std::memory_order_release);
          return true;
        }
      } else if (diff < 0) {
        return false;  // full
      } else {
        pos = enqueue_.load(std::memory_order_relaxed);
      }
    }
  }

  bool pop(T& out) noexcept {
    uint64_t pos = dequeue_.load(std::memory_order_relaxed);
    for (;;) {
      Cell& cell = cells_[pos & (N - 1)];
      const uint64_t seq = cell.seq.load(std::memory_order_acquire);
      const auto diff = static_cast<int64_t>(seq) - static_cast<int64_t>(pos + 1);
      if (diff == 0) {
        if (dequeue_.compare_exchange_weak(pos, pos + 1, std::memory_order_relaxed)) {
          out = cell.value;
          cell.seq.store(pos + N, std::memory_order_release);
          return true;
        }
      } else if (diff < 0) {
        return false;  // empty
      } else {
        pos = dequeue_.load(std::memory_order_relaxed);
      }
    }
  }

  // Approximate number of queued entries (exact when nobody is pushing/popping).
  std::size_t size_approx() const noexcept {
    const uint64_t e = enqueue_.load(std::memory_order_relaxed);
    const uint64_t d = dequeue_.load(std::memory_order_relaxed);
    return e > d ? static_cast<std::size_t>(e - d) : 0;
  }
  static constexpr std::size_t capacity() noexcept { return N; }

 private:
  struct alignas(64) Cell {
    std::atomic<uint64_t> seq;
    T value;
  };
  alignas(64) std::atomic<uint64_t> enqueue_{0};
  alignas(64) std::atomic<uint64_t> dequeue_{0};
  Cell cells_[N];
};

}  // namespace cnc
