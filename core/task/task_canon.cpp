#include "core/task/task_canon.hpp"

#include <algorithm>
#include <cmath>

#include "core/ini/ini_file.hpp"
#include "core/util/strings.hpp"

namespace cnc::task {
namespace {

bool is_linear(int axis) noexcept { return axis < 3 || axis > 5; }  // XYZ and UVW; ABC are angles

}  // namespace

CanonConfig canon_config(const ini::IniFile& ini, const motion::MotionConfig& m, uint32_t axis_mask) {
  CanonConfig c;
  c.machine_units_per_mm = m.linear_units_per_mm;
  c.axis_mask = axis_mask;
  if (const auto pos = ini.find("EMCIO", "TOOL_CHANGE_POSITION")) {
    const auto words = split_blanks(*pos);
    c.has_tool_change_position = true;
    for (std::size_t i = 0; i < words.size() && i < static_cast<std::size_t>(kNumAxes); ++i) {
      const auto v = parse_double(words[i]);
      if (!v) ini.fail(ini.find_entry("EMCIO", "TOOL_CHANGE_POSITION"), "expected numbers X Y Z [A B C ...]");
      c.tool_change_position[static_cast<int>(i)] = *v;
    }
  }
  c.tool_change_quill_up = ini.get_bool("EMCIO", "TOOL_CHANGE_QUILL_UP", false);
  return c;
}

void view_limits(const motion::MotionStatus& ms, MachineView& view) {
  view.max_linear_velocity = ms.traj.max_linear_velocity;
  view.max_linear_acceleration = ms.traj.max_linear_acceleration;
  // The fastest an axis may go bounds rapids when [TRAJ] gives no maximum.
  double rapid = ms.traj.max_linear_velocity;
  if (!(rapid < 1e98)) {
    rapid = 0;
    for (int a = 0; a < kNumAxes; ++a) {
      if (ms.traj.axis_mask & (1u << a)) rapid = std::max(rapid, ms.axes[a].velocity_limit);
    }
  }
  view.rapid_velocity = rapid > 0 ? rapid : 1;
  if (!(view.max_linear_velocity < 1e98)) view.max_linear_velocity = view.rapid_velocity;
}

TaskCanon::TaskCanon(CanonConfig config, std::deque<Item>& items, const MachineView& machine)
    : cfg_(config), items_(items), machine_(machine) {}

void TaskCanon::reset_state() {
  plane_ = interp::Plane::XY;
  term_ = tp::TermCond::Blend;
  tolerance_ = naive_tolerance_ = 0;
  feed_mode_ = interp::FeedMode::UnitsPerMinute;
}

double TaskCanon::length_factor() const noexcept {
  const double mm = units_ == interp::Units::Inch ? 25.4 : units_ == interp::Units::Cm ? 10.0 : 1.0;
  return mm * cfg_.machine_units_per_mm;
}

interp::Units TaskCanon::machine_length_units() const {
  return cfg_.machine_units_per_mm < 0.5 ? interp::Units::Inch : interp::Units::Mm;
}

void TaskCanon::use_length_units(interp::Units u) {
  // The offsets were given in the program units of their time (the
  // interpreter converts its own copies and does not send them again, as
  // LinuxCNC's canon keeps them converted): carry them over to the new unit.
  const double before = length_factor();
  units_ = u;
  const double k = before / length_factor();
  if (k == 1.0) return;
  for (int a = 0; a < kNumAxes; ++a) {
    if (!is_linear(a)) continue;
    g5x_[a] *= k;
    g92_[a] *= k;
    tool_offset_[a] *= k;
  }
}

void TaskCanon::set_g5x_offset(int origin, const Pose& offset) {
  g5x_index_ = origin;
  g5x_ = offset;
}

void TaskCanon::use_tool_length_offset(const Pose& offset) {
  tool_offset_ = offset;
  motion::MotionCommand c;
  c.type = motion::Cmd::SetToolOffset;
  const double f = length_factor();
  for (int a = 0; a < kNumAxes; ++a) c.end[a] = offset[a] * (is_linear(a) ? f : 1.0);
  queue_motion(0, c);
}

Pose TaskCanon::to_machine(const Pose& p) const noexcept {
  const double f = length_factor();
  Pose m;
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear(a) ? f : 1.0;
    m[a] = (p[a] + g92_[a]) * k;
  }
  if (rotation_deg_ != 0) {
    const double r = rotation_deg_ * M_PI / 180, c = std::cos(r), s = std::sin(r);
    const double x = m[0], y = m[1];
    m[0] = x * c - y * s;
    m[1] = x * s + y * c;
  }
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear(a) ? f : 1.0;
    m[a] += (g5x_[a] + tool_offset_[a]) * k;
  }
  return m;
}

