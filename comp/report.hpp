// Reports a person can read: the ISO 230-2 figures of a measurement (per
// target and for the axis), a before/after comparison, and the fitted
// model's parameters with their uncertainties. Plain text. Offline.
#pragma once

#include <string>

#include "comp/fit.hpp"
#include "comp/iso230.hpp"

namespace cnc::comp {

std::string iso230_report(const Iso230Result& r, const std::string& title);
// The axis figures side by side, with the change in percent.
std::string iso230_comparison(const Iso230Result& before, const Iso230Result& after, const std::string& before_label,
                              const std::string& after_label);
std::string fit_report(const FitResult& f);

}  // namespace cnc::comp
