// Fiducials for work offsets: an ArUco marker (OpenCV contrib) on the part
// or its fixture, seen by a camera at a known offset from the spindle. Its
// centre and the direction of its top edge, taken into machine
// coordinates, are the part's origin and rotation; the result is the G10
// L2 line that sets a work offset with the rotation R, applied after the
// operator confirms (docs/vision.md). The camera looks straight down at a
// calibrated pixel scale (um per pixel at the part's surface); lens
// distortion is removed from the corners when intrinsics are given.
// Offline.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "vision/calibration.hpp"

namespace cnc::vision {

// Where the camera is and how it is turned.
struct CameraMount {
  double offset_x_mm = 0, offset_y_mm = 0;  // image centre minus spindle axis, machine X and Y
  double rotation_deg = 0;                  // direction of image +x in the machine's XY plane
  bool y_down = true;                       // image +y is machine -Y (a camera looking down)
  double um_per_px = 10;                    // at the part's surface
};

struct FiducialPose {
  bool ok = false;
  std::string reason;
  int id = -1;
  cv::Point2d centre_px;                    // in the image (after undistortion)
  double x_mm = 0, y_mm = 0;                // machine coordinates of the marker's centre
  double angle_deg = 0;                     // its top edge's direction in the machine XY plane
  double side_mm = 0;                       // its measured side (a check against the printed size)
};

// Finds marker `id` (-1: the only marker in view) of the dictionary
// `dictionary` (cv::aruco::PREDEFINED_DICTIONARY_NAME, default DICT_4X4_50)
// with the spindle at (spindle_x, spindle_y).
FiducialPose locate_fiducial(const cv::Mat& image, int id, const CameraMount& mount, double spindle_x_mm,
                             double spindle_y_mm, const Intrinsics* intrinsics = nullptr, int dictionary = 0);

// "G10 L2 P1 X.. Y.. R..": work offset `coordinate_system` (1 = G54 .. 9 = G59.3).
std::string g10_line(int coordinate_system, const FiducialPose& p);

}  // namespace cnc::vision
