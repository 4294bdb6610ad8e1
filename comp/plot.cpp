#include "comp/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/util/atomic_file.hpp"

namespace cnc::comp {
namespace {

const cv::Scalar kBlack(0, 0, 0), kGrid(225, 225, 225), kUp(200, 90, 20), kDown(30, 40, 210);
const cv::Scalar kUpLight(235, 190, 150), kDownLight(150, 160, 240), kModelUp(40, 140, 40), kModelDown(0, 140, 230);

double nice_step(double span, int ticks) {
  const double raw = span / std::max(ticks, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double f : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (f * p >= raw) return f * p;
  }
  return 10 * p;
}

std::string label(double v, double step) {
  char b[32];
  if (std::fabs(v) < step * 1e-6) v = 0;  // no "-0" from rounding
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) + 1e-9));
  std::snprintf(b, sizeof b, "%.*f", std::min(decimals, 4), v);
  return b;
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.45, const cv::Scalar& c = kBlack,
          int thickness = 1) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, c, thickness, cv::LINE_AA);
}

void dashed(cv::Mat& img, cv::Point a, cv::Point b, const cv::Scalar& c) {
  const double len = std::hypot(b.x - a.x, b.y - a.y);
  const int n = std::max(1, static_cast<int>(len / 6));
  for (int i = 0; i < n; i += 2) {
    const cv::Point p(a.x + (b.x - a.x) * i / n, a.y + (b.y - a.y) * i / n);
    const cv::Point q(a.x + (b.x - a.x) * (i + 1) / n, a.y + (b.y - a.y) * (i + 1) / n);
    cv::line(img, p, q, c, 1, cv::LINE_AA);
  }
}

