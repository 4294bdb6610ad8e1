#include "sim/vision/renderer.hpp"

#include <cmath>

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

namespace cnc::vision::sim {

namespace {

// Length of line inside (-w/2, s] for lines of width w centred on k * p.
double line_measure(double s, double p, double w) {
  const double t = s + w / 2;
  const double k = std::floor(t / p);
  return k * w + std::min(t - k * p, w);
}

// Lighting, blur, noise and 8-bit quantisation of an ideal image (grey
// levels, float), in the order the camera applies them.
cv::Mat finish(cv::Mat img, const Imaging& m) {
  const double cx = (img.cols - 1) / 2.0, cy = (img.rows - 1) / 2.0;
  const double r2max = cx * cx + cy * cy;
  for (int y = 0; y < img.rows; ++y) {
    float* row = img.ptr<float>(y);
    for (int x = 0; x < img.cols; ++x) {
      const double dx = x - cx, dy = y - cy;
      const double light = (1 + m.gradient * dx / img.cols) * (1 - m.vignetting * (dx * dx + dy * dy) / r2max);
      row[x] = static_cast<float>(row[x] * light);
    }
  }
  if (m.blur_px > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), m.blur_px, m.blur_px, cv::BORDER_REFLECT);
  if (m.noise > 0) {
    cv::Mat n(img.size(), CV_32F);
    cv::RNG rng(m.seed);
    rng.fill(n, cv::RNG::NORMAL, 0, m.noise);
    img += n;
  }
  cv::Mat out;
  img.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

}  // namespace

cv::Mat render_scale(const ScaleScene& s) {
  const Imaging& m = s.imaging;
  cv::Mat img(m.height, m.width, CV_32F);
  const double cx = (m.width - 1) / 2.0, cy = (m.height - 1) / 2.0;
  const double r2max = cx * cx + cy * cy;
  const double a = s.angle_deg * M_PI / 180, ca = std::cos(a), sa = std::sin(a);
  const double mm_per_px = s.um_per_px / 1000;
  // Each pixel is kSub strips (rows of the pixel), each integrated exactly
  // across the lines over the pixel's width.
  constexpr int kSub = 4;
  const double half_strip = 0.5 * mm_per_px;
  for (int y = 0; y < m.height; ++y) {
    float* row = img.ptr<float>(y);
    for (int x = 0; x < m.width; ++x) {
      double covered = 0;
      for (int j = 0; j < kSub && !s.blank; ++j) {
        const double dx = x - cx, dy = y - 0.5 + (j + 0.5) / kSub - cy;
        const double f = 1 + s.imaging.k1 * (dx * dx + dy * dy) / r2max;
        const double u = (dx * f) * ca - (dy * f) * sa;
        const double sc = s.centre_mm + s.direction * u * mm_per_px;
        covered += (line_measure(sc + half_strip, s.pitch_mm, s.line_mm) -
                    line_measure(sc - half_strip, s.pitch_mm, s.line_mm)) /
                   (2 * half_strip);
      }
      covered /= kSub;
      row[x] = static_cast<float>(m.background - (m.background - m.dark) * covered);
    }
  }
  return finish(img, m);
}

double true_offset_px(const ScaleScene& s) {
  const double n = std::round(s.centre_mm / s.pitch_mm);
  return s.direction * (n * s.pitch_mm - s.centre_mm) * 1000 / s.um_per_px;
}

cv::Mat render_marker(const MarkerScene& s) {
  const Imaging& m = s.imaging;
  constexpr int kOver = 4;  // drawn at 4x and averaged down (area sampling)
  // The marker drawn with a white quiet zone of one cell.
  const auto dict = cv::aruco::getPredefinedDictionary(
      static_cast<cv::aruco::PREDEFINED_DICTIONARY_NAME>(s.dictionary == 0 ? cv::aruco::DICT_4X4_50 : s.dictionary));
  const int cells = dict->markerSize + 2;
  const int side_px = cells * 60;
  cv::Mat marker;
  cv::aruco::drawMarker(dict, s.id, side_px, marker, 1);
  const int quiet = side_px / cells;
  cv::Mat src(side_px + 2 * quiet, side_px + 2 * quiet, CV_8U, cv::Scalar(255));
  marker.copyTo(src(cv::Rect(quiet, quiet, side_px, side_px)));
  // Marker source px -> machine mm -> camera px (at kOver).
  const double mm_per_src = s.side_mm / side_px;
  const double mc = (src.cols - 1) / 2.0;
  const double a = s.angle_deg * M_PI / 180;
  // machine = centre + R(a) (sx, -sy) * mm_per_src, with (sx, sy) from the source's centre.
  const cv::Matx22d to_machine(std::cos(a) * mm_per_src, std::sin(a) * mm_per_src, std::sin(a) * mm_per_src,
                               -std::cos(a) * mm_per_src);
  const double ca = std::cos(s.mount.rotation_deg * M_PI / 180), sa = std::sin(s.mount.rotation_deg * M_PI / 180);
  const double px_per_mm = 1000 / s.mount.um_per_px;
  // camera (before flipping y): R(-rot) (machine - spindle - offset) px_per_mm
  const cv::Matx22d to_cam_rot(ca * px_per_mm, sa * px_per_mm, -sa * px_per_mm, ca * px_per_mm);
  const cv::Matx22d flip(1, 0, 0, s.mount.y_down ? -1 : 1);
  const cv::Matx22d A = flip * to_cam_rot * to_machine;
  const cv::Vec2d d(s.x_mm - s.spindle_x_mm - s.mount.offset_x_mm, s.y_mm - s.spindle_y_mm - s.mount.offset_y_mm);
  const cv::Vec2d centre_px = flip * to_cam_rot * d;
  const double cx = (m.width - 1) / 2.0, cy = (m.height - 1) / 2.0;
  // At kOver: big = kOver * (small + 0.5) - 0.5 for pixel centres.
  cv::Matx23d M;
  const cv::Vec2d t(cx + centre_px[0], cy + centre_px[1]);
  for (int r = 0; r < 2; ++r) {
    M(r, 0) = kOver * A(r, 0);
    M(r, 1) = kOver * A(r, 1);
    M(r, 2) = kOver * (t[r] - A(r, 0) * mc - A(r, 1) * mc + 0.5) - 0.5;
  }
  cv::Mat big;
  cv::warpAffine(src, big, M, cv::Size(m.width * kOver, m.height * kOver), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                 cv::Scalar(255));
  cv::Mat small;
  cv::resize(big, small, cv::Size(m.width, m.height), 0, 0, cv::INTER_AREA);
  cv::Mat img;
  small.convertTo(img, CV_32F, (m.background - m.dark) / 255.0, m.dark);
  return finish(img, m);
}

}  // namespace cnc::vision::sim