Pose TaskCanon::to_program(const Pose& m) const noexcept {
  const double f = length_factor();
  Pose p;
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear(a) ? f : 1.0;
    p[a] = m[a] - (g5x_[a] + tool_offset_[a]) * k;
  }
  if (rotation_deg_ != 0) {
    const double r = -rotation_deg_ * M_PI / 180, c = std::cos(r), s = std::sin(r);
    const double x = p[0], y = p[1];
    p[0] = x * c - y * s;
    p[1] = x * s + y * c;
  }
  for (int a = 0; a < kNumAxes; ++a) {
    const double k = is_linear(a) ? f : 1.0;
    p[a] = p[a] / k - g92_[a];
  }
  return p;
}

double TaskCanon::path_length(const Pose& a, const Pose& b) const noexcept {
  double l = 0;
  for (int i = 0; i < 3; ++i) l += (b[i] - a[i]) * (b[i] - a[i]);
  if (l > 1e-18) return std::sqrt(l);
  for (int i = 3; i < kNumAxes; ++i) l += (b[i] - a[i]) * (b[i] - a[i]);
  return std::sqrt(l);
}

void TaskCanon::set_feed_mode(int spindle, interp::FeedMode mode) {
  feed_mode_ = mode;
  feed_spindle_ = spindle >= 0 && spindle < 8 ? spindle : 0;  // G95 $n: per revolution of spindle n
}

void TaskCanon::set_motion_control_mode(interp::MotionMode mode, double tolerance) {
  term_ = mode == interp::MotionMode::ExactStop   ? tp::TermCond::ExactStop
          : mode == interp::MotionMode::ExactPath ? tp::TermCond::ExactPath
                                                  : tp::TermCond::Blend;
  tolerance_ = tolerance * length_factor();
}

tp::SegmentParams TaskCanon::segment(tp::MotionType type, int line, double length) noexcept {
  tp::SegmentParams s;
  s.type = type;
  s.line = line;
  s.id = next_id_++;
  s.term = term_;
  s.tolerance = tolerance_;
  s.naive_cam_tolerance = naive_tolerance_ * length_factor();
  s.max_velocity = machine_.max_linear_velocity;
  s.max_acceleration = machine_.max_linear_acceleration;
  if (type == tp::MotionType::Traverse) {
    s.feed = machine_.rapid_velocity;
    return s;
  }
  const double f = length_factor();
  switch (feed_mode_) {
    case interp::FeedMode::UnitsPerMinute:
      s.feed = feed_rate_ * f / 60.0;
      break;
    case interp::FeedMode::InverseTime:
      // F is how many times per minute the move could be made.
      s.feed = length * feed_rate_ / 60.0;
      break;
    case interp::FeedMode::UnitsPerRev:
      s.feed = feed_rate_ * f * std::fabs(spindle_rpm_[feed_spindle_]) / 60.0;
      break;
  }
  return s;
}

void TaskCanon::queue_motion(int line, const motion::MotionCommand& c, bool at_rest) {
  Item it;
  it.kind = at_rest ? Item::Kind::MotionAtRest : Item::Kind::Motion;
  it.line = line;
  it.motion = c;
  items_.push_back(std::move(it));
}

void TaskCanon::straight_traverse(int line, const Pose& end) {
  motion::MotionCommand c;
  c.type = motion::Cmd::SetLine;
  c.end = to_machine(end);
  c.segment = segment(tp::MotionType::Traverse, line, path_length(end_, c.end));
  end_ = c.end;
  queue_motion(line, c);
}

void TaskCanon::straight_feed(int line, const Pose& end) {
  motion::MotionCommand c;
  c.type = motion::Cmd::SetLine;
  c.end = to_machine(end);
  c.segment = segment(tp::MotionType::Feed, line, path_length(end_, c.end));
  end_ = c.end;
  queue_motion(line, c);
}

