// The camera closed loop on the simulator, shared by the test and the
// benchmark: one axis of the drive simulator's plant (pitch error,
// backlash, friction) measured with the ISO 230-2 cycle by the simulated
// camera reading a glass scale at the table's true position; the error
// model fitted and applied as compensation of the commands; the cycle run
// again. Beside it the same loop with perfect measurements (the table's
// true position, what an ideal interferometer reads).
#pragma once

#include <cmath>
#include <string>

#include "comp/camera_cycle.hpp"
#include "comp/fit.hpp"
#include "comp/iso230.hpp"
#include "sim/vision/camera.hpp"

namespace cnc::testing {

inline cnc::cia402::sim::PlantConfig camera_loop_plant() {
  cnc::cia402::sim::PlantConfig p;
  p.backlash_m = 6e-6;
  const double at[] = {-10, 20, 50, 80, 110, 140, 170, 210};
  const double err_um[] = {0, 4, 9, 6, 12, 15, 11, 18};
  for (std::size_t i = 0; i < std::size(at); ++i) {
    p.pitch_at[i] = at[i] * 1e-3;
    p.pitch_error[i] = err_um[i] * 1e-6;
  }
  p.pitch_points = std::size(at);
  return p;
}

inline vision::sim::ScaleScene camera_loop_scene() {
  vision::sim::ScaleScene s;
  s.imaging.width = 320;
  s.imaging.height = 240;
  s.imaging.blur_px = 1.2;
  s.imaging.noise = 2;
  s.imaging.gradient = 0.2;
  s.imaging.vignetting = 0.15;
  s.imaging.k1 = 0.02;
  s.angle_deg = 1.5;
  s.pitch_mm = 0.1;
  s.line_mm = 0.02;
  s.um_per_px = 2.5;
  return s;
}

inline comp::CameraCycleOptions camera_loop_options() {
  comp::CameraCycleOptions o;
  o.cycle.x_min = 5;
  o.cycle.x_max = 195;
  o.cycle.runs = 5;
  o.cycle.dwell_s = 0.2;
  o.cycle.overshoot_mm = 2;
  o.cycle.seed = 3;
  o.scale.pitch_mm = 0.1;
  o.scale.um_per_px = 2.5;
  o.scale_at_zero_mm = 10;
  return o;
}

// The same cycle measured by the table's true position.
inline comp::Measurement perfect_cycle(vision::sim::PlantAxis& axis, const comp::CameraCycleOptions& o) {
  comp::Measurement m;
  m.axis.assign(1, o.cycle.axis);
  const auto t = comp::iso_targets(o.cycle);
  const auto at = [&](double x, int run, int dir) {
    axis.move_to(x);
    axis.settle(o.cycle.dwell_s);
    m.points.push_back({x, run, dir, (axis.table_mm() - x) * 1000});
  };
  axis.move_to(t.front() - o.cycle.overshoot_mm);
  for (int run = 1; run <= o.cycle.runs; ++run) {
    for (double x : t) at(x, run, +1);
    axis.move_to(t.back() + o.cycle.overshoot_mm);
    for (auto it = t.rbegin(); it != t.rend(); ++it) at(*it, run, -1);
    axis.move_to(t.front() - o.cycle.overshoot_mm);
  }
  return m;
}

struct CameraLoopResult {
  std::string error;
  comp::Iso230Result before, after;             // measured by the camera
  comp::Iso230Result true_before, true_after;   // perfect measurements of the same machine
  comp::Iso230Result perfect_after;             // compensated from perfect measurements
  double worst_sigma_px = 0;
  int frames = 0;
};

inline std::function<double(double, int)> compensation_of(const comp::ErrorModel& model) {
  return [model](double x, int dir) { return -model.deviation_um(x, dir) / 1000; };
}

inline CameraLoopResult run_camera_loop() {
  CameraLoopResult r;
  const comp::CameraCycleOptions o = camera_loop_options();
  comp::FitOptions fo;
  fo.noise_um = 0.3;
  // Camera-measured loop.
  vision::sim::PlantAxis axis(camera_loop_plant(), {});
  vision::sim::SimulatedScaleCamera camera(camera_loop_scene(), [&] { return axis.table_mm(); }, o.scale_at_zero_mm);
  const auto before = comp::run_camera_cycle(axis, camera, o);
  if (!before.error.empty()) {
    r.error = "before: " + before.error;
    return r;
  }
  r.before = comp::evaluate_iso230(before.measurement);
  const auto fit = comp::fit_error_model({before.measurement}, fo);
  axis.compensation = compensation_of(fit.model);
  const auto after = comp::run_camera_cycle(axis, camera, o);
  if (!after.error.empty()) {
    r.error = "after: " + after.error;
    return r;
  }
  r.after = comp::evaluate_iso230(after.measurement);
  r.true_after = comp::evaluate_iso230(perfect_cycle(axis, o));
  r.worst_sigma_px = std::max(before.worst_sigma_px, after.worst_sigma_px);
  r.frames = camera.frames();
  // Perfect-measurement loop on an identical machine.
  vision::sim::PlantAxis ideal(camera_loop_plant(), {});
  const comp::Measurement m = perfect_cycle(ideal, o);
  r.true_before = comp::evaluate_iso230(m);
  ideal.compensation = compensation_of(comp::fit_error_model({m}, fo).model);
  r.perfect_after = comp::evaluate_iso230(perfect_cycle(ideal, o));
  return r;
}

}  // namespace cnc::testing
