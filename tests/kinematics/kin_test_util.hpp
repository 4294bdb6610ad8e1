// Shared by the kinematics tests: seeded random numbers (seed from
// CNC_TEST_SEED when set, printed on failure), pose comparisons, and ready
// modules with realistic geometry.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <string>

#include "core/util/pose.hpp"

namespace cnc::kin::testing {

inline uint64_t test_seed(uint64_t fallback) {
  if (const char* s = std::getenv("CNC_TEST_SEED")) return std::strtoull(s, nullptr, 0);
  return fallback;
}

// A generator whose seed every failure message shows (SCOPED_TRACE), and
// how to repeat the run.
class Rng {
 public:
  explicit Rng(uint64_t fallback_seed)
      : seed_(test_seed(fallback_seed)),
        gen_(seed_),
        trace_(__FILE__, __LINE__, "seed " + std::to_string(seed_) + " (rerun with CNC_TEST_SEED=" +
                                       std::to_string(seed_) + ")") {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen_); }
  uint64_t seed() const { return seed_; }

 private:
  uint64_t seed_;
  std::mt19937_64 gen_;
  ::testing::ScopedTrace trace_;
};

inline double linear_error(const Pose& a, const Pose& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// Largest difference over all nine coordinates.
inline double max_error(const Pose& a, const Pose& b) {
  double m = 0;
  for (int i = 0; i < kNumAxes; ++i) m = std::fmax(m, std::abs(a[i] - b[i]));
  return m;
}

// Difference of two angles in degrees, folded into [0, 180].
inline double angle_error_deg(double a, double b) {
  const double d = std::remainder(a - b, 360.0);
  return std::abs(d);
}

inline std::string pose_text(const Pose& p) {
  std::string s;
  for (int i = 0; i < kNumAxes; ++i) s += std::string(1, kAxisLetters[i]) + "=" + std::to_string(p[i]) + " ";
  return s;
}

}  // namespace cnc::kin::testing
