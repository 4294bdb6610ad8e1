// Segment tree over the servo side's piece ring: per piece the velocity
// ceilings (hard, feed, rapid, max-velocity factor), the tangential
// acceleration and jerk limits and the barrier flag. Answers "first piece
// after i whose ceiling under the current overrides is below x (or that is a
// barrier)" and range minima in O(log n). Realtime-safe after construction.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

namespace cnc::tp {

struct TreeLeaf {
  double hard;
  double feed;
  double rapid;
  double inv_speed;
  double accel;
  double jerk;
  bool barrier;
  bool stop;  // a stop point: motion never passes it without coming to rest
};

class LimitTree {
 public:
  // `size` must be a power of two.
  explicit LimitTree(std::size_t size);
  std::size_t size() const noexcept { return n_; }

  void set(std::size_t i, const TreeLeaf& leaf) noexcept;
  void set_hard(std::size_t i, double hard) noexcept;
  void clear(std::size_t i) noexcept;
  const TreeLeaf& leaf(std::size_t i) const noexcept { return node_[n_ + i]; }

  struct Query {
    double x = 0;           // ceiling threshold
    double feed_scale = 1;  // soft ceilings are multiplied by these...
    double rapid_scale = 1;
    double max_velocity = 1e300;  // ...and capped by inv_speed * max_velocity
    bool soft = true;       // false: hard ceilings and barriers only
  };
  // Value of a leaf under the query's overrides.
  static double value(const TreeLeaf& l, const Query& q) noexcept;

  // First index in [lo, hi) whose value is below q.x or that is a barrier;
  // -1 if none.
  int64_t find_first(std::size_t lo, std::size_t hi, const Query& q) const noexcept;
  // First stop point in [lo, hi); -1 if none.
  int64_t find_first_stop(std::size_t lo, std::size_t hi) const noexcept;
  // Last barrier index in [lo, hi); -1 if none.
  int64_t find_last_barrier(std::size_t lo, std::size_t hi) const noexcept;
  // Minimum tangential acceleration and jerk over [lo, hi) (+inf if empty).
  void range_limits(std::size_t lo, std::size_t hi, double& accel, double& jerk) const noexcept;
  // Minimum value under q over [lo, hi).
  double range_value(std::size_t lo, std::size_t hi, const Query& q) const noexcept;

 private:
  bool matches(std::size_t node, const Query& q) const noexcept;
  void pull(std::size_t node) noexcept;
  int64_t descend_first(std::size_t node, const Query& q) const noexcept;
  int64_t descend_last_barrier(std::size_t node) const noexcept;

  std::size_t n_;
  std::unique_ptr<TreeLeaf[]> node_;
};

}  // namespace cnc::tp
