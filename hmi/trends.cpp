#include "hmi/trends.hpp"

#include <algorithm>

namespace cnc::hmi {

void Trend::add(double t_s, double value) {
  if (!points_.empty() && t_s < points_.back().first) points_.clear();
  points_.emplace_back(t_s, value);
  while (!points_.empty() && points_.front().first < t_s - window_s_) points_.pop_front();
  while (points_.size() > max_points_) points_.pop_front();
}

std::pair<double, double> Trend::range() const {
  if (points_.empty()) return {0.0, 0.0};
  double lo = points_.front().second, hi = lo;
  for (const auto& p : points_) {
    lo = std::min(lo, p.second);
    hi = std::max(hi, p.second);
  }
  return {lo, hi};
}

}  // namespace cnc::hmi
