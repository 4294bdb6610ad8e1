// What the path builder hands to the servo side: programmed segments,
// smoothing vertices and "pieces" (spans of the smoothed path with their
// speed, acceleration and jerk limits), each in a single-producer /
// single-consumer slot ring that the consumer keeps items in until it
// releases them. Also the commands the servo thread sends to a builder that
// runs on its own thread. Plain data and lock-free rings: realtime-safe.
#pragma once

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>

#include "core/tp/blend.hpp"
#include "core/tp/planner.hpp"

namespace cnc::tp {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
// Limits are planned this far inside the configured ones: room for rounding
// and for the difference between derivatives and finite differences.
inline constexpr double kLimitMargin = 0.999;
// Share of every axis's acceleration and jerk a piece's velocity ceiling
// leaves for speeding up and braking along the path.
inline constexpr double kCeilingReserve = 0.2;

struct SegmentRecord {
  Curve curve;
  double s0 = 0;  // global path position of the start
  MotionType type = MotionType::Feed;
  int32_t line = 0;
  uint32_t id = 0;
  uint32_t epoch = 0;
  StateTag tag;
};

enum class StopKind : uint8_t { None, Stop, Dwell };

// Bounds, over one piece, of the smoothed path's first three derivatives
// with respect to the path parameter: per axis, and (in lin*) of their XYZ
// norm for [TRAJ]MAX_LINEAR_* limits. What the servo side turns into the
// tangential acceleration available at a given velocity.
struct PieceBounds {
  AxisVec c1{};
  AxisVec c2{};
  AxisVec c3{};
  double lin1 = 0, lin2 = 0, lin3 = 0;
};

struct Piece {
  double s0 = 0;       // global start; the piece spans [s0, s0 + length]
  double length = 0;   // 0 for a stop point
  uint64_t seg = 0;    // segment whose curve this span follows
  uint64_t v_lo = 0;   // vertices [v_lo, v_hi) may smooth this span
  uint64_t v_hi = 0;
  double v_hard = 0;     // path-velocity ceiling from geometry and the limits
  double v_feed = kInf;  // programmed feed (overridable), as path velocity
  double v_rapid = kInf; // requested rapid velocity, as path velocity
  double inv_speed = 1;  // 1 / max |dC/ds| in the length group (max-velocity cap)
  double a_cap = kInf;   // tangential acceleration cap of the move (SET_LINE acc)
  PieceBounds bounds;
  double dwell_s = 0;
  bool spindle_wait = false;  // a dwell stop that also waits for the spindles to be at speed
  uint32_t inputs_done = 0;  // input moves finished once this piece is passed
  uint32_t epoch = 0;
  StopKind stop = StopKind::None;
  bool probe = false;
};

// Single producer, single consumer; the consumer keeps what it has read
// until it releases it, so the ring doubles as the consumer's storage.
template <class T>
class SlotRing {
 public:
  explicit SlotRing(std::size_t min_capacity) {
    std::size_t c = 2;
    while (c < min_capacity) c *= 2;
    capacity_ = c;
    slots_ = std::make_unique<T[]>(c);
  }
  std::size_t capacity() const noexcept { return capacity_; }

  // Producer side.
  bool has_room(std::size_t n = 1) const noexcept {
    return head_ - released_.load(std::memory_order_acquire) + n <= capacity_;
  }
  uint64_t head() const noexcept { return head_; }
  T& push_slot() noexcept { return slots_[head_++ & (capacity_ - 1)]; }
  void publish() noexcept { published_.store(head_, std::memory_order_release); }

  // Consumer side.
  uint64_t published() const noexcept { return published_.load(std::memory_order_acquire); }
  const T& at(uint64_t seq) const noexcept { return slots_[seq & (capacity_ - 1)]; }
  T& at(uint64_t seq) noexcept { return slots_[seq & (capacity_ - 1)]; }
  uint64_t released() const noexcept { return released_.load(std::memory_order_relaxed); }
  void release_upto(uint64_t seq) noexcept {
    if (seq > released_.load(std::memory_order_relaxed)) released_.store(seq, std::memory_order_release);
  }

 private:
  std::size_t capacity_ = 0;
  std::unique_ptr<T[]> slots_;
  uint64_t head_ = 0;  // producer only
  alignas(64) std::atomic<uint64_t> published_{0};
  alignas(64) std::atomic<uint64_t> released_{0};
};

struct PathStore {
  PathStore(std::size_t segments, std::size_t vertices, std::size_t pieces)
      : segs(segments), verts(vertices), pieces(pieces) {}
  SlotRing<SegmentRecord> segs;
  SlotRing<Vertex> verts;
  SlotRing<Piece> pieces;
};

// Servo thread -> builder thread.
enum class CommandKind : uint8_t { Line, Circle, Dwell, SetPosition, SetConfig, Flush, Reset };

struct Command {
  CommandKind kind = CommandKind::Line;
  Pose pose;  // end point, or the new position
  std::array<double, 3> center{};
  std::array<double, 3> normal{};
  int turns = 0;
  double seconds = 0;
  SegmentParams params;
  PlannerConfig config;  // SetConfig only
  uint64_t config_gen = 0;  // SetConfig only: which configuration (Executor::set_prepare_config)
  uint32_t epoch = 0;
};

}  // namespace cnc::tp