void TaskCanon::arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis,
                         int rotation, double axis_end, const Pose& end) {
  (void)first_end;
  (void)second_end;
  (void)axis_end;
  // Plane: which axes are "first", "second" and the normal (LinuxCNC canon).
  int first = 0, second = 1, normal_axis = 2;
  switch (plane_) {
    case interp::Plane::XY: first = 0; second = 1; normal_axis = 2; break;
    case interp::Plane::YZ: first = 1; second = 2; normal_axis = 0; break;
    case interp::Plane::XZ: first = 2; second = 0; normal_axis = 1; break;
    default:
      error_ = "line " + std::to_string(line) + ": arcs in the UV, VW and UW planes are not supported";
      return;
  }
  Pose center_prog = to_program(end_);
  center_prog[first] = first_axis;
  center_prog[second] = second_axis;
  const Pose center_m = to_machine(center_prog);
  // The normal turns with the XY rotation; clockwise arcs use the opposite normal.
  double n[3] = {0, 0, 0};
  n[normal_axis] = rotation > 0 ? 1.0 : -1.0;
  if (rotation_deg_ != 0) {
    const double r = rotation_deg_ * M_PI / 180, c = std::cos(r), s = std::sin(r);
    const double x = n[0], y = n[1];
    n[0] = x * c - y * s;
    n[1] = x * s + y * c;
  }
  motion::MotionCommand c;
  c.type = motion::Cmd::SetCircle;
  c.end = to_machine(end);
  c.center = {center_m[0], center_m[1], center_m[2]};
  c.normal = {n[0], n[1], n[2]};
  c.turns = std::abs(rotation) - 1;
  // Length for inverse-time feeds: radius x angle (approximately) with the helix.
  const double r0 = std::hypot(end_[first] - center_m[first], end_[second] - center_m[second]);
  const double a0 = std::atan2(end_[second] - center_m[second], end_[first] - center_m[first]);
  const double a1 = std::atan2(c.end[second] - center_m[second], c.end[first] - center_m[first]);
  double sweep = rotation > 0 ? a1 - a0 : a0 - a1;
  while (sweep <= 0) sweep += 2 * M_PI;
  sweep += 2 * M_PI * c.turns;
  const double length = std::hypot(r0 * sweep, c.end[normal_axis] - end_[normal_axis]);
  c.segment = segment(tp::MotionType::Arc, line, length);
  end_ = c.end;
  queue_motion(line, c);
}

void TaskCanon::nurbs_feed(int line, int order, const std::vector<ControlPoint>& pts, const Pose& end) {
  const int n = static_cast<int>(pts.size());
  if (order < 2 || n < order) {
    error_ = "line " + std::to_string(line) + ": a NURBS curve of order " + std::to_string(order) + " needs at least " +
             std::to_string(order) + " control points";
    return;
  }
  // Clamped uniform knots: the curve starts and ends at the end points.
  std::vector<double> knots(static_cast<std::size_t>(n + order));
  for (int i = 0; i < n + order; ++i) {
    knots[static_cast<std::size_t>(i)] =
        i < order ? 0.0 : i >= n ? 1.0 : static_cast<double>(i - order + 1) / static_cast<double>(n - order + 1);
  }
  const auto eval = [&](double u) {
    int span = order - 1;
    while (span < n - 1 && u >= knots[static_cast<std::size_t>(span + 1)]) ++span;
    // de Boor on homogeneous coordinates (x*w, y*w, w).
    std::vector<std::array<double, 3>> d(static_cast<std::size_t>(order));
    for (int j = 0; j < order; ++j) {
      const ControlPoint& c = pts[static_cast<std::size_t>(span - order + 1 + j)];
      d[static_cast<std::size_t>(j)] = {c.x * c.weight, c.y * c.weight, c.weight};
    }
    for (int r = 1; r < order; ++r) {
      for (int j = order - 1; j >= r; --j) {
        const int i = span - order + 1 + j;
        const double denom = knots[static_cast<std::size_t>(i + order - r)] - knots[static_cast<std::size_t>(i)];
        const double a = denom > 0 ? (u - knots[static_cast<std::size_t>(i)]) / denom : 0.0;
        for (int c = 0; c < 3; ++c) {
          d[static_cast<std::size_t>(j)][static_cast<std::size_t>(c)] =
              (1 - a) * d[static_cast<std::size_t>(j - 1)][static_cast<std::size_t>(c)] + a * d[static_cast<std::size_t>(j)][static_cast<std::size_t>(c)];
        }
      }
    }
    const auto& p = d[static_cast<std::size_t>(order - 1)];
    return std::array<double, 2>{p[0] / p[2], p[1] / p[2]};
  };
  const Pose start = to_program(end_);
  const double tol = std::max(tolerance_ > 0 ? tolerance_ / 2 : 0.001, 1e-6) / length_factor();
  // Subdivide until every chord stays within the tolerance of the curve.
  std::vector<std::pair<double, double>> todo{{0.0, 1.0}};
  std::vector<double> accepted;
  while (!todo.empty()) {
    const auto [u0, u1] = todo.back();
    todo.pop_back();
    const auto p0 = eval(u0), p1 = eval(u1), pm = eval((u0 + u1) / 2);
    const double cx = (p0[0] + p1[0]) / 2 - pm[0], cy = (p0[1] + p1[1]) / 2 - pm[1];
    if ((cx * cx + cy * cy > tol * tol || u1 - u0 > 0.25) && u1 - u0 > 1e-4) {
      todo.emplace_back((u0 + u1) / 2, u1);
      todo.emplace_back(u0, (u0 + u1) / 2);
    } else {
      accepted.push_back(u1);
    }
  }
  for (const double u : accepted) {
    Pose p;
    for (int a = 0; a < kNumAxes; ++a) p[a] = start[a] + (end[a] - start[a]) * u;
    const auto xy = eval(std::min(u, 1.0 - 1e-15));
    p[0] = u >= 1.0 ? end[0] : xy[0];
    p[1] = u >= 1.0 ? end[1] : xy[1];
    straight_feed(line, p);
  }
}

