#include "comp/fit.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>

namespace cnc::comp {
namespace {

constexpr int kPeriodic = 4;  // two harmonics: a1 c1 a2 c2

struct Sample {
  double x = 0;
  int direction = 1;
  double y = 0;               // measured deviation, um
  double temperature = 20;
};

// One measured point: the model at the point minus the measurement, in
// noise standard deviations. The model is linear in every parameter.
struct PointResidual {
  double w[4];
  double half_dir;            // d / 2
  double xn;                  // (x - x_mid) / L
  double dtx;                 // (T - T_ref) (x - x_min) 1e-3
  double dt;                  // T - T_ref
  double sn[2], cs[2];
  double y, inv_sigma;

  template <class T>
  bool operator()(const T* c0, const T* c1, const T* c2, const T* c3, const T* backlash, const T* thermal,
                  const T* periodic, T* r) const {
    T v = w[0] * c0[0] + w[1] * c1[0] + w[2] * c2[0] + w[3] * c3[0];
    v += half_dir * (backlash[0] + backlash[1] * xn);
    v += thermal[0] * dtx + thermal[1] * dt;
    v += periodic[0] * sn[0] + periodic[1] * cs[0] + periodic[2] * sn[1] + periodic[3] * cs[1];
    r[0] = (v - y) * inv_sigma;
    return true;
  }
};

// Smoothness prior: the spline's second difference, in prior standard deviations.
struct SecondDifference {
  double inv_sigma;
  template <class T>
  bool operator()(const T* a, const T* b, const T* c, T* r) const {
    r[0] = (a[0] - 2.0 * b[0] + c[0]) * inv_sigma;
    return true;
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t k = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// Pooled repeatability: the spread of repeated runs at a target and
// direction within one measurement.
double repeatability_sigma(const std::vector<Measurement>& data) {
  double ss = 0;
  int dof = 0;
  for (const Measurement& m : data) {
    std::vector<std::pair<std::pair<double, int>, std::vector<double>>> groups;
    for (const MeasurementPoint& p : m.points) {
      auto it = std::find_if(groups.begin(), groups.end(), [&](const auto& g) {
        return g.first.second == p.direction && std::fabs(g.first.first - p.target) <= 1e-6;
      });
      if (it == groups.end()) {
        groups.push_back({{p.target, p.direction}, {}});
        it = groups.end() - 1;
      }
      it->second.push_back(p.deviation_um);
    }
    for (const auto& g : groups) {
      if (g.second.size() < 2) continue;
      double mean = 0;
      for (double v : g.second) mean += v;
      mean /= static_cast<double>(g.second.size());
      // Median absolute deviation keeps an outlier from inflating the estimate.
      std::vector<double> dev;
      for (double v : g.second) dev.push_back(std::fabs(v - mean));
      const double s = 1.4826 * median(dev);
      ss += s * s * static_cast<double>(g.second.size() - 1);
      dof += static_cast<int>(g.second.size() - 1);
    }
  }
  return dof > 0 ? std::sqrt(ss / dof) : 0;
}

// Knot spacing: the spacing of the targets measured in both directions
// with repeats (the ISO targets; with several measurements, the coarsest:
// dense periodic runs must not make the spline fine), at least two leads so
// that the spline cannot take up the periodic error.
double default_knot_spacing(const std::vector<Measurement>& data, double travel, double lead) {
  double h = 0;
  for (const Measurement& m : data) {
    std::vector<double> targets;
    for (const MeasurementPoint& p : m.points) {
      int up = 0, down = 0;
      for (const MeasurementPoint& q : m.points) {
        if (std::fabs(q.target - p.target) > 1e-6) continue;
        (q.direction > 0 ? up : down)++;
      }
      if (up >= 2 && down >= 2) targets.push_back(p.target);
    }
    std::sort(targets.begin(), targets.end());
    targets.erase(
        std::unique(targets.begin(), targets.end(), [](double a, double b) { return std::fabs(a - b) <= 1e-6; }),
        targets.end());
    std::vector<double> gaps;
    for (std::size_t i = 1; i < targets.size(); ++i) gaps.push_back(targets[i] - targets[i - 1]);
    if (!gaps.empty()) h = std::max(h, median(gaps));
  }
  if (h <= 0) h = travel / 10;
  if (lead > 0) h = std::max(h, 2 * lead);
  return std::clamp(h, travel / 200, travel);
}

}  // namespace

double FitResult::deviation_sigma_um(double x, int direction) const {
  if (!covariance_ok) return 0;
  std::vector<double> g(layout.size, 0.0);
  const SplineBasis b = spline_basis(x, model.x_min, model.x_max, model.segments());
  for (int i = 0; i < 4; ++i) g[layout.spline + b.first + static_cast<std::size_t>(i)] = b.w[i];
  const double half = direction > 0 ? 0.5 : -0.5;
  g[layout.backlash] = half;
  g[layout.backlash + 1] = half * (x - model.middle()) / (model.length() > 0 ? model.length() : 1);
  if (model.lead_mm > 0) {
    for (int h = 0; h < 2; ++h) {
      const double ph = 2 * std::numbers::pi * (h + 1) * x / model.lead_mm;
      g[layout.periodic + 2 * static_cast<std::size_t>(h)] = std::sin(ph);
      g[layout.periodic + 2 * static_cast<std::size_t>(h) + 1] = std::cos(ph);
    }
  }
  double v = 0;
  for (std::size_t i = 0; i < layout.size; ++i) {
    if (g[i] == 0) continue;
    for (std::size_t j = 0; j < layout.size; ++j) v += g[i] * covariance[i * layout.size + j] * g[j];
  }
  return std::sqrt(std::max(v, 0.0));
}

FitResult fit_error_model(const std::vector<Measurement>& data, const FitOptions& o) {
  std::vector<Sample> samples;
  double tmin = 1e300, tmax = -1e300;
  bool all_temps = true;
  for (const Measurement& m : data) {
    for (const MeasurementPoint& p : m.points) {
      Sample s{p.target, p.direction > 0 ? 1 : -1, p.deviation_um, o.reference_temperature_c};
      if (std::isfinite(p.temperature_c)) {
        s.temperature = p.temperature_c;
        tmin = std::min(tmin, p.temperature_c);
        tmax = std::max(tmax, p.temperature_c);
      } else {
        all_temps = false;
      }
      samples.push_back(s);
    }
  }
  if (samples.size() < 8) throw std::invalid_argument("too few measured points to fit a model (" +
                                                      std::to_string(samples.size()) + ")");
  FitResult res;
  res.points = static_cast<int>(samples.size());
  ErrorModel& model = res.model;
  double xlo = 1e300, xhi = -1e300;
  for (const Sample& s : samples) {
    xlo = std::min(xlo, s.x);
    xhi = std::max(xhi, s.x);
  }
  model.x_min = o.x_max > o.x_min ? o.x_min : xlo;
  model.x_max = o.x_max > o.x_min ? o.x_max : xhi;
  const double travel = model.x_max - model.x_min;
  if (!(travel > 0)) throw std::invalid_argument("the measurements cover no travel (one target only)");
  model.reference_temperature_c = o.reference_temperature_c;
  model.thermal_origin_mm = model.x_min;
  model.lead_mm = o.lead_mm > 0 ? o.lead_mm : 0;
  const int harmonics = std::clamp(o.harmonics, 1, 2);

  const double spacing = o.knot_spacing_mm > 0 ? o.knot_spacing_mm : default_knot_spacing(data, travel, model.lead_mm);
  const std::size_t segments = static_cast<std::size_t>(std::max(1.0, std::round(travel / spacing)));
  model.spline.assign(segments + 3, 0.0);
  {
    char b[160];
    std::snprintf(b, sizeof b, "geometric error: cubic B-spline, %zu segments of %.3f mm over %.3f..%.3f mm", segments,
                  travel / static_cast<double>(segments), model.x_min, model.x_max);
    res.notes.push_back(b);
  }
  // Backlash is the difference between the two approach directions at the
  // same target: without a target measured both ways it is not in the
  // data (the spline would take any value the solver gave it), and its
  // change over travel needs two such targets.
  int reversal_targets = 0;
  {
    std::vector<std::pair<double, int>> xd;
    for (const Sample& s : samples) xd.emplace_back(s.x, s.direction);
    std::sort(xd.begin(), xd.end());
    for (std::size_t i = 0; i < xd.size();) {
      std::size_t k = i;
      bool up = false, down = false;
      for (; k < xd.size() && xd[k].first - xd[i].first <= 1e-6; ++k) (xd[k].second > 0 ? up : down) = true;
      if (up && down) ++reversal_targets;
      i = k;
    }
  }
  const bool fit_backlash = reversal_targets > 0;
  const bool fit_backlash_change = o.backlash_varies && reversal_targets >= 2;
  model.backlash_measured = fit_backlash;
  res.reversal_targets = reversal_targets;
  if (!fit_backlash) {
    int up = 0;
    for (const Sample& s : samples) up += s.direction > 0;
    res.notes.push_back(
        "backlash not fitted: no target was approached from both directions (" + std::to_string(up) + " points moving +, " +
        std::to_string(samples.size() - static_cast<std::size_t>(up)) +
        " moving -); it is taken as 0, so the tables' forward and reverse trims are equal. Measure both directions "
        "(ISO 230-2) to compensate backlash");
  } else if (o.backlash_varies && !fit_backlash_change) {
    res.notes.push_back("backlash change over travel not fitted: the reversal was measured at one target only");
  }
  const bool thermal = o.thermal && all_temps && tmax - tmin >= o.min_temperature_range_k;
  model.has_thermal = thermal;
  if (o.thermal && !thermal) {
    res.notes.push_back(all_temps && tmax >= tmin
                            ? "thermal term not fitted: the temperature changed by less than " +
                                  std::to_string(o.min_temperature_range_k) + " K (it would merge into the slope)"
                            : "thermal term not fitted: no temperature with every point");
  }

  // Parameters.
  std::vector<double> coeff(model.spline.size(), 0.0);
  double backlash[2] = {0, 0}, therm[2] = {0, 0}, periodic[kPeriodic] = {0, 0, 0, 0};
  {
    // Start from the mean reversal and the mean level.
    double up = 0, down = 0;
    int nu = 0, nd = 0;
    for (const Sample& s : samples) {
      if (s.direction > 0) { up += s.y; ++nu; } else { down += s.y; ++nd; }
    }
    if (nu > 0 && nd > 0) backlash[0] = up / nu - down / nd;
    const double level = (up + down) / static_cast<double>(nu + nd);
    std::fill(coeff.begin(), coeff.end(), level);
  }

  double sigma = o.noise_um > 0 ? o.noise_um : repeatability_sigma(data);
  if (!(sigma > 0)) sigma = 0.5;
  sigma = std::max(sigma, 1e-3);

  ceres::Solver::Summary summary;
  int total_iterations = 0;
  double first_cost = -1;
  std::vector<double> resid(samples.size(), 0.0);
  // With the noise given: one solve. Otherwise the first solve (Huber,
  // convex) starts from the repeatability, and the noise the residuals
  // show sets the weights of the next, until it settles.
  const int max_passes = o.noise_um > 0 ? 1 : 5;
  std::unique_ptr<ceres::Problem> problem;
  for (int pass = 0; pass < max_passes; ++pass) {
    ceres::Problem::Options po;
    problem = std::make_unique<ceres::Problem>(po);
    for (double& c : coeff) problem->AddParameterBlock(&c, 1);
    problem->AddParameterBlock(backlash, 2);
    problem->AddParameterBlock(therm, 2);
    problem->AddParameterBlock(periodic, kPeriodic);
    const double inv = 1.0 / sigma;
    const double L = travel;
    for (const Sample& s : samples) {
      const SplineBasis b = spline_basis(s.x, model.x_min, model.x_max, segments);
      auto* f = new PointResidual;
      for (int i = 0; i < 4; ++i) f->w[i] = b.w[i];
      f->half_dir = 0.5 * s.direction;
      f->xn = (s.x - model.middle()) / L;
      const double dT = thermal ? s.temperature - model.reference_temperature_c : 0;
      f->dtx = dT * (s.x - model.thermal_origin_mm) * 1e-3;
      f->dt = dT;
      for (int h = 0; h < 2; ++h) {
        const double ph = model.lead_mm > 0 ? 2 * std::numbers::pi * (h + 1) * s.x / model.lead_mm : 0;
        f->sn[h] = model.lead_mm > 0 ? std::sin(ph) : 0;
        f->cs[h] = model.lead_mm > 0 ? std::cos(ph) : 0;
      }
      f->y = s.y;
      f->inv_sigma = inv;
      ceres::LossFunction* loss = nullptr;
      // First pass: Huber, convex, from a rough noise level; the second uses
      // the noise the residuals show and the loss asked for.
      const RobustLoss kind = pass == 0 && max_passes > 1 && o.loss != RobustLoss::None ? RobustLoss::Huber : o.loss;
      if (kind == RobustLoss::Huber) loss = new ceres::HuberLoss(o.loss_scale);
      else if (kind == RobustLoss::Cauchy) loss = new ceres::CauchyLoss(o.loss_scale);
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<PointResidual, 1, 1, 1, 1, 1, 2, 2, kPeriodic>(f), loss,
                                &coeff[b.first], &coeff[b.first + 1], &coeff[b.first + 2], &coeff[b.first + 3],
                                backlash, therm, periodic);
    }
    const double inv_prior = 1.0 / std::max(o.smoothness_um, 1e-6);
    for (std::size_t i = 0; i + 2 < coeff.size(); ++i) {
      problem->AddResidualBlock(
          new ceres::AutoDiffCostFunction<SecondDifference, 1, 1, 1, 1>(new SecondDifference{inv_prior}), nullptr,
          &coeff[i], &coeff[i + 1], &coeff[i + 2]);
    }
    if (!fit_backlash) {
      backlash[0] = backlash[1] = 0;
      problem->SetParameterBlockConstant(backlash);
    } else if (!fit_backlash_change) {
      backlash[1] = 0;
      problem->SetManifold(backlash, new ceres::SubsetManifold(2, {1}));
    }
    if (!thermal) {
      therm[0] = therm[1] = 0;
      problem->SetParameterBlockConstant(therm);
    }
    if (model.lead_mm <= 0) {
      std::fill(periodic, periodic + kPeriodic, 0.0);
      problem->SetParameterBlockConstant(periodic);
    } else if (harmonics == 1) {
      periodic[2] = periodic[3] = 0;
      problem->SetManifold(periodic, new ceres::SubsetManifold(kPeriodic, {2, 3}));
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = o.max_iterations;
    so.function_tolerance = 1e-12;
    so.gradient_tolerance = 1e-12;
    so.parameter_tolerance = 1e-12;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solve(so, problem.get(), &summary);
    total_iterations += static_cast<int>(summary.iterations.size());
    if (first_cost < 0) first_cost = summary.initial_cost;

    // Residuals in micrometres, and the noise they show.
    model.spline = coeff;
    model.backlash0_um = backlash[0];
    model.backlash1_um = backlash[1];
    model.thermal_ppm_per_k = therm[0];
    model.sin_um.assign(static_cast<std::size_t>(harmonics), 0.0);
    model.cos_um.assign(static_cast<std::size_t>(harmonics), 0.0);
    for (int h = 0; h < harmonics; ++h) {
      model.sin_um[static_cast<std::size_t>(h)] = periodic[2 * h];
      model.cos_um[static_cast<std::size_t>(h)] = periodic[2 * h + 1];
    }
    std::vector<double> abs_resid;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const Sample& s = samples[i];
      double v = model.deviation_um(s.x, s.direction);
      if (thermal) v += therm[0] * (s.temperature - model.reference_temperature_c) * (s.x - model.thermal_origin_mm) * 1e-3 +
                        therm[1] * (s.temperature - model.reference_temperature_c);
      resid[i] = s.y - v;
      abs_resid.push_back(std::fabs(resid[i]));
    }
    if (max_passes > 1) {
      const double robust = std::max(1.4826 * median(abs_resid), 1e-3);
      const bool settled = pass > 0 && std::fabs(robust - sigma) <= 0.1 * sigma;
      if (settled) break;
      sigma = robust;
    }
  }
  res.iterations = total_iterations;
  res.initial_cost = first_cost;
  res.final_cost = summary.final_cost;
  res.converged = summary.termination_type == ceres::CONVERGENCE;
  res.noise_um = sigma;
  res.residuals_um = resid;
  double ss = 0;
  int n_in = 0;
  for (double r : resid) {
    if (std::fabs(r) > 5 * sigma) {
      ++res.outliers;
    } else {
      ss += r * r;
      ++n_in;
    }
  }
  res.residual_rms_um = n_in > 0 ? std::sqrt(ss / n_in) : 0;
  // The thermal offset per kelvin moves the whole axis: fold it into the
  // origin of the expansion so that the model keeps one coefficient.
  if (thermal && std::fabs(therm[0]) > 1e-12) {
    model.thermal_origin_mm = model.x_min - therm[1] / (therm[0] * 1e-3);
  }

