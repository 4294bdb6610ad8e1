#include "comp/report.hpp"

#include <cmath>
#include <cstdarg>
#include <cstdio>

namespace cnc::comp {
namespace {

__attribute__((format(printf, 2, 3))) void line(std::string& out, const char* fmt, ...) {
  char b[512];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(b, sizeof b, fmt, ap);
  va_end(ap);
  out += b;
  out += "\n";
}

}  // namespace

std::string iso230_report(const Iso230Result& r, const std::string& title) {
  std::string out;
  line(out, "%s", title.c_str());
  line(out, "ISO 230-2 positioning accuracy and repeatability, %zu targets from %.3f to %.3f mm, %d runs per direction",
       r.targets.size(), r.targets.front().position, r.targets.back().position, r.min_runs);
  line(out, "deviations in micrometres (position reached minus target); up = approached moving +");
  out += "\n";
  line(out, "%10s %8s %8s %8s %8s %7s %7s %7s %7s %7s", "target mm", "mean up", "mean dn", "mean", "B_i", "s up", "s dn",
       "R_i up", "R_i dn", "R_i");
  for (const Iso230Target& t : r.targets) {
    line(out, "%10.3f %8.3f %8.3f %8.3f %8.3f %7.3f %7.3f %7.3f %7.3f %7.3f", t.position, t.mean_up, t.mean_down,
         t.mean, t.reversal, t.s_up, t.s_down, t.r_up, t.r_down, t.r);
  }
  out += "\n";
  line(out, "  accuracy                     A  = %8.3f   A up = %8.3f   A down = %8.3f", r.A, r.A_up, r.A_down);
  line(out, "  systematic deviation         E  = %8.3f   E up = %8.3f   E down = %8.3f", r.E, r.E_up, r.E_down);
  line(out, "  repeatability                R  = %8.3f   R up = %8.3f   R down = %8.3f", r.R, r.R_up, r.R_down);
  line(out, "  reversal value               B  = %8.3f   mean B = %8.3f", r.B, r.B_mean);
  line(out, "  mean bidirectional range     M  = %8.3f", r.M);
  for (const std::string& w : r.warnings) line(out, "  note: %s", w.c_str());
  return out;
}

std::string iso230_comparison(const Iso230Result& a, const Iso230Result& b, const std::string& la,
                              const std::string& lb) {
  std::string out;
  line(out, "%-28s %12s %12s %10s", "ISO 230-2 figure (um)", la.c_str(), lb.c_str(), "change");
  const auto row = [&](const char* name, double x, double y) {
    const double pct = std::fabs(x) > 1e-12 ? (y - x) / std::fabs(x) * 100 : 0;
    line(out, "%-28s %12.3f %12.3f %9.1f%%", name, x, y, pct);
  };
  row("A   accuracy", a.A, b.A);
  row("A up", a.A_up, b.A_up);
  row("A down", a.A_down, b.A_down);
  row("E   systematic deviation", a.E, b.E);
  row("E up", a.E_up, b.E_up);
  row("E down", a.E_down, b.E_down);
  row("R   repeatability", a.R, b.R);
  row("R up", a.R_up, b.R_up);
  row("R down", a.R_down, b.R_down);
  row("B   reversal value", a.B, b.B);
  row("mean B", a.B_mean, b.B_mean);
  row("M   mean bidirectional range", a.M, b.M);
  return out;
}

std::string fit_report(const FitResult& f) {
  std::string out;
  line(out, "Fitted error model (robust least squares, Ceres)");
  line(out, "  %d points, %d iterations, cost %.4g -> %.4g%s", f.points, f.iterations, f.initial_cost, f.final_cost,
       f.converged ? "" : " (stopped before convergence)");
  line(out, "  residual RMS %.3f um (noise sigma %.3f um), %d outliers beyond 5 sigma", f.residual_rms_um, f.noise_um,
       f.outliers);
  for (const std::string& n : f.notes) line(out, "  %s", n.c_str());
  line(out, "  %-36s %12s %10s  %s", "parameter", "value", "+- sigma", "unit");
  for (const ParameterEstimate& p : f.parameters) {
    line(out, "  %-36s %12.4f %10.4f  %s", p.name.c_str(), p.value, p.sigma, p.unit.c_str());
  }
  if (f.covariance_ok) line(out, "  geometric error S(x): standard uncertainty at most %.3f um", f.max_geometric_sigma_um);
  return out;
}

}  // namespace cnc::comp
