#include "fieldbus/ethercat/dc.hpp"

#include <algorithm>

namespace cnc::ethercat {

std::vector<int64_t> line_delays(const std::vector<PortTimes>& t) {
  std::vector<int64_t> d(t.size(), 0);
  if (t.empty()) return d;
  auto loop = [](const PortTimes& p) -> int64_t {
    return p.port1_open ? static_cast<int64_t>(static_cast<uint32_t>(p.port1 - p.port0)) : 0;
  };
  const int64_t ref = loop(t[0]);
  for (std::size_t i = 1; i < t.size(); ++i) d[i] = (ref - loop(t[i])) / 2;
  return d;
}

std::vector<int64_t> system_offsets(const std::vector<PortTimes>& t, const std::vector<int64_t>& delays,
                                    int64_t reference_offset) {
  std::vector<int64_t> o(t.size(), reference_offset);
  for (std::size_t i = 1; i < t.size(); ++i) {
    o[i] = t[0].local_at_latch + reference_offset + delays[i] - t[i].local_at_latch;
  }
  return o;
}

void PhaseLock::reset() noexcept {
  started_ = false;
  integral_ = 0;
  inside_ = outside_ = 0;
  locked_ = false;
  offset_ = 0;
  stats_.reset();
  stats_all_.reset();
}

int64_t PhaseLock::update(int64_t st) noexcept {
  const int64_t c = o_.cycle_ns;
  int64_t e = ((st - o_.target_ns) % c + c) % c;
  if (e >= c / 2) e -= c;
  offset_ = e;
  const int64_t window = o_.lock_window_ns > 0 ? o_.lock_window_ns : c / 10;
  if (!started_) {
    started_ = true;
    return -e;  // one step onto the grid, then track
  }
  if (e > -window && e < window) {
    ++inside_;
    outside_ = 0;
    if (inside_ >= 100) locked_ = true;
  } else {
    ++outside_;
    inside_ = 0;
    if (outside_ >= 50) locked_ = false;
  }
  stats_all_.add(e);
  if (locked_) stats_.add(e);
  integral_ += o_.ki * static_cast<double>(e);
  const double max = o_.max_step * static_cast<double>(c);
  integral_ = std::clamp(integral_, -max, max);
  const double u = std::clamp(o_.kp * static_cast<double>(e) + integral_, -max, max);
  return -static_cast<int64_t>(u);
}

}  // namespace cnc::ethercat
