#include "vision/scale_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "vision/camera.hpp"

namespace cnc::vision {

namespace {

std::string fmt(const char* f, double a, double b = 0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// A graduation in one band's profile.
struct Dip {
  double x = 0;      // centre (px)
  double edge = 0;   // 20-80 % width of its left edge (px)
};

// Where the profile crosses `level` between index i (above) and i+1 or i-1.
double crossing(const std::vector<double>& p, int from, int step, double level) {
  int i = from;
  const int n = static_cast<int>(p.size());
  while (i + step >= 0 && i + step < n && p[i + step] > level) i += step;
  if (i + step < 0 || i + step >= n) return std::nan("");
  const double a = p[i], b = p[i + step];
  return i + step * (a - level) / (a - b);
}

// The dips of a profile `p` in which graduations are peaks (already
// inverted for dark lines).
std::vector<Dip> find_dips(const std::vector<double>& p) {
  std::vector<Dip> out;
  const int n = static_cast<int>(p.size());
  const auto [lo_it, hi_it] = std::minmax_element(p.begin(), p.end());
  const double lo = *lo_it, hi = *hi_it;
  if (hi - lo < 1e-6) return out;
  const double mid = (lo + hi) / 2;
  // Runs above the mid level; the background between runs is the minimum
  // of the gap on each side.
  std::vector<std::pair<int, int>> runs;
  for (int i = 0; i < n;) {
    if (p[i] <= mid) {
      ++i;
      continue;
    }
    int j = i;
    while (j + 1 < n && p[j + 1] > mid) ++j;
    runs.emplace_back(i, j);
    i = j + 1;
  }
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const auto [a, b] = runs[k];
    if (a == 0 || b == n - 1) continue;  // cut by the image border
    const int left_from = k == 0 ? 0 : runs[k - 1].second + 1;
    const int right_to = k + 1 == runs.size() ? n - 1 : runs[k + 1].first - 1;
    if (a - left_from < 1 || right_to - b < 1) continue;
    const int peak_i = static_cast<int>(std::max_element(p.begin() + a, p.begin() + b + 1) - p.begin());
    const double peak = p[peak_i];
    const double bg_l = *std::min_element(p.begin() + left_from, p.begin() + a);
    const double bg_r = *std::min_element(p.begin() + b + 1, p.begin() + right_to + 1);
    const double xl = crossing(p, peak_i, -1, (peak + bg_l) / 2);
    const double xr = crossing(p, peak_i, +1, (peak + bg_r) / 2);
    if (std::isnan(xl) || std::isnan(xr)) continue;
    const double e20 = crossing(p, peak_i, -1, bg_l + 0.2 * (peak - bg_l));
    const double e80 = crossing(p, peak_i, -1, bg_l + 0.8 * (peak - bg_l));
    out.push_back({(xl + xr) / 2, std::isnan(e20) || std::isnan(e80) ? 0 : e80 - e20});
  }
  return out;
}

// Least squares x = c0 + c1 t + c2 t^2 (degree 1 or 2); returns the residual rms.
double fit_poly(const std::vector<double>& t, const std::vector<double>& x, int degree, double c[3]) {
  const int m = degree + 1;
  cv::Mat A(static_cast<int>(t.size()), m, CV_64F), b(static_cast<int>(t.size()), 1, CV_64F), sol;
  for (std::size_t i = 0; i < t.size(); ++i) {
    double v = 1;
    for (int j = 0; j < m; ++j, v *= t[i]) A.at<double>(static_cast<int>(i), j) = v;
    b.at<double>(static_cast<int>(i)) = x[i];
  }
  cv::solve(A, b, sol, cv::DECOMP_SVD);
  c[0] = c[1] = c[2] = 0;
  for (int j = 0; j < m; ++j) c[j] = sol.at<double>(j);
  double ss = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double r = x[i] - (c[0] + c[1] * t[i] + c[2] * t[i] * t[i]);
    ss += r * r;
  }
  return t.size() > static_cast<std::size_t>(m) ? std::sqrt(ss / static_cast<double>(t.size() - m)) : 0;
}

struct Track {
  std::vector<double> t, x;  // band centre row minus the centre row; dip centre
  double c[3] = {0, 0, 0};
  double rms = 0;
  double at_centre = 0;
};

}  // namespace

