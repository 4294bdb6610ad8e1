// Plots of measurements as PNG images (OpenCV drawing): for each panel the
// measured deviations (up and down runs), the mean deviations per target
// with the +-2 s bands of ISO 230-2, the axis figures, and optionally the
// fitted model's curves. Offline only; OpenCV stays inside plot.cpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "comp/error_model.hpp"
#include "comp/iso230.hpp"
#include "comp/measurement.hpp"

namespace cnc::comp {

struct PlotPanel {
  std::string title;
  const Measurement* measurement = nullptr;  // required
  const Iso230Result* iso = nullptr;         // optional: means, bands, figures
  const ErrorModel* model = nullptr;         // optional: model curves (reference temperature)
  double model_offset_um = 0;                // added to the model curves
};

// One image with the panels stacked; encoded PNG bytes.
std::vector<uint8_t> plot_png(const std::vector<PlotPanel>& panels, int width = 1280, int panel_height = 520);
// The same, written atomically to `path`.
void write_plot(const std::filesystem::path& path, const std::vector<PlotPanel>& panels);

}  // namespace cnc::comp
