#include "hmi/positions.hpp"

#include <cmath>

#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::hmi {
namespace {

void rotate_xy(Pose& p, double degrees) {
  if (degrees == 0) return;
  const double r = degrees * M_PI / 180.0, c = std::cos(r), s = std::sin(r);
  const double x = p[0], y = p[1];
  p[0] = x * c - y * s;
  p[1] = x * s + y * c;
}

}  // namespace

bool program_inch(const ipc::Status& s) noexcept { return s.task.program_units == 1; }
bool machine_inch(const ipc::Status& s) noexcept { return s.motion.linear_units > 0 && s.motion.linear_units < 0.5; }

double program_to_machine(const ipc::Status& s) noexcept {
  const double mm_per_program_unit = program_inch(s) ? 25.4 : 1.0;
  const double units_per_mm = s.motion.linear_units > 0 ? s.motion.linear_units : 1.0;
  return mm_per_program_unit * units_per_mm;
}

DroPositions dro_positions(const ipc::Status& s, bool actual) {
  DroPositions d;
  d.valid = !actual || s.motion.carte_fb_valid;
  d.machine = actual ? s.motion.actual_position : s.motion.position;
  const double f = program_to_machine(s);
  Pose p;
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear_axis(a) ? f : 1.0;
    p[a] = d.machine[a] - (s.task.g5x_offset[a] + s.task.tool_offset[a]) * k;
  }
  rotate_xy(p, -s.task.rotation_xy);
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear_axis(a) ? f : 1.0;
    d.work[a] = p[a] / k - s.task.g92_offset[a];
    d.dtg[a] = s.motion.dtg[a] / k;
  }
  return d;
}

Pose touch_off_offsets(const ipc::Status& s, int axis, double value, bool actual) {
  const DroPositions now = dro_positions(s, actual);
  Pose wanted = now.work;
  if (axis >= 0 && axis < kNumAxes) wanted[axis] = value;
  const double f = program_to_machine(s);
  Pose r;
  for (int a = 0; a < kNumAxes; ++a) r[a] = (wanted[a] + s.task.g92_offset[a]) * (is_linear_axis(a) ? f : 1.0);
  rotate_xy(r, s.task.rotation_xy);
  Pose g5x;
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear_axis(a) ? f : 1.0;
    g5x[a] = (now.machine[a] - r[a]) / k - s.task.tool_offset[a];
  }
  return g5x;
}

bool diameter_mode(const ipc::Status& s) noexcept {
  for (int g : s.task.active_gcodes) {
    if (g == 70) return true;
  }
  return false;
}

std::string work_offset_name(int index) {
  static const char* kNames[] = {"G92", "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"};
  return index >= 0 && index <= 9 ? kNames[index] : "G5x?";
}

std::map<int, double> parse_parameter_text(std::string_view text) {
  std::map<int, double> out;
  for (const auto& line : split(text, '\n', true)) {
    const auto words = split_blanks(line);
    if (words.size() < 2) continue;
    const auto n = parse_int(words[0]);
    const auto v = parse_double(words[1]);
    if (n && v) out[static_cast<int>(*n)] = *v;
  }
  return out;
}

WorkOffsets work_offsets_from_parameters(const std::map<int, double>& params) {
  WorkOffsets w;
  const auto get = [&](int n) {
    const auto it = params.find(n);
    return it == params.end() ? 0.0 : it->second;
  };
  for (int i = 0; i < 9; ++i) {
    const int base = 5221 + 20 * i;
    for (int a = 0; a < kNumAxes; ++a) w.g5x[i][a] = get(base + a);
    w.rotation[i] = get(base + 9);
  }
  for (int a = 0; a < kNumAxes; ++a) w.g92[a] = get(5211 + a);
  const int active = static_cast<int>(std::lround(get(5220)));
  w.active = active >= 1 && active <= 9 ? active : 1;
  w.loaded = true;
  return w;
}

WorkOffsets read_work_offsets(const std::filesystem::path& parameter_file) {
  try {
    return work_offsets_from_parameters(parse_parameter_text(read_file(parameter_file)));
  } catch (const std::exception& e) {
    WorkOffsets w;
    w.error = e.what();
    return w;
  }
}

}  // namespace cnc::hmi
