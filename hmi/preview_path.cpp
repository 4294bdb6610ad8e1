#include "hmi/preview_path.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <system_error>

#include "core/ini/ini_file.hpp"
#include "core/interp/interp.hpp"
#include "core/util/strings.hpp"

namespace cnc::hmi {
namespace {

using interp::Plane;
using interp::Units;

struct Stop {};  // thrown inside the Canon when the point budget is spent

class PreviewCanon final : public interp::Canon {
 public:
  PreviewCanon(PreviewResult& out, tooltable::ToolTable tools, bool machine_inch, double arc_tolerance, std::size_t max_points)
      : out_(out), tools_(std::move(tools)), machine_inch_(machine_inch), tolerance_(arc_tolerance), max_points_(max_points) {}

  void start_at(const Pose& machine) {
    pos_ = machine;
    add(MoveKind::Start, 0, machine);
  }

  // --- representation
  void use_length_units(Units u) override { units_ = u; }
  void select_plane(Plane p) override { plane_ = p; }
  void set_g5x_offset(int, const Pose& o) override { g5x_ = o; }
  void set_g92_offset(const Pose& o) override { g92_ = o; }
  void set_xy_rotation(double d) override { rotation_ = d; }
  void set_feed_reference(interp::FeedReference) override {}
  void use_tool_length_offset(const Pose& o) override { tlo_ = o; }

  // --- motion
  void set_feed_rate(double) override {}
  void set_feed_mode(int, interp::FeedMode) override {}
  void set_motion_control_mode(interp::MotionMode, double) override {}
  void set_naivecam_tolerance(double) override {}
  void straight_traverse(int line, const Pose& end) override { move(MoveKind::Rapid, line, to_machine(end)); }
  void straight_feed(int line, const Pose& end) override { move(MoveKind::Feed, line, to_machine(end)); }
  void arc_feed(int line, double, double, double first_axis, double second_axis, int rotation, double,
                const Pose& end) override;
  void nurbs_feed(int line, int order, const std::vector<ControlPoint>& points, const Pose& end) override;
  void straight_probe(int line, const Pose& end, interp::ProbeKind) override {
    move(MoveKind::Probe, line, to_machine(end));
    probe_ = end;
  }
  void rigid_tap(int line, const Pose& end, double) override {
    const Pose start = pos_;
    move(MoveKind::Feed, line, to_machine(end));
    move(MoveKind::Feed, line, start);
  }
  void start_speed_feed_synch(int, double, bool) override {}
  void stop_speed_feed_synch() override {}
  void dwell(double) override {}

  // --- spindle, coolant, overrides, I/O: nothing to draw
  void set_spindle_speed(int, double) override {}
  void set_spindle_mode(int, double) override {}
  void start_spindle_clockwise(int) override {}
  void start_spindle_counterclockwise(int) override {}
  void stop_spindle_turning(int) override {}
  void orient_spindle(int, double, int) override {}
  void wait_spindle_orient_complete(int, double) override {}
  void flood_on() override {}
  void flood_off() override {}
  void mist_on() override {}
  void mist_off() override {}
  void enable_feed_override() override {}
  void disable_feed_override() override {}
  void enable_speed_override(int) override {}
  void disable_speed_override(int) override {}
  void enable_adaptive_feed() override {}
  void disable_adaptive_feed() override {}
  void enable_feed_hold() override {}
  void disable_feed_hold() override {}
  void set_motion_output_bit(int) override {}
  void clear_motion_output_bit(int) override {}
  void set_aux_output_bit(int) override {}
  void clear_aux_output_bit(int) override {}
  void set_motion_output_value(int, double) override {}
  void set_aux_output_value(int, double) override {}
  void wait_input(int, bool, interp::WaitType, double) override {}

  // --- tools
  void select_tool(int) override {}
  void start_change() override {}
  void change_tool(int index) override { tools_.change_tool(index); }
  void change_tool_number(int index) override { tools_.set_spindle_tool(index); }
  void set_tool_table_entry(int index, const interp::ToolData& tool) override { tools_.set_slot(index, tool); }

