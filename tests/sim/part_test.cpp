// The simulated part for probing (sim/machine/part.hpp): where a ball tip
// touches the block, its bore, its top and its edges, and the [SIM_PART]
// errors naming file, line and key.
#include <gtest/gtest.h>

#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/error.hpp"
#include "sim/machine/part.hpp"

using namespace cnc;

namespace {

// A block 0..60 x 0..40, top at Z -80, a bore of 20 about (30, 20), tip 3.
sim::Part part() {
  return sim::Part::from_ini(ini::IniFile::parse("[SIM_PART]\nX_MIN = 0\nX_MAX = 60\nY_MIN = 0\nY_MAX = 40\nZ_TOP = -80\n"
                                                 "BORE_X = 30\nBORE_Y = 20\nBORE_DIAMETER = 20\nTIP_DIAMETER = 3\n",
                                                 "part.ini"),
                             "SIM_PART");
}

std::string error_of(const std::string& text) {
  try {
    sim::Part::from_ini(ini::IniFile::parse(text, "part.ini"), "SIM_PART");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SimPart, TheTipTouchesAnOutsideFaceAtItsRadius) {
  const sim::Part p = part();
  EXPECT_FALSE(p.touches(-1.5001, 20, -85));
  EXPECT_TRUE(p.touches(-1.5, 20, -85));
  EXPECT_TRUE(p.touches(61.4999, 20, -85));
  EXPECT_FALSE(p.touches(30, 41.5001, -85));
  EXPECT_DOUBLE_EQ(p.distance(-4, 20, -85), 4);
  EXPECT_DOUBLE_EQ(p.distance(-3, -4, -85), 5);  // off the corner
}

TEST(SimPart, InTheBoreTheTipTouchesTheWallAtItsRadius) {
  const sim::Part p = part();
  EXPECT_FALSE(p.touches(30, 20, -85));
  EXPECT_DOUBLE_EQ(p.distance(30, 20, -85), 10);
  EXPECT_FALSE(p.touches(38.4999, 20, -85));
  EXPECT_TRUE(p.touches(38.5, 20, -85));
  EXPECT_TRUE(p.touches(30, 20 - 8.5, -85));
  EXPECT_TRUE(p.touches(30 + 8.5001 / std::sqrt(2.0), 20 + 8.5001 / std::sqrt(2.0), -85));
  EXPECT_FALSE(p.touches(30 + 8.4999 / std::sqrt(2.0), 20 + 8.4999 / std::sqrt(2.0), -85));
}

TEST(SimPart, AboveTheTopTheBallTouchesTheFaceAndRollsOverTheEdges) {
  const sim::Part p = part();
  EXPECT_TRUE(p.touches(5, 5, -78.5));
  EXPECT_FALSE(p.touches(5, 5, -78.4999));
  // Over the bore: only its rim, not the bore's bottom.
  EXPECT_FALSE(p.touches(30, 20, -100 + 0));  // in the bore, far from the wall
  // A ball over the outside edge touches the edge, not the face's plane.
  EXPECT_DOUBLE_EQ(p.distance(-1, 20, -79), std::sqrt(2.0));
  EXPECT_TRUE(p.touches(-1, 20, -79));
  EXPECT_FALSE(p.touches(-1.1, 20, -78.9));
}

TEST(SimPart, ConfigErrorsNameFileLineAndKey) {
  EXPECT_NE(error_of("[SIM_PART]\nX_MIN = 0\nX_MAX = 60\nY_MIN = 0\nY_MAX = 40\n").find("Z_TOP"), std::string::npos);
  const std::string empty = error_of("[SIM_PART]\nX_MIN = 5\nX_MAX = 5\nY_MIN = 0\nY_MAX = 40\nZ_TOP = 0\n");
  EXPECT_NE(empty.find("part.ini:3"), std::string::npos) << empty;
  EXPECT_NE(empty.find("X_MAX must be above X_MIN"), std::string::npos) << empty;
  const std::string bore =
      error_of("[SIM_PART]\nX_MIN = 0\nX_MAX = 60\nY_MIN = 0\nY_MAX = 40\nZ_TOP = 0\nBORE_DIAMETER = 40\n");
  EXPECT_NE(bore.find("part.ini:7"), std::string::npos) << bore;
  EXPECT_NE(bore.find("inside the block"), std::string::npos) << bore;
}
