// Step 8 with the camera as the measurement source: a camera on the
// spindle reads a glass scale clamped to the table (vision/
// scale_reader.hpp, as `cnc-comp camera`, docs/vision.md), and at each stop
// of the ISO 230-2 cycle that comp-run runs (commission/compensation.hpp)
// its reading of the scale is the table's position, as a laser's would be.
// The scale's graduations are numbered by following them from stop to
// stop: the first reading takes its number from `scale_at_zero_mm` and the
// target, each later one from the reading before it and the commanded
// travel since, so only the deviation's change between neighbouring stops
// (not the deviation itself) must stay under half a pitch; readings count
// relative to the first stop, so any whole-pitch offset of the first
// reading cancels. Non-realtime.
#pragma once

#include <memory>
#include <string>

#include "commission/compensation.hpp"

namespace cnc::vision {
class FrameSource;
}

namespace cnc::commission {

struct CameraOptions {
  // Where the images come from: vision::open_source's spec (/dev/videoN,
  // v4l2:..., folder:PATH, file:PATH), or `exec:COMMAND`: a program that
  // takes one picture per reading (a camera's capture tool; in the tests
  // the simulated camera, tests/commission/sim_camera.sh), run through the
  // shell with the image file to write appended.
  std::string source;
  double pitch_mm = 0.1;        // the scale's graduation spacing
  double um_per_px = 2.5;       // pixel scale at the scale's surface
  double scale_at_zero_mm = 10; // scale coordinate under the camera at axis 0 (any: see above)
  int sign = 1;                 // +1: the scale coordinate grows as the axis moves +
  int frames = 1;               // readings averaged per call
};

// A StopReader (commission/compensation.hpp) on `camera`: the axis'
// position in mm, sign * (scale coordinate - scale_at_zero_mm); it throws
// std::runtime_error naming the camera and what it saw (no frame, no
// scale, blurred ...). A reader on `camera` (kept alive by the reader).
StopReader camera_reader(std::shared_ptr<vision::FrameSource> camera, const CameraOptions& o);
// A reader on o.source; throws std::runtime_error when the camera is known
// to be missing or this build has no camera (comp/'s camera library).
StopReader camera_reader(const CameraOptions& o);

}  // namespace cnc::commission