  // --- messages and flow
  void comment(std::string_view) override {}
  void message(std::string_view text) override {
    if (out_.messages.size() < 100) out_.messages.emplace_back(text);
  }
  void print(std::string_view) override {}
  void program_stop() override {}
  void optional_program_stop() override {}
  void pallet_shuttle() override {}
  void program_end() override {}
  void user_m_code(int, double, double) override {}

  // --- queries
  Pose current_position() const override { return to_program(pos_); }
  Pose probe_position() const override { return probe_; }
  bool probe_tripped() const override { return true; }
  double input_value() const override { return 0; }
  Units machine_length_units() const override { return machine_inch_ ? Units::Inch : Units::Mm; }
  const tooltable::ToolTable& tool_table() const override { return tools_; }
  int tool_in_spindle() const override {
    const auto& t = tools_.spindle();
    return t.is_empty() ? 0 : t.number;
  }

  void set_spindle_tool_number(int number) {
    if (number <= 0) return;
    if (const auto idx = tools_.find_tool(number)) tools_.set_spindle_tool(*idx);
  }

 private:
  double factor() const noexcept {
    const double mm = units_ == Units::Inch ? 25.4 : units_ == Units::Cm ? 10.0 : 1.0;
    return machine_inch_ ? mm / 25.4 : mm;
  }
  static bool linear(int a) noexcept { return a < 3 || a > 5; }

  Pose to_machine(const Pose& p) const noexcept {
    const double f = factor();
    Pose m;
    for (int a = 0; a < kNumAxes; ++a) m[a] = (p[a] + g92_[a]) * (linear(a) ? f : 1.0);
    if (rotation_ != 0) {
      const double r = rotation_ * M_PI / 180, c = std::cos(r), s = std::sin(r);
      const double x = m[0], y = m[1];
      m[0] = x * c - y * s;
      m[1] = x * s + y * c;
    }
    for (int a = 0; a < kNumAxes; ++a) m[a] += (g5x_[a] + tlo_[a]) * (linear(a) ? f : 1.0);
    return m;
  }
  Pose to_program(const Pose& m) const noexcept {
    const double f = factor();
    Pose p;
    for (int a = 0; a < kNumAxes; ++a) p[a] = m[a] - (g5x_[a] + tlo_[a]) * (linear(a) ? f : 1.0);
    if (rotation_ != 0) {
      const double r = -rotation_ * M_PI / 180, c = std::cos(r), s = std::sin(r);
      const double x = p[0], y = p[1];
      p[0] = x * c - y * s;
      p[1] = x * s + y * c;
    }
    for (int a = 0; a < kNumAxes; ++a) p[a] = p[a] / (linear(a) ? f : 1.0) - g92_[a];
    return p;
  }

  void add(MoveKind kind, int line, const Pose& m) {
    if (out_.points.size() >= max_points_) {
      out_.truncated = true;
      throw Stop{};
    }
    out_.points.push_back(PathPoint{static_cast<float>(m[0]), static_cast<float>(m[1]), static_cast<float>(m[2]), line, kind});
    if (kind == MoveKind::Start) return;
    if (!out_.has_extents) {
      out_.min = out_.max = m;
      out_.has_extents = true;
    }
    for (int a = 0; a < kNumAxes; ++a) {
      out_.min[a] = std::min(out_.min[a], m[a]);
      out_.max[a] = std::max(out_.max[a], m[a]);
    }
  }
  void move(MoveKind kind, int line, const Pose& m) {
    add(kind, line, m);
    pos_ = m;
  }