void TaskCanon::straight_probe(int line, const Pose& end, interp::ProbeKind kind) {
  motion::MotionCommand c;
  c.type = motion::Cmd::Probe;
  c.end = to_machine(end);
  c.segment = segment(tp::MotionType::Probe, line, path_length(end_, c.end));
  c.value[0] = (kind == interp::ProbeKind::AwayStopOnLoss || kind == interp::ProbeKind::AwayNoError) ? 1 : 0;
  c.value[1] = (kind == interp::ProbeKind::TowardStopOnContact || kind == interp::ProbeKind::AwayStopOnLoss) ? 1 : 0;
  end_ = c.end;  // re-synchronised after the probe
  queue_motion(line, c);
  Item check;
  check.kind = Item::Kind::ProbeCheck;
  check.line = line;
  check.probe_must_touch = c.value[1] != 0;
  items_.push_back(std::move(check));
}

void TaskCanon::rigid_tap(int line, const Pose& end, double) {
  // Spindle-synchronised tapping needs spindle position feedback, which the
  // simulated spindle does not have yet: refuse it clearly.
  error_ = "line " + std::to_string(line) + ": rigid tapping (G33.1) needs spindle-synchronised motion, not available yet";
  (void)end;
}

void TaskCanon::start_speed_feed_synch(int, double, bool) {
  error_ = "spindle-synchronised motion (G33, G76, G95 threading) is not available yet";
}

void TaskCanon::dwell(double seconds) {
  motion::MotionCommand c;
  c.type = motion::Cmd::SetDwell;
  c.value[0] = seconds;
  c.segment.id = next_id_++;
  c.segment.type = tp::MotionType::Dwell;
  queue_motion(0, c);
}

void TaskCanon::spindle_command(int spindle) {
  motion::MotionCommand c;
  c.type = motion::Cmd::SetSpindle;
  c.joint = static_cast<int16_t>(spindle);
  const int dir = spindle_dir_[spindle];
  c.value[0] = dir * std::fabs(spindle_rpm_[spindle]);
  c.value[1] = dir != 0 ? 1 : 0;
  queue_motion(0, c, true);
}

void TaskCanon::set_spindle_speed(int spindle, double rpm) {
  if (spindle < 0 || spindle > 7) return;
  spindle_rpm_[spindle] = rpm;
  if (spindle_dir_[spindle] != 0) spindle_command(spindle);
}

void TaskCanon::set_spindle_mode(int, double css_max) {
  if (css_max > 0) error_ = "constant surface speed (G96) needs a lathe's X position feedback to the spindle: not available yet";
}

void TaskCanon::start_spindle_clockwise(int spindle) {
  if (spindle < 0 || spindle > 7) return;
  spindle_dir_[spindle] = 1;
  spindle_command(spindle);
}

