#include "comp/exports.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "comp/tables.hpp"

namespace cnc::comp {
namespace {

struct Range {
  double x0, x1, ref;
};

Range range_of(const ErrorModel& m, const ExportOptions& o) {
  Range r;
  r.x0 = o.x_max > o.x_min ? o.x_min : m.x_min;
  r.x1 = o.x_max > o.x_min ? o.x_max : m.x_max;
  r.ref = std::isfinite(o.reference_mm) ? o.reference_mm : r.x0;
  return r;
}

// Positional error (um) relative to the mean error at the reference.
double error_um(const ErrorModel& m, double x, int d, double ref) {
  const double at_ref = (m.deviation_um(ref, 1) + m.deviation_um(ref, -1)) / 2;
  return m.deviation_um(x, d) - at_ref;
}

// The smallest "round" spacing (1, 2, 2.5, 5 x 10^k) giving at most `max_points` points.
double nice_spacing(double length, int max_points) {
  const double raw = length / std::max(1, max_points - 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double f : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    if (f * p >= raw * (1 - 1e-12)) return f * p;
  }
  return 10 * p;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

}  // namespace

std::string export_linuxcnc(const ErrorModel& model, const ExportOptions& o, int type, int max_points) {
  const Range r = range_of(model, o);
  TableOptions to;
  to.x_min = r.x0;
  to.x_max = r.x1;
  to.reference_mm = r.ref;
  if (o.spacing_mm > 0) {
    to.points = std::min(max_points, static_cast<int>(std::ceil((r.x1 - r.x0) / o.spacing_mm - 1e-9)) + 1);
  } else {
    to.max_points = max_points;
  }
  const CompTable t = make_comp_table(model, to);
  const double offset = reference_offset_um(model, to);
  const double err = interpolation_error_um(t, model, offset);
  std::vector<std::string> notes = {
      "LinuxCNC COMP_FILE, COMP_FILE_TYPE = " + std::to_string(type) + ", from the fitted model (cnc-comp)",
      std::to_string(t.size()) + " entries, spacing " + fmt("%.4f", t.size() > 1 ? t.nominal[1] - t.nominal[0] : 0) +
          " mm; linear interpolation within " + fmt("%.3f", err) + " um of the model",
      "mean correction 0 at " + fmt("%.4f", r.ref) + " mm; BACKLASH is ignored when COMP_FILE is set"};
  if (!model.backlash_measured) {
    notes.push_back("backlash not measured (no target approached from both directions): forward and reverse trims "
                    "are equal, and this table replaces BACKLASH");
  }
  return format_comp_table(t, type == 0 ? CompFileType::Positions : CompFileType::Trims, notes);
}

std::string export_siemens_lec(const ErrorModel& model, const ExportOptions& o) {
  const Range r = range_of(model, o);
  const double step = o.spacing_mm > 0 ? o.spacing_mm : nice_spacing(r.x1 - r.x0, 200);
  const int n = static_cast<int>(std::ceil((r.x1 - r.x0) / step - 1e-9)) + 1;
  const double xmax = r.x0 + step * (n - 1);
  const std::string ax = o.axis;
  std::string out = "%_N_AX_EEC_INI\nCHANDATA(1)\n";
  out += "; LEC (measuring-system error compensation) for " + ax + " from the fitted model (cnc-comp)\n";
  out += "; value = positional error (reached - commanded, mean of both directions) in mm:\n";
  out += "; a positive value moves the axis in the negative direction. 0 at the reference " + fmt("%.3f", r.ref) +
         " mm.\n";
  const double b_lo = model.backlash_um(r.x0), b_hi = model.backlash_um(r.x1);
  if (model.backlash_measured) {
    out += "; backlash: MD32450 $MA_BACKLASH[0] = " + fmt("%.5f", model.backlash0_um / 1000) + " (mean reversal; " +
           fmt("%.5f", b_lo / 1000) + " at " + fmt("%.1f", r.x0) + " mm, " + fmt("%.5f", b_hi / 1000) + " at " +
           fmt("%.1f", r.x1) + " mm)\n";
  } else {
    out += "; backlash: not measured (no target approached from both directions); MD32450 left as it is\n";
  }
  out += "; needs MD38000 $MA_MM_ENC_COMP_MAX_POINTS[0] >= " + std::to_string(n) +
         " and MD32700 $MA_ENC_COMP_ENABLE[0] = 1\n";
  char b[128];
  for (int i = 0; i < n; ++i) {
    const double x = r.x0 + step * i;
    const double e = (error_um(model, x, 1, r.ref) + error_um(model, x, -1, r.ref)) / 2;
    std::snprintf(b, sizeof b, "$AA_ENC_COMP[0,%d,%s]=%.6f\n", i, ax.c_str(), e / 1000);
    out += b;
  }
  std::snprintf(b, sizeof b, "$AA_ENC_COMP_STEP[0,%s]=%.4f\n", ax.c_str(), step);
  out += b;
  std::snprintf(b, sizeof b, "$AA_ENC_COMP_MIN[0,%s]=%.4f\n", ax.c_str(), r.x0);
  out += b;
  std::snprintf(b, sizeof b, "$AA_ENC_COMP_MAX[0,%s]=%.4f\n", ax.c_str(), xmax);
  out += b;
  std::snprintf(b, sizeof b, "$AA_ENC_COMP_IS_MODULO[0,%s]=0\n", ax.c_str());
  out += b;
  out += "M17\n";
  return out;
}

std::string export_heidenhain_com(const ErrorModel& model, const ExportOptions& o) {
  const Range r = range_of(model, o);
  const double step = o.spacing_mm > 0 ? o.spacing_mm : nice_spacing(r.x1 - r.x0, 256);
  const int n = static_cast<int>(std::ceil((r.x1 - r.x0) / step - 1e-9)) + 1;
  std::string out = "BEGIN " + o.axis + ".COM MM\n";
  char b[160];
  std::snprintf(b, sizeof b, "%-6s %-14s %-14s %-14s\n", "NR", "AXISPOS", o.axis.c_str(), "BACKLASH");
  out += b;
  for (int i = 0; i < n; ++i) {
    const double x = r.x0 + step * i;
    // Compensation values (added to the nominal position): the negative of
    // the error, moving + in the axis column, moving - in BACKLASH.
    const double cp = -error_um(model, x, 1, r.ref) / 1000, cn = -error_um(model, x, -1, r.ref) / 1000;
    std::snprintf(b, sizeof b, "%-6d %+-14.4f %+-14.5f %+-14.5f\n", i, x, cp, cn);
    out += b;
  }
  out += "[END]\n";
  return out;
}

std::string export_fanuc_pitch(const ErrorModel& model, const ExportOptions& o, FanucPoints* used) {
  const Range r = range_of(model, o);
  int ax = o.fanuc_axis;
  if (ax == 0) {
    if (o.axis == "X" || o.axis == "x") ax = 1;
    else if (o.axis == "Y" || o.axis == "y") ax = 2;
    else if (o.axis == "Z" || o.axis == "z") ax = 3;
    else {
      throw std::invalid_argument("Fanuc export: the controlled-axis number of axis " + o.axis +
                                  " is not known; give it (cnc-comp --fanuc-axis N, and --fanuc-reference-point P "
                                  "for a range of compensation points no other axis uses)");
    }
  }
  if (ax < 1 || ax > 32) throw std::invalid_argument("Fanuc export: axis number " + std::to_string(ax) + " is not 1..32");
  if (!(o.fanuc_unit_um > 0) || !std::isfinite(o.fanuc_unit_um)) {
    throw std::invalid_argument("Fanuc export: the detection unit must be a positive number of micrometres");
  }
  if (o.fanuc_magnification < 1 || o.fanuc_magnification > 100) {
    throw std::invalid_argument("Fanuc export: the magnification (parameter 3623) must be 1..100, not " +
                                std::to_string(o.fanuc_magnification));
  }
  // At most 126 intervals by default, so that both directions' tables
  // (128 points each at most) fit the axis's block.
  const double interval = o.spacing_mm > 0 ? o.spacing_mm : nice_spacing(r.x1 - r.x0, 127);
  const double unit_um = o.fanuc_unit_um * o.fanuc_magnification;
  const int below = static_cast<int>(std::ceil((r.ref - r.x0) / interval - 1e-9));
  const int above = static_cast<int>(std::ceil((r.x1 - r.ref) / interval - 1e-9));
  const int points = below + above + 1;
  const bool default_block = o.fanuc_reference_point < 0;
  const int ref_no = default_block ? (ax - 1) * kFanucPointsPerAxis + below : o.fanuc_reference_point;
  if (ref_no < below) {
    throw std::invalid_argument("Fanuc export: reference point " + std::to_string(ref_no) + " leaves " +
                                std::to_string(ref_no) + " point numbers below it, and the table has " +
                                std::to_string(below) + " points below the reference: give at least " +
                                std::to_string(below));
  }
  const int k_min = ref_no - below, k_max = ref_no + above;
  const int neg_base = k_max + 1;
  const int last_used = o.fanuc_bidirectional ? neg_base + points - 1 : k_max;
  if (default_block && last_used >= ax * kFanucPointsPerAxis) {
    throw std::invalid_argument("Fanuc export: " + std::to_string(last_used - k_min + 1) +
                                " compensation points do not fit axis " + std::to_string(ax) + "'s block of " +
                                std::to_string(kFanucPointsPerAxis) + " (" + std::to_string((ax - 1) * kFanucPointsPerAxis) +
                                ".." + std::to_string(ax * kFanucPointsPerAxis - 1) +
                                "); give a larger spacing or the reference point (cnc-comp --fanuc-reference-point P)");
  }
  if (used) {
    *used = FanucPoints{ax, ref_no, k_min, k_max, o.fanuc_bidirectional ? neg_base : -1,
                        o.fanuc_bidirectional ? last_used : -1};
  }
  // Absolute corrections in units, 0 at the reference approached moving +
  // (where the axis is referenced), rounded once each so that the sums of
  // the increments never drift.
  const double at_ref = model.deviation_um(r.ref, 1);
  const auto absolute = [&](int k, int d) {
    const double x = r.ref + (k - ref_no) * interval;
    return static_cast<long>(std::lround(-(model.deviation_um(x, d) - at_ref) / unit_um));
  };
  std::string out = "%\n";
  char b[96];
  if (o.fanuc_bidirectional) {
    std::snprintf(b, sizeof b, "N03605A%dP00000001\n", ax);
    out += b;
  }
  std::snprintf(b, sizeof b, "N03620A%dP%d\nN03621A%dP%d\nN03622A%dP%d\nN03623A%dP%d\nN03624A%dP%.4f\n", ax, ref_no, ax,
                k_min, ax, k_max, ax, o.fanuc_magnification, ax, interval);
  out += b;
  if (o.fanuc_bidirectional) {
    std::snprintf(b, sizeof b, "N03626A%dP%d\nN03627A%dP%ld\n", ax, neg_base, ax, absolute(ref_no, -1) - absolute(ref_no, 1));
    out += b;
  }
  const auto table = [&](int d, int base) {
    for (int k = k_min; k <= k_max; ++k) {
      const long inc = k == k_min ? 0 : absolute(k, d) - absolute(k - 1, d);
      std::snprintf(b, sizeof b, "N%05dP%ld\n", 10000 + base + (k - k_min), inc);
      out += b;
    }
  };
  table(1, k_min);
  if (o.fanuc_bidirectional) table(-1, neg_base);
  out += "%\n";
  return out;
}

}  // namespace cnc::comp
