// Single-producer single-consumer ring for trivially copyable entries:
// task -> servo thread commands, and (in shared memory) one client's
// commands to the controller. push, front and pop never block and never
// allocate.
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace cnc {

template <class T, std::size_t N>
class SpscRing {
  static_assert((N & (N - 1)) == 0, "capacity must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  void reset() noexcept {
    head_.store(0, std::memory_order_relaxed);
    tail_.store(0, std::memory_order_relaxed);
  }
  bool push(const T& v) noexcept {
    const uint64_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_.load(std::memory_order_acquire) >= N) return false;
    items_[h & (N - 1)] = v;
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  // The oldest entry without taking it, or nullptr when empty (consumer only).
  const T* front() const noexcept {
    const uint64_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return nullptr;
    return &items_[t & (N - 1)];
  }
  // Drops the entry front() returned (consumer only).
  void pop_front() noexcept { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  bool pop(T& out) noexcept {
    const uint64_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return false;
    out = items_[t & (N - 1)];
    tail_.store(t + 1, std::memory_order_release);
    return true;
  }
  static constexpr std::size_t capacity() noexcept { return N; }
  std::size_t size() const noexcept {
    return static_cast<std::size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }

 private:
  alignas(64) std::atomic<uint64_t> head_{0};
  alignas(64) std::atomic<uint64_t> tail_{0};
  T items_[N];
};

}  // namespace cnc
