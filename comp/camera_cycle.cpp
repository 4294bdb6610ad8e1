#include "comp/camera_cycle.hpp"

#include <cmath>
#include <cstdio>
#include <optional>

#include "comp/iso230.hpp"
#include "core/util/atomic_file.hpp"

namespace cnc::comp {

CameraCycleResult run_camera_cycle(Positioner& axis, vision::FrameSource& camera, const CameraCycleOptions& o) {
  CameraCycleResult r;
  r.measurement.axis = std::string(1, o.cycle.axis);
  r.measurement.notes.push_back("measured by camera (" + camera.name() + ") on a glass scale, pitch " +
                                std::to_string(o.scale.pitch_mm) + " mm, " + std::to_string(o.scale.um_per_px) +
                                " um/px");
  const std::vector<double> t = iso_targets(o.cycle);
  r.planned = static_cast<int>(2 * t.size()) * o.cycle.runs;
  std::optional<double> reference;  // scale coordinate at axis 0, from the first reading
  const auto where = [](double target, int run, int dir) {
    char b[96];
    std::snprintf(b, sizeof b, "target %.3f, run %d %s: ", target, run, dir > 0 ? "up" : "down");
    return std::string(b);
  };
  // Reads the scale at `target`; "" or why not.
  const auto measure = [&](double target, int run, int dir) -> std::string {
    if (std::string e = axis.move_to(target); !e.empty()) return where(target, run, dir) + "move: " + e;
    axis.settle(o.cycle.dwell_s);
    double sum = 0;
    const int frames = std::max(1, o.frames);
    for (int i = 0; i < frames; ++i) {
      const vision::Frame f = camera.grab();
      if (!f.ok()) return where(target, run, dir) + (f.error.empty() ? camera.name() + ": empty frame" : f.error);
      const vision::ScaleReading reading = vision::read_scale(f.image, o.reader);
      if (!reading.ok) return where(target, run, dir) + camera.name() + ": " + reading.reason;
      r.worst_sigma_px = std::max(r.worst_sigma_px, reading.sigma_px);
      const double coarse = reference ? *reference + o.sign * target : o.scale_at_zero_mm + o.sign * target;
      sum += vision::scale_position_mm(reading, o.scale, coarse);
    }
    const double s = sum / frames;
    if (!reference) reference = s - o.sign * target;
    MeasurementPoint p;
    p.target = target;
    p.run = run;
    p.direction = dir;
    p.deviation_um = (o.sign * (s - *reference) - target) * 1000;
    r.measurement.points.push_back(p);
    return "";
  };
  // A camera known to be missing stops the cycle before anything moves.
  if (std::string e = camera.check(); !e.empty()) {
    r.error = "before the first move: " + e;
    return r;
  }
  const double lo = t.front() - o.cycle.overshoot_mm, hi = t.back() + o.cycle.overshoot_mm;
  if (std::string e = axis.move_to(lo); !e.empty()) {
    r.error = "approach: " + e;
    return r;
  }
  for (int run = 1; run <= o.cycle.runs; ++run) {
    for (double x : t) {
      if (std::string e = measure(x, run, +1); !e.empty()) {
        r.error = e;
        return r;
      }
    }
    if (std::string e = axis.move_to(hi); !e.empty()) {
      r.error = "overshoot: " + e;
      return r;
    }
    for (auto it = t.rbegin(); it != t.rend(); ++it) {
      if (std::string e = measure(*it, run, -1); !e.empty()) {
        r.error = e;
        return r;
      }
    }
    if (std::string e = axis.move_to(lo); !e.empty()) {
      r.error = "overshoot: " + e;
      return r;
    }
  }
  return r;
}

int report_camera_cycle(const CameraCycleResult& r, const std::string& out) {
  write_file_atomically(out, format_measurement(r.measurement));
  std::printf("%zu of %d points measured (worst reading sigma %.4f px), written to %s\n", r.measurement.points.size(),
              r.planned, r.worst_sigma_px, out.c_str());
  if (!r.measurement.points.empty()) {
    try {
      const Iso230Result iso = evaluate_iso230(r.measurement);
      std::printf("ISO 230-2: A %.2f um, E %.2f um, B %.2f um, R %.2f um\n", iso.A, iso.E, iso.B, iso.R);
    } catch (const std::exception& e) {
      std::printf("no ISO 230-2 figures: %s\n", e.what());
    }
  }
  if (!r.error.empty()) {
    std::fprintf(stderr, "the cycle stopped: %s\n", r.error.c_str());
    return 1;
  }
  return 0;
}

}  // namespace cnc::comp
