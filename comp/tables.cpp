#include "comp/tables.hpp"

#include <algorithm>
#include <cmath>

namespace cnc::comp {
namespace {

CompTable sample(const ErrorModel& m, double x0, double x1, int n, double offset_um, double um_per_unit) {
  CompTable t;
  n = std::max(n, 2);
  for (int i = 0; i < n; ++i) {
    const double x = i == n - 1 ? x1 : x0 + (x1 - x0) * i / (n - 1);
    t.nominal.push_back(x);
    t.forward.push_back(-(m.deviation_um(x, 1) + offset_um) / um_per_unit);
    t.reverse.push_back(-(m.deviation_um(x, -1) + offset_um) / um_per_unit);
  }
  return t;
}

}  // namespace

double reference_offset_um(const ErrorModel& model, const TableOptions& o) {
  if (!std::isfinite(o.reference_mm)) return 0;
  return -(model.deviation_um(o.reference_mm, 1) + model.deviation_um(o.reference_mm, -1)) / 2;
}

double interpolation_error_um(const CompTable& t, const ErrorModel& m, double offset_um, double um_per_unit) {
  if (t.size() < 2) return 0;
  const double x0 = t.nominal.front(), x1 = t.nominal.back();
  const std::size_t steps = std::max<std::size_t>(2000, 8 * t.size());
  double worst = 0;
  for (std::size_t k = 0; k <= steps; ++k) {
    const double x = x0 + (x1 - x0) * static_cast<double>(k) / static_cast<double>(steps);
    worst = std::max(worst, std::fabs(-t.forward_at(x) * um_per_unit - (m.deviation_um(x, 1) + offset_um)));
    worst = std::max(worst, std::fabs(-t.reverse_at(x) * um_per_unit - (m.deviation_um(x, -1) + offset_um)));
  }
  return worst;
}

CompTable make_comp_table(const ErrorModel& model, const TableOptions& o) {
  const double x0 = o.x_max > o.x_min ? o.x_min : model.x_min;
  const double x1 = o.x_max > o.x_min ? o.x_max : model.x_max;
  const double offset = reference_offset_um(model, o);
  const double L = x1 - x0;
  if (o.spacing_mm > 0) {
    return sample(model, x0, x1, static_cast<int>(std::ceil(L / o.spacing_mm - 1e-9)) + 1, offset, o.um_per_unit);
  }
  if (o.points > 0) return sample(model, x0, x1, o.points, offset, o.um_per_unit);
  // The fewest points within tolerance: interpolation error falls with the
  // spacing squared, so a doubling search then bisection finds it.
  int lo = 2, hi = 2;
  while (hi < o.max_points &&
         interpolation_error_um(sample(model, x0, x1, hi, offset, o.um_per_unit), model, offset, o.um_per_unit) >
             o.tolerance_um) {
    lo = hi;
    hi = std::min(hi * 2, o.max_points);
  }
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    if (interpolation_error_um(sample(model, x0, x1, mid, offset, o.um_per_unit), model, offset, o.um_per_unit) >
        o.tolerance_um) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return sample(model, x0, x1, hi, offset, o.um_per_unit);
}

Measurement predicted_after(const Measurement& m, const CompTable& t, double um_per_unit) {
  Measurement p = m;
  for (MeasurementPoint& q : p.points) q.deviation_um += t.at(q.target, q.direction) * um_per_unit;
  return p;
}

}  // namespace cnc::comp