void draw_panel(cv::Mat& img, const cv::Rect& area, const PlotPanel& p) {
  const Measurement& m = *p.measurement;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const MeasurementPoint& q : m.points) {
    x0 = std::min(x0, q.target);
    x1 = std::max(x1, q.target);
    y0 = std::min(y0, q.deviation_um);
    y1 = std::max(y1, q.deviation_um);
  }
  if (p.model) {
    for (int k = 0; k <= 100; ++k) {
      const double x = x0 + (x1 - x0) * k / 100;
      for (int d : {1, -1}) {
        const double v = p.model->deviation_um(x, d) + p.model_offset_um;
        y0 = std::min(y0, v);
        y1 = std::max(y1, v);
      }
    }
  }
  if (!(x1 > x0)) x1 = x0 + 1;
  if (y1 - y0 < 1) {
    const double c = (y0 + y1) / 2;
    y0 = c - 0.5;
    y1 = c + 0.5;
  }
  const double ypad = (y1 - y0) * 0.08, xpad = (x1 - x0) * 0.03;
  x0 -= xpad;
  x1 += xpad;
  y0 -= ypad;
  y1 += ypad;
  const cv::Rect plot(area.x + 80, area.y + 60, area.width - 110, area.height - 120);
  const auto px = [&](double x) { return plot.x + static_cast<int>(std::lround((x - x0) / (x1 - x0) * plot.width)); };
  const auto py = [&](double y) {
    return plot.y + plot.height - static_cast<int>(std::lround((y - y0) / (y1 - y0) * plot.height));
  };
  // Grid and ticks.
  const double xs = nice_step(x1 - x0, 10), ys = nice_step(y1 - y0, 8);
  for (double x = std::ceil(x0 / xs) * xs; x <= x1; x += xs) {
    cv::line(img, {px(x), plot.y}, {px(x), plot.y + plot.height}, kGrid, 1);
    text(img, label(x, xs), {px(x) - 14, plot.y + plot.height + 18}, 0.4);
  }
  for (double y = std::ceil(y0 / ys) * ys; y <= y1; y += ys) {
    cv::line(img, {plot.x, py(y)}, {plot.x + plot.width, py(y)}, kGrid, 1);
    text(img, label(y, ys), {plot.x - 60, py(y) + 5}, 0.4);
  }
  if (y0 < 0 && y1 > 0) cv::line(img, {plot.x, py(0)}, {plot.x + plot.width, py(0)}, cv::Scalar(160, 160, 160), 1);
  cv::rectangle(img, plot, kBlack, 1);
  text(img, "position (mm)", {plot.x + plot.width / 2 - 50, plot.y + plot.height + 40}, 0.5);
  text(img, "deviation (um)", {area.x + 6, plot.y - 12}, 0.5);
  text(img, p.title, {area.x + 10, area.y + 24}, 0.6, kBlack, 2);
  // Measured points.
  for (const MeasurementPoint& q : m.points) {
    const cv::Point c(px(q.target) + (q.direction > 0 ? -3 : 3), py(q.deviation_um));
    if (q.direction > 0) cv::circle(img, c, 2, kUp, cv::FILLED, cv::LINE_AA);
    else cv::drawMarker(img, c, kDown, cv::MARKER_TILTED_CROSS, 6, 1, cv::LINE_AA);
  }
  // Means and +-2 s bands.
  if (p.iso) {
    const auto& t = p.iso->targets;
    for (std::size_t i = 1; i < t.size(); ++i) {
      cv::line(img, {px(t[i - 1].position), py(t[i - 1].mean_up)}, {px(t[i].position), py(t[i].mean_up)}, kUp, 2,
               cv::LINE_AA);
      cv::line(img, {px(t[i - 1].position), py(t[i - 1].mean_down)}, {px(t[i].position), py(t[i].mean_down)}, kDown,
               2, cv::LINE_AA);
      for (const double k : {2.0, -2.0}) {
        cv::line(img, {px(t[i - 1].position), py(t[i - 1].mean_up + k * t[i - 1].s_up)},
                 {px(t[i].position), py(t[i].mean_up + k * t[i].s_up)}, kUpLight, 1, cv::LINE_AA);
        cv::line(img, {px(t[i - 1].position), py(t[i - 1].mean_down + k * t[i - 1].s_down)},
                 {px(t[i].position), py(t[i].mean_down + k * t[i].s_down)}, kDownLight, 1, cv::LINE_AA);
      }
    }
    char b[200];
    std::snprintf(b, sizeof b, "A %.2f   E %.2f   R %.2f   B %.2f   M %.2f um", p.iso->A, p.iso->E, p.iso->R,
                  p.iso->B, p.iso->M);
    int base = 0;
    const cv::Size size = cv::getTextSize(b, cv::FONT_HERSHEY_SIMPLEX, 0.55, 1, &base);
    text(img, b, {area.x + area.width - size.width - 20, area.y + 24}, 0.55, kBlack, 1);
  }
  // Model curves.
  if (p.model) {
    for (int d : {1, -1}) {
      cv::Point prev;
      for (int k = 0; k <= 400; ++k) {
        const double x = x0 + xpad + (x1 - x0 - 2 * xpad) * k / 400;
        const cv::Point c(px(x), py(p.model->deviation_um(x, d) + p.model_offset_um));
        if (k > 0) dashed(img, prev, c, d > 0 ? kModelUp : kModelDown);
        prev = c;
      }
    }
  }
  // Legend.
  int lx = plot.x + 10, ly = plot.y + 18;
  cv::circle(img, {lx, ly - 4}, 3, kUp, cv::FILLED);
  text(img, "moving +  (mean, +-2s)", {lx + 10, ly}, 0.42, kUp);
  cv::drawMarker(img, {lx, ly + 14}, kDown, cv::MARKER_TILTED_CROSS, 7, 1);
  text(img, "moving -  (mean, +-2s)", {lx + 10, ly + 18}, 0.42, kDown);
  if (p.model) text(img, "- - fitted model (+ green, - orange)", {lx + 10, ly + 36}, 0.42, kModelUp);
}

}  // namespace

std::vector<uint8_t> plot_png(const std::vector<PlotPanel>& panels, int width, int panel_height) {
  if (panels.empty()) throw std::invalid_argument("nothing to plot");
  cv::Mat img(panel_height * static_cast<int>(panels.size()), width, CV_8UC3, cv::Scalar(255, 255, 255));
  for (std::size_t i = 0; i < panels.size(); ++i) {
    if (!panels[i].measurement || panels[i].measurement->points.empty()) throw std::invalid_argument("a panel has no data");
    draw_panel(img, cv::Rect(0, static_cast<int>(i) * panel_height, width, panel_height), panels[i]);
  }
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", img, png)) throw std::runtime_error("PNG encoding failed");
  return png;
}

void write_plot(const std::filesystem::path& path, const std::vector<PlotPanel>& panels) {
  const std::vector<uint8_t> png = plot_png(panels);
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace cnc::comp
