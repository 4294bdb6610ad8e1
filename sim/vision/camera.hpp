// The simulated camera on the simulated machine: a vision::FrameSource that
// renders the glass scale as the camera on the spindle sees it at the
// table's true position (asked of `table_position_mm` at each grab: the
// drive simulator's plant, pitch error and backlash included), with the
// imaging faults of the scene (blur, noise, vignetting, distortion); a new
// noise seed per frame. Fault injection: it disconnects after a number of
// frames, or shows no scale.
//
// PlantAxis: one axis of the drive simulator's mechanics (sim/cia402
// Plant: motor, screw with pitch error, backlash, friction) under a
// cascaded position / velocity loop on the motor encoder, moved point to
// point in simulated time: what the camera cycle needs of a machine
// (comp::Positioner) without a controller. The commanded position can be
// corrected by a compensation function (the loaded table).
#pragma once

#include <functional>
#include <string>

#include "comp/camera_cycle.hpp"
#include "sim/cia402/plant.hpp"
#include "sim/vision/renderer.hpp"
#include "vision/camera.hpp"

namespace cnc::vision::sim {

class SimulatedScaleCamera : public FrameSource {
 public:
  // Scale coordinate under the camera = scale_at_zero_mm + sign * table position.
  SimulatedScaleCamera(ScaleScene scene, std::function<double()> table_position_mm, double scale_at_zero_mm,
                       int sign = 1)
      : scene_(scene), position_(std::move(table_position_mm)), zero_(scale_at_zero_mm), sign_(sign) {}
  Frame grab() override;
  std::string name() const override { return "simulated camera"; }
  void disconnect_after(int frames) { disconnect_after_ = frames; }
  void set_blank(bool blank) { scene_.blank = blank; }
  int frames() const noexcept { return frames_; }

 private:
  ScaleScene scene_;
  std::function<double()> position_;
  double zero_;
  int sign_;
  int frames_ = 0;
  int disconnect_after_ = -1;
};

class PlantAxis : public comp::Positioner {
 public:
  struct Options {
    double feed_mm_s = 50, accel_mm_s2 = 500;
    double step_s = 50e-6;
    double position_gain = 150;       // 1/s
    double velocity_bandwidth_hz = 100;
    double velocity_integral_time = 0.01;
  };
  PlantAxis(const cnc::cia402::sim::PlantConfig& plant, Options o);
  // "" or why the move failed.
  std::string move_to(double target_mm) override;
  void settle(double seconds) override;
  double table_mm() const noexcept { return plant_.table_position() * 1000; }
  double commanded_mm() const noexcept { return cmd_mm_; }
  double seconds() const noexcept { return t_; }
  // Correction (mm) added to the command for a target and direction of travel.
  std::function<double(double mm, int direction)> compensation;

 private:
  void step(double cmd_mm, double vel_mm_s);
  cnc::cia402::sim::Plant plant_;
  Options o_;
  double cmd_mm_ = 0, t_ = 0, integral_ = 0;
  int direction_ = 1;
};

}  // namespace cnc::vision::sim
