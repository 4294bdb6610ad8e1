// The ISO 230-2 cycle with a camera as the measurement source: a camera on
// the spindle reads a glass scale clamped to the table (vision/
// scale_reader.hpp). At each target the axis stops, settles, the camera
// reads the scale (averaging `frames` readings), and the deviation (scale
// travel minus commanded travel, zeroed at the first reading) is recorded.
// The targets and their order are those of the cycle program
// (cycle.hpp: up through the targets, overshoot, down, overshoot; `runs`
// times); the result is an ordinary Measurement for the existing ISO
// evaluation, fit, report and tables.
//
// Bad input stops the cycle and keeps what it measured: a camera known
// to be missing (FrameSource::check) before anything moves; one that
// gives no frame (not there, disconnected), an image the reader refuses
// (no scale, blurred, badly exposed), a move that fails. The reason names
// the target, run and direction. Offline.
#pragma once

#include <string>
#include <vector>

#include "comp/cycle.hpp"
#include "comp/measurement.hpp"
#include "vision/camera.hpp"
#include "vision/scale_reader.hpp"

namespace cnc::comp {

// What the cycle needs of the machine: a machine-coordinate move of the
// axis (exact stop) and a wait. Implemented by the simulator's axis
// (sim/vision) and by whatever drives a real machine.
class Positioner {
 public:
  virtual ~Positioner() = default;
  virtual std::string move_to(double target_mm) = 0;  // "" or why not
  virtual void settle(double seconds) = 0;
};

struct CameraCycleOptions {
  CycleOptions cycle;                  // targets, runs, overshoot, dwell (the settling time)
  vision::ScaleGeometry scale;         // pitch and pixel scale
  vision::ScaleReaderOptions reader;
  double scale_at_zero_mm = 0;         // scale coordinate under the camera with the axis at 0 (within half a pitch)
  int sign = 1;                        // +1: the scale coordinate under the camera grows as the axis moves +
  int frames = 1;                      // readings averaged per target
};

struct CameraCycleResult {
  Measurement measurement;             // what was measured, also when the cycle stopped
  std::string error;                   // empty: the whole cycle ran
  int planned = 0;                     // points the full cycle has
  double worst_sigma_px = 0;           // the largest quality figure of the readings
};

CameraCycleResult run_camera_cycle(Positioner& axis, vision::FrameSource& camera, const CameraCycleOptions& o);

// What the tools do with a result: the measurement written to `out` (also
// a partial one), a summary printed (points, ISO 230-2 A, E, B when the
// data allow), the reason on stderr when the cycle stopped. Returns the
// exit status: 0 when the whole cycle ran, 1 otherwise.
int report_camera_cycle(const CameraCycleResult& r, const std::string& out);

}  // namespace cnc::comp