  // Uncertainties.
  res.layout.spline = 0;
  res.layout.backlash = coeff.size();
  res.layout.thermal = res.layout.backlash + 2;
  res.layout.periodic = res.layout.thermal + 2;
  res.layout.size = res.layout.periodic + kPeriodic;
  {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;
    co.min_reciprocal_condition_number = 1e-14;
    co.apply_loss_function = true;
    ceres::Covariance cov(co);
    std::vector<const double*> blocks;
    for (const double& c : coeff) blocks.push_back(&c);
    blocks.push_back(backlash);
    blocks.push_back(therm);
    blocks.push_back(periodic);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      for (std::size_t j = i; j < blocks.size(); ++j) pairs.emplace_back(blocks[i], blocks[j]);
    }
    if (cov.Compute(pairs, problem.get())) {
      res.covariance.assign(res.layout.size * res.layout.size, 0.0);
      res.covariance_ok = cov.GetCovarianceMatrix(blocks, res.covariance.data());
    }
    if (!res.covariance_ok) res.notes.push_back("parameter covariance not available (the problem is degenerate)");
  }
  const auto var = [&](std::size_t i) { return res.covariance_ok ? res.covariance[i * res.layout.size + i] : 0.0; };
  const auto cov = [&](std::size_t i, std::size_t j) {
    return res.covariance_ok ? res.covariance[i * res.layout.size + j] : 0.0;
  };
  const auto add = [&](const std::string& name, double value, double variance, const std::string& unit) {
    res.parameters.push_back(ParameterEstimate{name, value, std::sqrt(std::max(variance, 0.0)), unit});
  };
  const std::size_t bl = res.layout.backlash, th = res.layout.thermal, pe = res.layout.periodic;
  if (fit_backlash) {
    add("backlash b0 (mean reversal)", backlash[0], var(bl), "um");
    if (fit_backlash_change) add("backlash change over travel b1", backlash[1], var(bl + 1), "um");
    add("backlash at x_min", model.backlash_um(model.x_min), var(bl) + 0.25 * var(bl + 1) - cov(bl, bl + 1), "um");
    add("backlash at x_max", model.backlash_um(model.x_max), var(bl) + 0.25 * var(bl + 1) + cov(bl, bl + 1), "um");
  }
  if (thermal) {
    add("thermal expansion k", therm[0], var(th), "ppm/K");
    add("thermal drift at x_min", therm[1], var(th + 1), "um/K");
  }
  if (model.lead_mm > 0) {
    for (int h = 0; h < harmonics; ++h) {
      const std::size_t i = pe + 2 * static_cast<std::size_t>(h);
      const double a = periodic[2 * h], c = periodic[2 * h + 1];
      const double amp = std::hypot(a, c);
      const std::string tag = h == 0 ? "" : " (harmonic 2)";
      add("periodic sine" + tag, a, var(i), "um");
      add("periodic cosine" + tag, c, var(i + 1), "um");
      const double vamp = amp > 0 ? (a * a * var(i) + c * c * var(i + 1) + 2 * a * c * cov(i, i + 1)) / (amp * amp) : 0;
      add("periodic amplitude" + tag, amp, vamp, "um");
      const double vph = amp > 0 ? (c * c * var(i) + a * a * var(i + 1) - 2 * a * c * cov(i, i + 1)) / std::pow(amp, 4) : 0;
      add("periodic phase" + tag, std::atan2(c, a) * 180 / std::numbers::pi, vph * std::pow(180 / std::numbers::pi, 2),
          "deg");
    }
  }
  if (res.covariance_ok) {
    for (int k = 0; k <= 200; ++k) {
      const double x = model.x_min + travel * k / 200.0;
      const SplineBasis b = spline_basis(x, model.x_min, model.x_max, segments);
      double v = 0;
      for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) v += b.w[i] * b.w[j] * cov(b.first + static_cast<std::size_t>(i), b.first + static_cast<std::size_t>(j));
      }
      res.max_geometric_sigma_um = std::max(res.max_geometric_sigma_um, std::sqrt(std::max(v, 0.0)));
    }
  }
  add("noise (repeatability) sigma", sigma, 0, "um");
  return res;
}

}  // namespace cnc::comp