  PreviewResult& out_;
  tooltable::ToolTable tools_;
  bool machine_inch_;
  double tolerance_;
  std::size_t max_points_;
  Units units_ = Units::Mm;
  Plane plane_ = Plane::XY;
  Pose g5x_, g92_, tlo_, pos_, probe_;
  double rotation_ = 0;
};

void PreviewCanon::arc_feed(int line, double, double, double first_axis, double second_axis, int rotation, double,
                            const Pose& end) {
  int first = 0, second = 1, normal = 2;
  switch (plane_) {
    case Plane::XY: first = 0; second = 1; normal = 2; break;
    case Plane::YZ: first = 1; second = 2; normal = 0; break;
    case Plane::XZ: first = 2; second = 0; normal = 1; break;
    default:  // UV/VW/UW planes: drawn as a straight move
      move(MoveKind::Arc, line, to_machine(end));
      return;
  }
  // Sample in program coordinates, convert each point.
  const Pose start = to_program(pos_);
  const double s1 = start[first] - first_axis, s2 = start[second] - second_axis;
  const double e1 = end[first] - first_axis, e2 = end[second] - second_axis;
  const double r0 = std::hypot(s1, s2), r1 = std::hypot(e1, e2);
  const double a0 = std::atan2(s2, s1), a1 = std::atan2(e2, e1);
  const int turns = std::max(std::abs(rotation), 1) - 1;
  double sweep = rotation > 0 ? a1 - a0 : a0 - a1;
  while (sweep <= 1e-12) sweep += 2 * M_PI;
  sweep += 2 * M_PI * turns;
  if (rotation < 0) sweep = -sweep;
  const double r_machine = std::max(r0, r1) * factor();
  double step = 2 * std::acos(std::clamp(1.0 - tolerance_ / std::max(r_machine, 1e-9), -1.0, 1.0));
  if (!(step > 1e-4)) step = 1e-4;
  const int n = std::clamp(static_cast<int>(std::ceil(std::fabs(sweep) / step)), 2, 20000);
  for (int i = 1; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    Pose p;
    if (i == n) {
      p = end;
    } else {
      const double ang = a0 + sweep * t, r = r0 + (r1 - r0) * t;
      for (int a = 0; a < kNumAxes; ++a) p[a] = start[a] + (end[a] - start[a]) * t;
      p[first] = first_axis + r * std::cos(ang);
      p[second] = second_axis + r * std::sin(ang);
      p[normal] = start[normal] + (end[normal] - start[normal]) * t;
    }
    add(MoveKind::Arc, line, to_machine(p));
  }
  pos_ = to_machine(end);
}

// A clamped uniform B-spline (weights: NURBS) through the control points,
// evaluated with the Cox-de Boor recursion of its basis functions.
void PreviewCanon::nurbs_feed(int line, int order, const std::vector<ControlPoint>& cps, const Pose& end) {
  const int n = static_cast<int>(cps.size());
  if (order < 2 || n < order) {
    move(MoveKind::Feed, line, to_machine(end));
    return;
  }
  const int spans = n - order + 1;
  const auto knot = [&](int i) -> double {
    if (i < order) return 0.0;
    if (i >= n) return 1.0;
    return static_cast<double>(i - order + 1) / spans;
  };
  std::vector<double> basis(static_cast<std::size_t>(n + order));
  const Pose start = to_program(pos_);
  const int samples = std::clamp(16 * spans, 16, 4000);
  for (int s = 1; s <= samples; ++s) {
    const double u = std::min(static_cast<double>(s) / samples, 1.0 - 1e-12);
    // degree 0
    for (int i = 0; i < n + order - 1; ++i) basis[static_cast<std::size_t>(i)] = (knot(i) <= u && u < knot(i + 1)) ? 1.0 : 0.0;
    for (int k = 2; k <= order; ++k) {
      for (int i = 0; i < n + order - k; ++i) {
        double v = 0;
        const double d1 = knot(i + k - 1) - knot(i), d2 = knot(i + k) - knot(i + 1);
        if (d1 > 0) v += (u - knot(i)) / d1 * basis[static_cast<std::size_t>(i)];
        if (d2 > 0) v += (knot(i + k) - u) / d2 * basis[static_cast<std::size_t>(i + 1)];
        basis[static_cast<std::size_t>(i)] = v;
      }
    }
    double x = 0, y = 0, w = 0;
    for (int i = 0; i < n; ++i) {
      const double b = basis[static_cast<std::size_t>(i)] * cps[static_cast<std::size_t>(i)].weight;
      x += b * cps[static_cast<std::size_t>(i)].x;
      y += b * cps[static_cast<std::size_t>(i)].y;
      w += b;
    }
    Pose p;
    const double t = static_cast<double>(s) / samples;
    for (int a = 0; a < kNumAxes; ++a) p[a] = start[a] + (end[a] - start[a]) * t;
    if (s == samples || w <= 0) {
      p = end;
    } else {
      p[0] = x / w;
      p[1] = y / w;
    }
    add(MoveKind::Arc, line, to_machine(p));
  }
  pos_ = to_machine(end);
}

// The interpreter must never write the controller's parameter file: it
// works on a private copy, removed afterwards.
struct ParameterCopy {
  std::filesystem::path path;
  explicit ParameterCopy(const std::filesystem::path& original) {
    if (original.empty()) return;
    path = std::filesystem::temp_directory_path() / ("cnc-hmi-preview-" + std::to_string(::getpid()) + ".var");
    std::error_code ec;
    std::filesystem::copy_file(original, path, std::filesystem::copy_options::overwrite_existing, ec);
    if (ec) std::filesystem::remove(path, ec);
  }
  ~ParameterCopy() {
    std::error_code ec;
    if (!path.empty()) std::filesystem::remove(path, ec);
  }
};

}  // namespace

std::vector<LimitViolation> check_limits(const std::vector<PathPoint>& points, const std::vector<AxisLimit>& limits) {
  std::vector<LimitViolation> out;
  for (const auto& lim : limits) {
    if (lim.axis < 0 || lim.axis > 2) continue;  // the path holds X, Y and Z
    LimitViolation low{lim.axis, false, lim.min, lim.min, 0}, high{lim.axis, true, lim.max, lim.max, 0};
    for (const auto& p : points) {
      if (p.kind == MoveKind::Start) continue;
      const double v = lim.axis == 0 ? p.x : lim.axis == 1 ? p.y : p.z;
      // float storage: a point exactly on the limit must not count
      const double eps = 1e-6 * std::max(1.0, std::fabs(v));
      if (v < lim.min - eps) {
        if (low.first_line == 0) low.first_line = std::max(p.line, 1);
        low.value = std::min(low.value, v);
      }
      if (v > lim.max + eps) {
        if (high.first_line == 0) high.first_line = std::max(p.line, 1);
        high.value = std::max(high.value, v);
      }
    }
    if (low.first_line) out.push_back(low);
    if (high.first_line) out.push_back(high);
  }
  return out;
}

PreviewResult build_preview(const PreviewInput& in, const std::atomic<bool>* cancel) {
  PreviewResult r;
  r.program = in.program;
  try {
    const ini::IniFile ini = in.ini.empty() ? ini::IniFile() : ini::IniFile::load(in.ini);
    interp::Config config = in.ini.empty() ? interp::Config{} : interp::Config::from_ini(ini);
    const ParameterCopy params(config.parameter_file);
    config.parameter_file = params.path;
    config.block_delete = in.block_delete;
    const bool random = config.random_toolchanger;
    tooltable::ToolTable tools(random ? tooltable::ChangerKind::Random : tooltable::ChangerKind::NonRandom);
    if (const auto tt = ini.find("EMCIO", "TOOL_TABLE")) {
      try {
        tools = tooltable::ToolTable::load(ini.resolve_path(trim(*tt)), tools.kind());
      } catch (const std::exception& e) {
        r.messages.emplace_back(std::string("tool table: ") + e.what());
      }
    }
    PreviewCanon canon(r, std::move(tools), config.default_units == Units::Inch, in.arc_tolerance, in.max_points);
    canon.set_spindle_tool_number(in.tool_in_spindle);
    canon.start_at(in.start_machine);
    interp::Interpreter it(canon, config);
    try {
      it.init();
      it.open(in.program);
      for (;;) {
        if (cancel && cancel->load(std::memory_order_relaxed)) {
          r.cancelled = true;
          break;
        }
        if (r.blocks >= in.max_blocks) {
          r.truncated = true;
          break;
        }
        const interp::Status rs = it.read();
        if (rs == interp::Status::SynchRequired) {
          it.synch();
          continue;
        }
        if (rs == interp::Status::Yield) continue;  // a long computation: the cancel flag is seen meanwhile
        if (rs == interp::Status::ProgramEnd || rs == interp::Status::EndOfFile) break;
        ++r.blocks;
        const interp::Status es = it.execute();
        if (es == interp::Status::ProgramEnd) break;
        if (it.is_synch_pending()) it.synch();
      }
    } catch (const interp::InterpError& e) {
      r.error = e.message();
      r.error_line = e.line();
    } catch (const Stop&) {
    }
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  r.violations = check_limits(r.points, in.limits);
  return r;
}

}  // namespace cnc::hmi
