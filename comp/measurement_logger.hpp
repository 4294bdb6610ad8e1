// The measurement side of an ISO 230-2 cycle run by the controller: a HAL
// component that watches a joint's commanded position and a reference
// position (a laser interferometer, or a simulator's true position) and,
// each time the command has stood still for settle-time, averages the
// reference over average-time and records one point: target, approach
// direction (of the last move), deviation, temperature, time.
//   loadrt complog file=<path, %d = measurement number> [axis=X] [scale=1000] [temperature=0|1]
//   addf complog servo-thread        (after the functions that set its inputs)
// Pins: complog.enable (rising edge starts a measurement, falling edge ends
// it), complog.stop (rising edge ends it too), complog.commanded, complog.actual, complog.temperature,
// complog.actual-offset, complog.zero-at-start (the first point reads 0, as
// a laser zeroed at the first target), complog.settle-time,
// complog.average-time, complog.min-move (the approach direction counts
// moves larger than this, not the rounding of a planner's last sample); out: complog.points, complog.measurements,
// complog.measuring. The servo-thread function never allocates; the task
// cycle writes the measurement file (docs/compensation.md) atomically
// after every point.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "comp/measurement.hpp"
#include "core/hal/component.hpp"
#include "core/ipc/service.hpp"
#include "core/util/spsc_ring.hpp"

namespace cnc::comp {

class MeasurementLogger final : public hal::Component, public ipc::ControllerService {
 public:
  MeasurementLogger(hal::ComponentContext& ctx, const hal::LoadArgs& args);

  // --- servo thread ---
  void sample(const rt::CycleInfo& info) noexcept;

  // --- task cycle ---
  int service_order() const noexcept override { return 26; }
  void update(int64_t now_ns) override;

  // Files of the measurements finished so far, and the one being written.
  const std::vector<std::filesystem::path>& finished() const noexcept { return finished_; }
  const Measurement& current() const noexcept { return current_; }

 private:
  struct Event {
    enum Kind : uint8_t { Start, Point, Stop } kind = Point;
    int8_t direction = 0;
    double commanded = 0, actual = 0, temperature = 0, time_s = 0;
  };
  std::filesystem::path file_for(int number) const;
  void write_current();

  // pins
  hal::BitPin enable_, stop_, zero_at_start_, measuring_;
  hal::FloatPin commanded_, actual_, temperature_, actual_offset_, settle_time_, average_time_, min_move_;
  hal::S32Pin points_, measurements_;
  // servo-thread state
  bool was_enabled_ = false, was_stop_ = false, open_rt_ = false, sampled_ = false, have_last_ = false;
  int8_t direction_ = 0;
  double last_cmd_ = 0, anchor_ = 0, still_s_ = 0, time_s_ = 0, sum_actual_ = 0, sum_temp_ = 0;
  int count_ = 0;
  int32_t points_rt_ = 0;
  SpscRing<Event, 1024> events_;
  // task-cycle state
  std::string pattern_;
  std::string axis_;
  double scale_ = 1000;
  bool with_temperature_ = false;
  int number_ = 0;
  bool open_ = false;
  bool have_zero_ = false;
  double zero_ = 0;
  Measurement current_;
  std::vector<std::filesystem::path> finished_;
};

}  // namespace cnc::comp
