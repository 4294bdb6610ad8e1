#include "core/tp/limit_tree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cnc::tp {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr TreeLeaf kEmpty{kInf, kInf, kInf, kInf, kInf, kInf, false, false};

double scaled(double v, double k) { return v == kInf ? kInf : v * k; }

}  // namespace

LimitTree::LimitTree(std::size_t size) : n_(size), node_(std::make_unique<TreeLeaf[]>(2 * size)) {
  for (std::size_t i = 0; i < 2 * n_; ++i) node_[i] = kEmpty;
}

void LimitTree::pull(std::size_t i) noexcept {
  const TreeLeaf& l = node_[2 * i];
  const TreeLeaf& r = node_[2 * i + 1];
  TreeLeaf& p = node_[i];
  p.hard = std::min(l.hard, r.hard);
  p.feed = std::min(l.feed, r.feed);
  p.rapid = std::min(l.rapid, r.rapid);
  p.inv_speed = std::min(l.inv_speed, r.inv_speed);
  p.accel = std::min(l.accel, r.accel);
  p.jerk = std::min(l.jerk, r.jerk);
  p.barrier = l.barrier || r.barrier;
  p.stop = l.stop || r.stop;
}

void LimitTree::set(std::size_t i, const TreeLeaf& leaf) noexcept {
  std::size_t k = i + n_;
  node_[k] = leaf;
  for (k >>= 1; k >= 1; k >>= 1) pull(k);
}

void LimitTree::set_hard(std::size_t i, double hard) noexcept {
  std::size_t k = i + n_;
  node_[k].hard = hard;
  for (k >>= 1; k >= 1; k >>= 1) pull(k);
}

void LimitTree::clear(std::size_t i) noexcept { set(i, kEmpty); }

double LimitTree::value(const TreeLeaf& l, const Query& q) noexcept {
  double v = l.hard;
  if (q.soft) {
    v = std::min({v, scaled(l.feed, q.feed_scale), scaled(l.rapid, q.rapid_scale), scaled(l.inv_speed, q.max_velocity)});
  }
  return v;
}

bool LimitTree::matches(std::size_t i, const Query& q) const noexcept {
  const TreeLeaf& l = node_[i];
  return l.barrier || value(l, q) < q.x;
}

int64_t LimitTree::descend_first(std::size_t i, const Query& q) const noexcept {
  while (i < n_) {
    i = matches(2 * i, q) ? 2 * i : 2 * i + 1;
  }
  return static_cast<int64_t>(i - n_);
}

int64_t LimitTree::find_first(std::size_t lo, std::size_t hi, const Query& q) const noexcept {
  if (lo >= hi) return -1;
  // Left boundary nodes in order, right boundary nodes in reverse order.
  std::size_t left[64];
  std::size_t right[64];
  int nl = 0, nr = 0;
  for (std::size_t l = lo + n_, r = hi + n_; l < r; l >>= 1, r >>= 1) {
    if (l & 1) left[nl++] = l++;
    if (r & 1) right[nr++] = --r;
  }
  for (int i = 0; i < nl; ++i) {
    if (matches(left[i], q)) return descend_first(left[i], q);
  }
  for (int i = nr - 1; i >= 0; --i) {
    if (matches(right[i], q)) return descend_first(right[i], q);
  }
  return -1;
}

int64_t LimitTree::find_first_stop(std::size_t lo, std::size_t hi) const noexcept {
  if (lo >= hi) return -1;
  std::size_t left[64];
  std::size_t right[64];
  int nl = 0, nr = 0;
  for (std::size_t l = lo + n_, r = hi + n_; l < r; l >>= 1, r >>= 1) {
    if (l & 1) left[nl++] = l++;
    if (r & 1) right[nr++] = --r;
  }
  auto descend = [&](std::size_t i) {
    while (i < n_) i = node_[2 * i].stop ? 2 * i : 2 * i + 1;
    return static_cast<int64_t>(i - n_);
  };
  for (int i = 0; i < nl; ++i) {
    if (node_[left[i]].stop) return descend(left[i]);
  }
  for (int i = nr - 1; i >= 0; --i) {
    if (node_[right[i]].stop) return descend(right[i]);
  }
  return -1;
}

int64_t LimitTree::descend_last_barrier(std::size_t i) const noexcept {
  while (i < n_) i = node_[2 * i + 1].barrier ? 2 * i + 1 : 2 * i;
  return static_cast<int64_t>(i - n_);
}

int64_t LimitTree::find_last_barrier(std::size_t lo, std::size_t hi) const noexcept {
  if (lo >= hi) return -1;
  std::size_t left[64];
  std::size_t right[64];
  int nl = 0, nr = 0;
  for (std::size_t l = lo + n_, r = hi + n_; l < r; l >>= 1, r >>= 1) {
    if (l & 1) left[nl++] = l++;
    if (r & 1) right[nr++] = --r;
  }
  for (int i = 0; i < nr; ++i) {
    if (node_[right[i]].barrier) return descend_last_barrier(right[i]);
  }
  for (int i = nl - 1; i >= 0; --i) {
    if (node_[left[i]].barrier) return descend_last_barrier(left[i]);
  }
  return -1;
}

void LimitTree::range_limits(std::size_t lo, std::size_t hi, double& accel, double& jerk) const noexcept {
  accel = kInf;
  jerk = kInf;
  for (std::size_t l = lo + n_, r = hi + n_; l < r; l >>= 1, r >>= 1) {
    if (l & 1) {
      accel = std::min(accel, node_[l].accel);
      jerk = std::min(jerk, node_[l].jerk);
      ++l;
    }
    if (r & 1) {
      --r;
      accel = std::min(accel, node_[r].accel);
      jerk = std::min(jerk, node_[r].jerk);
    }
  }
}

double LimitTree::range_value(std::size_t lo, std::size_t hi, const Query& q) const noexcept {
  double v = kInf;
  for (std::size_t l = lo + n_, r = hi + n_; l < r; l >>= 1, r >>= 1) {
    if (l & 1) v = std::min(v, value(node_[l++], q));
    if (r & 1) v = std::min(v, value(node_[--r], q));
  }
  return v;
}

}  // namespace cnc::tp
