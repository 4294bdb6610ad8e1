// Reading a graduated glass scale (or a precision ruler) through the
// camera: the sub-pixel position of the graduation nearest the image
// centre, the graduation's number from a coarse position, and a quality
// figure; or, when the image cannot be trusted, the reason (blurred,
// over- or under-exposed, no evenly spaced lines).
//
// Method (docs/vision.md): the image is cut into bands of rows; in each
// band's column profile every graduation is a dip (dark lines on a bright
// ground, transmitted light) whose centre is the mean of its two
// half-depth crossings, each found against the background on its own side
// (so a lighting gradient does not shift it). The centres are tracked from
// the centre band up and down (the lines may be tilted), a quadratic
// x(y) fitted per graduation (rotation, lens distortion) and evaluated on
// the centre row. The result is the perpendicular distance from the image
// centre to that graduation. Offline.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace cnc::vision {

struct ScaleReaderOptions {
  bool dark_lines = true;          // chrome graduations in transmitted light; false: bright lines
  int band_rows = 8;               // rows averaged into one profile
  double min_contrast = 40;        // grey levels between 5th and 95th percentile
  double max_saturated = 0.02;     // fraction of pixels at 255 (or at 0) that is over- (under-) exposure
  double min_mean = 25;            // mean grey below this: under-exposed
  double max_blur = 0.15;          // 20-80 % edge width over the line pitch above this: blurred
  int min_lines = 3;               // graduations that must be found
  double max_angle_deg = 20;       // lines tilted more than this from the image's columns: refused
  double max_pitch_spread = 0.2;   // spacing of neighbouring lines may differ from the median by this fraction
};

struct ScaleReading {
  bool ok = false;
  std::string reason;              // why not, when !ok
  double offset_px = 0;            // graduation nearest the centre minus the centre, perpendicular to the lines (+: image +x)
  double x_px = 0, y_px = 0;       // where that graduation crosses the image's centre row
  double angle_deg = 0;            // the lines' tilt from the image columns (+: lower end towards +x)
  double pitch_px = 0;             // spacing of the graduations, perpendicular to them
  double sigma_px = 0;             // quality: standard uncertainty of offset_px from the fit's residuals
  double contrast = 0;             // grey levels, 95th minus 5th percentile
  double edge_px = 0;              // median 20-80 % edge width (blur)
  int lines = 0;                   // graduations tracked over most of the image
};

ScaleReading read_scale(const cv::Mat& image, const ScaleReaderOptions& o = {});

// What is known about the scale and the optics.
struct ScaleGeometry {
  double pitch_mm = 0.1;           // graduation spacing
  double um_per_px = 2;            // pixel scale at the scale's surface (calibrate_pixel_scale)
  int direction = 1;               // +1: scale numbers grow towards image +x; -1: towards -x
};

// The scale coordinate (mm) under the image centre: the graduation nearest
// the centre gets its number from `coarse_mm` (the expected scale coordinate
// under the centre, right within half a pitch). `graduation` (optional):
// that number.
double scale_position_mm(const ScaleReading& r, const ScaleGeometry& g, double coarse_mm, long* graduation = nullptr);

// Pixel scale (um per pixel) from a reading of a scale with a known pitch.
double pixel_scale_um(const ScaleReading& r, double pitch_um);

}  // namespace cnc::vision
