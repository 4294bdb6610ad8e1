// The tool path of a program for the 3-D preview: the project's interpreter
// (core/interp) reads the file offline, in the screen's process, through a
// Canon that converts program to machine coordinates as the task controller
// does and samples arcs and splines into short lines. It only reads the
// program (and a copy of the parameter file); it never talks to the
// controller. Also checks the path against the axes' soft limits. No Qt;
// runs on a worker thread and can be cancelled.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/util/pose.hpp"

namespace cnc::hmi {

enum class MoveKind : uint8_t { Start = 0, Rapid = 1, Feed = 2, Arc = 3, Probe = 4 };

// A vertex of the path; the move from the previous vertex to this one has
// `kind` and comes from `line` (1-based source line of the main file or a
// subroutine's call site as the interpreter reports it).
struct PathPoint {
  float x = 0, y = 0, z = 0;
  int32_t line = 0;
  MoveKind kind = MoveKind::Start;
};

struct AxisLimit {
  int axis = 0;
  double min = -1e9, max = 1e9;
};

struct LimitViolation {
  int axis = 0;
  bool above = false;  // beyond the maximum (else below the minimum)
  double value = 0;    // the extreme reached
  double limit = 0;
  int first_line = 0;  // where it first happened
};

struct PreviewInput {
  std::filesystem::path program;
  std::filesystem::path ini;      // for the interpreter's configuration
  Pose start_machine;             // where the machine is now
  int tool_in_spindle = 0;
  bool block_delete = false;
  std::vector<AxisLimit> limits;  // soft limits to check, machine units
  std::size_t max_points = 4'000'000;
  long max_blocks = 20'000'000;
  double arc_tolerance = 0.005;   // chord error of sampled arcs, machine units
};

struct PreviewResult {
  std::filesystem::path program;
  std::vector<PathPoint> points;
  bool has_extents = false;
  Pose min, max;                  // of the program's moves, machine coordinates
  std::vector<LimitViolation> violations;
  std::string error;              // interpreter error (the path up to it is kept)
  int error_line = 0;
  bool truncated = false;         // max_points or max_blocks reached
  bool cancelled = false;
  long blocks = 0;
  std::vector<std::string> messages;  // (MSG, ...) of the program
};

// Interprets the program. `cancel` (optional) is polled between blocks.
PreviewResult build_preview(const PreviewInput& input, const std::atomic<bool>* cancel = nullptr);

// Where a path point leaves the limits (tests and the live check).
std::vector<LimitViolation> check_limits(const std::vector<PathPoint>& points, const std::vector<AxisLimit>& limits);

}  // namespace cnc::hmi
