// Synthetic camera images with a known truth, for the tests, the benchmark
// (bench/vision) and the simulated camera: a graduated glass scale at a
// given position, and an ArUco marker at a given pose, each with blur,
// noise, lighting gradient, vignetting and lens distortion. The scale is
// drawn with exact area coverage across the lines (no quantised edges), so
// the reader's error is the reader's. Seeded, reproducible.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "vision/fiducial.hpp"

namespace cnc::vision::sim {

struct Imaging {
  int width = 640, height = 480;
  double background = 200, dark = 40;  // grey levels of the glass and of the lines (or of black marker cells)
  double blur_px = 1.0;                // Gaussian sigma of the optics
  double noise = 2.0;                  // grey levels, Gaussian
  double gradient = 0;                 // brightness change across the width (0.3: +-15 % at the edges)
  double vignetting = 0;               // brightness lost in the corners (0.2: 20 %)
  double k1 = 0;                       // radial distortion: ideal = image (1 + k1 r^2), r = 1 at the corners
  uint64_t seed = 1;
};

struct ScaleScene {
  Imaging imaging;
  double pitch_mm = 0.1;
  double line_mm = 0.02;               // line width
  double um_per_px = 2.5;
  double centre_mm = 0;                // scale coordinate under the image centre (the truth)
  int direction = 1;                   // +1: scale numbers grow towards image +x
  double angle_deg = 0;                // the lines' tilt from the image columns
  bool blank = false;                  // no graduations (a scale out of view)
};

cv::Mat render_scale(const ScaleScene& s);
// The truth read_scale should find: the graduation nearest the centre minus
// the centre, perpendicular to the lines, in pixels.
double true_offset_px(const ScaleScene& s);

struct MarkerScene {
  Imaging imaging;
  CameraMount mount;
  double spindle_x_mm = 0, spindle_y_mm = 0;
  int id = 7, dictionary = 0;          // 0: DICT_4X4_50
  double side_mm = 4;                  // black square, border included
  double x_mm = 0, y_mm = 0, angle_deg = 0;  // the truth: the marker's centre and top edge in machine coordinates
};

cv::Mat render_marker(const MarkerScene& s);

}  // namespace cnc::vision::sim