ScaleReading read_scale(const cv::Mat& image, const ScaleReaderOptions& o) {
  ScaleReading r;
  if (image.empty()) {
    r.reason = "empty image";
    return r;
  }
  const cv::Mat grey = to_grey(image);
  const int W = grey.cols, H = grey.rows;
  const int band = std::max(1, o.band_rows);
  if (W < 16 || H < 2 * band) {
    r.reason = fmt("image too small (%.0f x %.0f px)", W, H);
    return r;
  }
  // Exposure.
  int hist[256] = {0};
  double sum = 0;
  for (int y = 0; y < H; ++y) {
    const uint8_t* row = grey.ptr<uint8_t>(y);
    for (int x = 0; x < W; ++x) {
      ++hist[row[x]];
      sum += row[x];
    }
  }
  const double N = static_cast<double>(W) * H;
  const double mean = sum / N;
  auto percentile = [&](double q) {
    double acc = 0;
    for (int v = 0; v < 256; ++v) {
      acc += hist[v];
      if (acc >= q * N) return static_cast<double>(v);
    }
    return 255.0;
  };
  r.contrast = percentile(0.95) - percentile(0.05);
  const double high = hist[255] / N, low = hist[0] / N;
  if (high > o.max_saturated) {
    r.reason = fmt("over-exposed: %.1f %% of the pixels saturated (shorter exposure or less light)", 100 * high);
    return r;
  }
  if (mean < o.min_mean || low > o.max_saturated) {
    r.reason = fmt("under-exposed: mean grey %.0f, %.1f %% of the pixels black (longer exposure or more light)", mean,
                   100 * low);
    return r;
  }
  if (r.contrast < o.min_contrast) {
    r.reason = fmt("no scale in view: contrast %.0f grey levels (needs %.0f; out of focus, or no graduations)",
                   r.contrast, o.min_contrast);
    return r;
  }
  // Profiles per band, graduations as peaks.
  const int nb = H / band;
  const double cy = (H - 1) / 2.0, cx = (W - 1) / 2.0;
  std::vector<std::vector<Dip>> dips(nb);
  std::vector<double> band_t(nb);
  std::vector<double> edges;
  std::vector<double> p(W);
  const int y0 = (H - nb * band) / 2;
  for (int b = 0; b < nb; ++b) {
    std::fill(p.begin(), p.end(), 0.0);
    for (int y = y0 + b * band; y < y0 + (b + 1) * band; ++y) {
      const uint8_t* row = grey.ptr<uint8_t>(y);
      for (int x = 0; x < W; ++x) p[x] += row[x];
    }
    for (double& v : p) v = o.dark_lines ? 255.0 * band - v : v;
    dips[b] = find_dips(p);
    band_t[b] = y0 + b * band + (band - 1) / 2.0 - cy;
    for (const Dip& d : dips[b]) edges.push_back(d.edge);
  }
  // Track each graduation of the centre band up and down.
  int centre_band = 0;
  for (int b = 0; b < nb; ++b) {
    if (std::abs(band_t[b]) < std::abs(band_t[centre_band])) centre_band = b;
  }
  std::vector<double> spacing;
  for (std::size_t k = 1; k < dips[centre_band].size(); ++k) {
    spacing.push_back(dips[centre_band][k].x - dips[centre_band][k - 1].x);
  }
  if (dips[centre_band].size() < static_cast<std::size_t>(std::max(2, o.min_lines))) {
    r.reason = fmt("no scale in view: no graduation lines (%.0f in the centre of the image, needs %.0f)",
                   static_cast<double>(dips[centre_band].size()), std::max(2, o.min_lines));
    return r;
  }
  const double gap = median(spacing);
  const double tolerance = gap / 3;
  std::vector<Track> tracks;
  for (const Dip& start : dips[centre_band]) {
    Track tr;
    tr.t.push_back(band_t[centre_band]);
    tr.x.push_back(start.x);
    for (int dir : {-1, +1}) {
      double last_x = start.x, last_t = band_t[centre_band], slope = 0;
      int misses = 0;
      for (int b = centre_band + dir; b >= 0 && b < nb && misses < 3; b += dir) {
        const double predicted = last_x + slope * (band_t[b] - last_t);
        const Dip* best = nullptr;
        for (const Dip& d : dips[b]) {
          if (std::abs(d.x - predicted) < tolerance && (!best || std::abs(d.x - predicted) < std::abs(best->x - predicted))) {
            best = &d;
          }
        }
        if (!best) {
          ++misses;
          continue;
        }
        misses = 0;
        slope = (best->x - start.x) / (band_t[b] - band_t[centre_band]);
        last_x = best->x;
        last_t = band_t[b];
        tr.t.push_back(band_t[b]);
        tr.x.push_back(best->x);
      }
    }
    if (tr.t.size() < static_cast<std::size_t>(std::max(3, nb / 2))) continue;
    const int degree = tr.t.size() >= 8 ? 2 : 1;
    tr.rms = fit_poly(tr.t, tr.x, degree, tr.c);
    // One pass of outlier removal (a speck of dust on a line).
    const double limit = std::max(3 * tr.rms, 0.3);
    Track kept;
    for (std::size_t i = 0; i < tr.t.size(); ++i) {
      const double res = tr.x[i] - (tr.c[0] + tr.c[1] * tr.t[i] + tr.c[2] * tr.t[i] * tr.t[i]);
      if (std::abs(res) <= limit) {
        kept.t.push_back(tr.t[i]);
        kept.x.push_back(tr.x[i]);
      }
    }
    if (kept.t.size() != tr.t.size() && kept.t.size() > 3) {
      kept.rms = fit_poly(kept.t, kept.x, degree, kept.c);
      tr = kept;
    }
    tr.at_centre = tr.c[0];
    tracks.push_back(tr);
  }
  r.lines = static_cast<int>(tracks.size());
  if (r.lines < o.min_lines) {
    r.reason = fmt("no scale in view: %.0f graduation lines followed over the image, needs %.0f", r.lines, o.min_lines);
    return r;
  }
  // Even spacing: a scale, not an arbitrary pattern.
  std::vector<double> xs;
  for (const Track& t : tracks) xs.push_back(t.at_centre);
  std::sort(xs.begin(), xs.end());
  spacing.clear();
  for (std::size_t k = 1; k < xs.size(); ++k) spacing.push_back(xs[k] - xs[k - 1]);
  const double step = median(spacing);
  for (double s : spacing) {
    if (std::abs(s - step) > o.max_pitch_spread * step) {
      r.reason = fmt("the lines are not evenly spaced (%.1f px where most are %.1f px): not a graduated scale, or a "
                     "line is missing",
                     s, step);
      return r;
    }
  }
  const Track* nearest = &tracks[0];
  for (const Track& t : tracks) {
    if (std::abs(t.at_centre - cx) < std::abs(nearest->at_centre - cx)) nearest = &t;
  }
  std::vector<double> slopes;
  for (const Track& t : tracks) slopes.push_back(t.c[1]);
  const double slope = median(slopes);
  const double cosa = 1 / std::sqrt(1 + slope * slope);
  r.angle_deg = std::atan(slope) * 180 / M_PI;
  if (std::abs(r.angle_deg) > o.max_angle_deg) {
    r.reason = fmt("the lines are tilted %.1f deg from the image columns (at most %.1f): turn the camera", r.angle_deg,
                   o.max_angle_deg);
    return r;
  }
  r.pitch_px = step * cosa;
  r.edge_px = median(edges);
  if (r.edge_px > o.max_blur * r.pitch_px) {
    r.reason = fmt("blurred: edges %.1f px wide where the lines are %.1f px apart (focus the camera)", r.edge_px,
                   r.pitch_px);
    return r;
  }
  r.x_px = nearest->at_centre;
  r.y_px = cy;
  r.offset_px = (nearest->at_centre - cx) * cosa;
  r.sigma_px = nearest->rms / std::sqrt(static_cast<double>(nearest->t.size())) * cosa;
  r.ok = true;
  return r;
}

double scale_position_mm(const ScaleReading& r, const ScaleGeometry& g, double coarse_mm, long* graduation) {
  const double offset_mm = g.direction * r.offset_px * g.um_per_px / 1000;
  const long n = std::lround((coarse_mm + offset_mm) / g.pitch_mm);
  if (graduation) *graduation = n;
  return static_cast<double>(n) * g.pitch_mm - offset_mm;
}

double pixel_scale_um(const ScaleReading& r, double pitch_um) { return r.pitch_px > 0 ? pitch_um / r.pitch_px : 0; }

}  // namespace cnc::vision
