#include "comp/measurement_logger.hpp"

#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/atomic_file.hpp"

namespace cnc::comp {

MeasurementLogger::MeasurementLogger(hal::ComponentContext& ctx, const hal::LoadArgs& args)
    : hal::Component(ctx.hal, "complog") {
  args.allow_only({"file", "axis", "scale", "temperature"});
  pattern_ = args.get_string("file", "");
  if (pattern_.empty()) throw hal::HalError("complog: file=<path> is required (%d: the measurement's number)");
  if (ctx.ini && std::filesystem::path(pattern_).is_relative()) pattern_ = ctx.ini->resolve_path(pattern_).string();
  axis_ = args.get_string("axis", "");
  scale_ = args.get_double("scale", 1000.0);
  if (!(scale_ > 0)) throw hal::HalError("complog: scale (micrometres per machine unit) must be positive");
  with_temperature_ = args.get_int("temperature", 0, 0, 1) != 0;
  enable_ = make_pin<bool>("complog.enable", hal::PinDir::In);
  stop_ = make_pin<bool>("complog.stop", hal::PinDir::In);
  zero_at_start_ = make_pin<bool>("complog.zero-at-start", hal::PinDir::In, true);
  measuring_ = make_pin<bool>("complog.measuring", hal::PinDir::Out);
  commanded_ = make_pin<double>("complog.commanded", hal::PinDir::In);
  actual_ = make_pin<double>("complog.actual", hal::PinDir::In);
  temperature_ = make_pin<double>("complog.temperature", hal::PinDir::In, 20.0);
  actual_offset_ = make_pin<double>("complog.actual-offset", hal::PinDir::In);
  settle_time_ = make_pin<double>("complog.settle-time", hal::PinDir::In, 0.25);
  average_time_ = make_pin<double>("complog.average-time", hal::PinDir::In, 0.25);
  min_move_ = make_pin<double>("complog.min-move", hal::PinDir::In, 1e-6);
  points_ = make_pin<int32_t>("complog.points", hal::PinDir::Out);
  measurements_ = make_pin<int32_t>("complog.measurements", hal::PinDir::Out);
  export_method<&MeasurementLogger::sample>("complog", this);
}

void MeasurementLogger::sample(const rt::CycleInfo& info) noexcept {
  const double dt = static_cast<double>(info.period_ns) * 1e-9;
  const bool en = enable_.get(), stop = stop_.get();
  const double cmd = commanded_.get();
  if (en && !was_enabled_) {
    events_.push(Event{Event::Start});
    open_rt_ = true;
    time_s_ = 0;
    points_rt_ = 0;
    direction_ = 0;
    have_last_ = false;
  } else if (open_rt_ && (!en || (stop && !was_stop_))) {
    events_.push(Event{Event::Stop});
    open_rt_ = false;
  }
  was_enabled_ = en;
  was_stop_ = stop;
  if (!open_rt_) {
    measuring_.set(false);
    return;
  }
  time_s_ += dt;
  if (!have_last_ || cmd != last_cmd_) {
    // The approach direction: that of the last move beyond min-move from
    // where the direction was last decided.
    if (!have_last_) {
      anchor_ = cmd;
    } else if (std::fabs(cmd - anchor_) > min_move_.get()) {
      direction_ = cmd > anchor_ ? 1 : -1;
      anchor_ = cmd;
    }
    have_last_ = true;
    last_cmd_ = cmd;
    still_s_ = 0;
    sampled_ = false;
    sum_actual_ = sum_temp_ = 0;
    count_ = 0;
    measuring_.set(false);
    return;
  }
  still_s_ += dt;
  if (sampled_ || direction_ == 0 || still_s_ < settle_time_.get()) return;
  measuring_.set(true);
  sum_actual_ += actual_.get();
  sum_temp_ += temperature_.get();
  ++count_;
  if (still_s_ >= settle_time_.get() + average_time_.get()) {
    Event e;
    e.kind = Event::Point;
    e.direction = direction_;
    e.commanded = cmd;
    e.actual = sum_actual_ / count_;
    e.temperature = sum_temp_ / count_;
    e.time_s = time_s_;
    if (events_.push(e)) points_.set(++points_rt_);
    sampled_ = true;
    measuring_.set(false);
  }
}

std::filesystem::path MeasurementLogger::file_for(int number) const {
  std::string p = pattern_;
  const std::size_t k = p.find("%d");
  if (k != std::string::npos) p.replace(k, 2, std::to_string(number));
  return p;
}

void MeasurementLogger::write_current() {
  Measurement m = current_;
  number_runs(m);
  write_file_atomically(file_for(number_), format_measurement(m));
}

void MeasurementLogger::update(int64_t /*now_ns*/) {
  Event e;
  bool changed = false;
  while (events_.pop(e)) {
    switch (e.kind) {
      case Event::Start:
        ++number_;
        open_ = true;
        have_zero_ = false;
        current_ = Measurement{};
        current_.axis = axis_;
        current_.notes.push_back("measured by complog: deviation = reference position - commanded position" +
                                 std::string(zero_at_start_.get() ? ", zeroed at the first point" : ""));
        changed = true;
        break;
      case Event::Point: {
        if (!open_) break;
        const double raw = e.actual - actual_offset_.get() - e.commanded;
        if (!have_zero_) {
          zero_ = zero_at_start_.get() ? raw : 0.0;
          have_zero_ = true;
        }
        MeasurementPoint p;
        p.target = e.commanded;
        p.direction = e.direction;
        p.deviation_um = (raw - zero_) * scale_;
        if (with_temperature_) p.temperature_c = e.temperature;
        p.time_s = e.time_s;
        current_.points.push_back(p);
        changed = true;
        break;
      }
      case Event::Stop:
        if (!open_) break;
        if (!current_.points.empty()) write_current();
        finished_.push_back(file_for(number_));
        measurements_.set(static_cast<int32_t>(finished_.size()));
        open_ = false;
        changed = false;
        break;
    }
  }
  if (changed && open_ && !current_.points.empty()) write_current();
}

}  // namespace cnc::comp