void TaskCanon::start_spindle_counterclockwise(int spindle) {
  if (spindle < 0 || spindle > 7) return;
  spindle_dir_[spindle] = -1;
  spindle_command(spindle);
}

void TaskCanon::stop_spindle_turning(int spindle) {
  if (spindle < 0 || spindle > 7) return;
  spindle_dir_[spindle] = 0;
  spindle_command(spindle);
}

void TaskCanon::orient_spindle(int spindle, double degrees, int mode) {
  motion::MotionCommand c;
  c.type = motion::Cmd::SpindleOrient;
  c.joint = static_cast<int16_t>(spindle);
  c.value[0] = degrees;
  c.value[1] = mode;
  spindle_dir_[spindle] = 0;
  queue_motion(0, c, true);
}

void TaskCanon::wait_spindle_orient_complete(int spindle, double timeout_s) {
  Item it;
  it.kind = Item::Kind::WaitOrient;
  it.i0 = spindle;
  it.d0 = timeout_s;
  items_.push_back(std::move(it));
}

void TaskCanon::simple(Item::Kind kind, int i0) {
  Item it;
  it.kind = kind;
  it.i0 = i0;
  items_.push_back(std::move(it));
}

void TaskCanon::motion_flag(motion::Cmd cmd, double v) {
  motion::MotionCommand c;
  c.type = cmd;
  c.value[0] = v;
  queue_motion(0, c, true);
}

void TaskCanon::output(int index, double value, bool digital, bool with_motion) {
  motion::MotionCommand c;
  c.type = digital ? motion::Cmd::SetDigitalOut : motion::Cmd::SetAnalogOut;
  c.joint = static_cast<int16_t>(index);
  c.value[0] = value;
  c.value[1] = with_motion ? 1 : 0;
  queue_motion(0, c);
}

void TaskCanon::select_tool(int tool_number) {
  Item it;
  it.kind = Item::Kind::ToolPrepare;
  it.i0 = tool_number;
  items_.push_back(std::move(it));
}

void TaskCanon::change_tool(int index) {
  // [EMCIO]TOOL_CHANGE_QUILL_UP / TOOL_CHANGE_POSITION: go there first.
  if (cfg_.tool_change_quill_up || cfg_.has_tool_change_position) {
    Pose target = end_;
    target[2] = cfg_.has_tool_change_position ? std::max(end_[2], cfg_.tool_change_position[2]) : 0;
    if (cfg_.tool_change_quill_up) target[2] = 0;
    motion::MotionCommand up;
    up.type = motion::Cmd::SetLine;
    up.end = target;
    up.segment = segment(tp::MotionType::Traverse, 0, 0);
    up.segment.term = tp::TermCond::ExactStop;
    queue_motion(0, up);
    end_ = target;
    if (cfg_.has_tool_change_position) {
      motion::MotionCommand go = up;
      go.end = cfg_.tool_change_position;
      go.segment.id = next_id_++;
      queue_motion(0, go);
      end_ = go.end;
    }
  }
  Item it;
  it.kind = Item::Kind::ToolChange;
  it.i0 = index;
  items_.push_back(std::move(it));
}

void TaskCanon::change_tool_number(int index) {
  Item it;
  it.kind = Item::Kind::ToolNumber;
  it.i0 = index;
  items_.push_back(std::move(it));
}

void TaskCanon::set_tool_table_entry(int index, const interp::ToolData& tool) {
  Item it;
  it.kind = Item::Kind::ToolSetEntry;
  it.i0 = index;
  it.tool = tool;
  items_.push_back(std::move(it));
}

void TaskCanon::wait_input(int index, bool digital, interp::WaitType type, double timeout_s) {
  Item it;
  it.kind = Item::Kind::WaitInput;
  it.i0 = index;
  it.i1 = digital ? 1 : 0;
  it.i2 = static_cast<int>(type);
  it.d0 = timeout_s;
  items_.push_back(std::move(it));
}

void TaskCanon::message(std::string_view text) {
  Item it;
  it.kind = Item::Kind::Message;
  it.text = std::string(text);
  items_.push_back(std::move(it));
}

void TaskCanon::print(std::string_view text) {
  if (on_print) on_print(text);
}

void TaskCanon::user_m_code(int code, double p, double q) {
  Item it;
  it.kind = Item::Kind::UserMCode;
  it.i0 = code;
  it.d0 = p;
  it.d1 = q;
  items_.push_back(std::move(it));
}

}  // namespace cnc::task
