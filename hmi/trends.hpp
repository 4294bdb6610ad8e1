// Live trends (the drive page's plots): the last few seconds of a value,
// sampled at the screen's cycle, oldest first. No Qt: the page copies the
// points into its charts.
#pragma once

#include <cstddef>
#include <deque>
#include <utility>

namespace cnc::hmi {

class Trend {
 public:
  Trend() = default;
  Trend(double window_s, std::size_t max_points) : window_s_(window_s), max_points_(max_points) {}
  // A sample at time t (seconds, increasing); drops those older than the
  // window before t and the oldest beyond max_points. A time that goes
  // backwards (a new screen clock) starts the trend again.
  void add(double t_s, double value);
  void clear() { points_.clear(); }
  const std::deque<std::pair<double, double>>& points() const noexcept { return points_; }
  // Range of the values kept (0, 0 when empty).
  std::pair<double, double> range() const;
  double window_s() const noexcept { return window_s_; }

 private:
  double window_s_ = 30.0;
  std::size_t max_points_ = 3000;
  std::deque<std::pair<double, double>> points_;
};

// The three plots of one drive.
struct DriveTrends {
  Trend following_error;  // machine units (joint units; the spindle: none)
  Trend torque;           // % of rated torque
  Trend velocity;         // as the page shows it (units/s, spindle rpm)
};

}  // namespace cnc::hmi
