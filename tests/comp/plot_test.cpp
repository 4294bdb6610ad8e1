// Plots: a PNG of the stated size, written atomically; refused without data.
#include <gtest/gtest.h>

#include "comp/iso230.hpp"
#include "comp/plot.hpp"
#include "core/util/atomic_file.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::comp;

namespace {
uint32_t be32(const uint8_t* p) { return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3]; }
}  // namespace

TEST(Plot, WritesAPngWithOnePanelPerMeasurement) {
  Measurement m;
  for (int i = 0; i < 4; ++i) {
    for (int d : {1, -1}) {
      for (int r = 1; r <= 3; ++r) {
        MeasurementPoint p;
        p.target = i * 50;
        p.direction = d;
        p.run = r;
        p.deviation_um = i * 1.5 + d * 2 + r * 0.1;
        m.points.push_back(p);
      }
    }
  }
  const Iso230Result iso = evaluate_iso230(m);
  ErrorModel model;
  model.x_min = 0;
  model.x_max = 150;
  model.spline = {0, 1, 3, 4.5};
  model.backlash0_um = 4;
  const auto png = plot_png({PlotPanel{"before", &m, &iso, &model}, PlotPanel{"after", &m, nullptr}}, 900, 400);
  ASSERT_GT(png.size(), 2000u);
  const uint8_t magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  EXPECT_TRUE(std::equal(magic, magic + 8, png.begin()));
  EXPECT_EQ(be32(&png[16]), 900u) << "width";
  EXPECT_EQ(be32(&png[20]), 800u) << "two panels of 400";
  cnc::testing::TempDir dir;
  write_plot(dir / "p.png", {PlotPanel{"one", &m, &iso}});
  EXPECT_GT(cnc::read_file(dir / "p.png").size(), 1000u);
  Measurement empty;
  EXPECT_THROW(plot_png({PlotPanel{"none", &empty}}), std::invalid_argument);
  EXPECT_THROW(plot_png({}), std::invalid_argument);
}
