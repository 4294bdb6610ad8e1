#include "core/interp/text_canon.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>

namespace cnc::interp {

namespace {
// printf("%.4f") for any double, without printf's cost.
void fix4(std::string& s, double v) {
  char b[400];
  const auto r = std::to_chars(b, b + sizeof b, v, std::chars_format::fixed, 4);
  s.append(b, r.ptr);
}
void fix6(std::string& s, double v) {
  char b[400];
  const auto r = std::to_chars(b, b + sizeof b, v, std::chars_format::fixed, 6);
  s.append(b, r.ptr);
}
void integer(std::string& s, long v) {
  char b[24];
  const auto r = std::to_chars(b, b + sizeof b, v);
  s.append(b, r.ptr);
}
void six_axes(std::string& s, const Pose& p) {
  for (int i = 0; i < 6; ++i) {
    if (i) s += ", ";
    fix4(s, p[i]);
  }
}
void nine_grouped(std::string& s, const Pose& p) {
  for (int i = 0; i < 9; ++i) {
    if (i) s += (i % 3 == 0) ? ", " : " ";
    fix4(s, p[i]);
  }
}
}  // namespace

TextCanon::TextCanon(std::FILE* out, cnc::tooltable::ToolTable tools, Units machine_units)
    : file_(out), tools_(std::move(tools)), machine_units_(machine_units) {
  buf_.reserve(1 << 17);
}

TextCanon::~TextCanon() { flush(); }

void TextCanon::flush() {
  if (file_ != nullptr && !buf_.empty()) {
    std::fwrite(buf_.data(), 1, buf_.size(), file_);
    std::fflush(file_);
  }
  buf_.clear();
}

void TextCanon::out(std::string_view call) {
  ++index_;
  if (file_ != nullptr) {
    // "%5ld N%-5d " or "%5ld N..... ", without printf
    char head[40];
    char* h = head;
    char num[24];
    auto r = std::to_chars(num, num + sizeof num, index_);
    const int width = static_cast<int>(r.ptr - num);
    for (int k = width; k < 5; ++k) *h++ = ' ';
    std::memcpy(h, num, static_cast<std::size_t>(width));
    h += width;
    *h++ = ' ';
    *h++ = 'N';
    if (!n_text_.empty()) {
      const int w = static_cast<int>(std::min<std::size_t>(n_text_.size(), 20));
      std::memcpy(h, n_text_.data(), static_cast<std::size_t>(w));
      h += w;
      for (int k = w; k < 5; ++k) *h++ = ' ';
    } else {
      std::memcpy(h, ".....", 5);
      h += 5;
    }
    *h++ = ' ';
    buf_.append(head, static_cast<std::size_t>(h - head));
    buf_.append(call);
    buf_.push_back('\n');
    if (buf_.size() > (1 << 16)) {
      std::fwrite(buf_.data(), 1, buf_.size(), file_);
      buf_.clear();
    }
  }
  emit(call);
}

void TextCanon::begin_block(int, int, std::string_view n_text) { n_text_.assign(n_text); }

void TextCanon::move_to(const Pose& end) { pos_ = end; }

Pose TextCanon::current_position() const { return pos_; }

int TextCanon::tool_in_spindle() const {
  const auto& t = tools_.spindle();
  return t.is_empty() ? 0 : t.number;
}

#define SIMPLE(fn, text) \
  void TextCanon::fn() { out(text); }
SIMPLE(turn_probe_on, "TURN_PROBE_ON()")
SIMPLE(turn_probe_off, "TURN_PROBE_OFF()")
SIMPLE(stop_speed_feed_synch, "STOP_SPEED_FEED_SYNCH()")
SIMPLE(flood_on, "FLOOD_ON()")
SIMPLE(flood_off, "FLOOD_OFF()")
SIMPLE(mist_on, "MIST_ON()")
SIMPLE(mist_off, "MIST_OFF()")
SIMPLE(enable_feed_override, "ENABLE_FEED_OVERRIDE()")
SIMPLE(disable_feed_override, "DISABLE_FEED_OVERRIDE()")
SIMPLE(enable_adaptive_feed, "ENABLE_ADAPTIVE_FEED()")
SIMPLE(disable_adaptive_feed, "DISABLE_ADAPTIVE_FEED()")
SIMPLE(enable_feed_hold, "ENABLE_FEED_HOLD()")
SIMPLE(disable_feed_hold, "DISABLE_FEED_HOLD()")
SIMPLE(start_change, "START_CHANGE()")
SIMPLE(program_stop, "PROGRAM_STOP()")
SIMPLE(optional_program_stop, "OPTIONAL_PROGRAM_STOP()")
SIMPLE(pallet_shuttle, "PALLET_SHUTTLE()")
SIMPLE(program_end, "PROGRAM_END()")
SIMPLE(finish, "FINISH()")
SIMPLE(on_reset, "ON_RESET()")
SIMPLE(log_close, "LOGCLOSE()")
#undef SIMPLE

#define ONE_INT(fn, name)        \
  void TextCanon::fn(int v) {    \
    call_ = name "(";            \
    integer(call_, v);           \
    call_ += ')';                \
    out(call_);                  \
  }
ONE_INT(enable_speed_override, "ENABLE_SPEED_OVERRIDE")
ONE_INT(disable_speed_override, "DISABLE_SPEED_OVERRIDE")
ONE_INT(start_spindle_clockwise, "START_SPINDLE_CLOCKWISE")
ONE_INT(start_spindle_counterclockwise, "START_SPINDLE_COUNTERCLOCKWISE")
ONE_INT(stop_spindle_turning, "STOP_SPINDLE_TURNING")
ONE_INT(set_motion_output_bit, "SET_MOTION_OUTPUT_BIT")
ONE_INT(clear_motion_output_bit, "CLEAR_MOTION_OUTPUT_BIT")
ONE_INT(set_aux_output_bit, "SET_AUX_OUTPUT_BIT")
ONE_INT(clear_aux_output_bit, "CLEAR_AUX_OUTPUT_BIT")
#undef ONE_INT

void TextCanon::use_length_units(Units u) {
  if (u != units_) {
    const double k = (u == Units::Inch ? 1.0 : 25.4) / (units_ == Units::Inch ? 1.0 : 25.4);
    // saicanon divides by 25.4 going to inches (multiplies going to mm):
    // dividing and multiplying by the reciprocal round differently.
    const bool to_inch = u == Units::Inch && units_ == Units::Mm;
    for (int i = 0; i < kNumAxes; ++i) {
      if (i < 3 || i > 5) {
        if (to_inch) {
          pos_[i] /= 25.4;
          g5x_[i] /= 25.4;
          g92_[i] /= 25.4;
          tlo_[i] /= 25.4;
        } else {
          pos_[i] *= k;
          g5x_[i] *= k;
          g92_[i] *= k;
          tlo_[i] *= k;
        }
      }
    }
    units_ = u;
  }
  call_ = "USE_LENGTH_UNITS(";
  call_ += to_string(u);
  call_ += ')';
  out(call_);
}

void TextCanon::select_plane(Plane p) {
  call_ = "SELECT_PLANE(";
  call_ += (p == Plane::XY || p == Plane::YZ || p == Plane::XZ) ? to_string(p) : "CANON_PLANE_UNKNOWN";
  call_ += ')';
  out(call_);
}

void TextCanon::set_g5x_offset(int origin, const Pose& o) {
  // saicanon keeps its position in program coordinates through G5x and G92
  // changes (not through tool length offset changes), adding the old offset
  // first: (p + old) - new, which may leave a tiny residue (-0.0000 printed).
  for (int i = 0; i < kNumAxes; ++i) pos_[i] = pos_[i] + g5x_[i] - o[i];
  g5x_ = o;
  call_ = "SET_G5X_OFFSET(";
  integer(call_, origin);
  call_ += ", ";
  six_axes(call_, o);
  call_ += ')';
  out(call_);
}

void TextCanon::set_g92_offset(const Pose& o) {
  for (int i = 0; i < kNumAxes; ++i) pos_[i] = pos_[i] + g92_[i] - o[i];
  g92_ = o;
  call_ = "SET_G92_OFFSET(";
  six_axes(call_, o);
  call_ += ')';
  out(call_);
}

void TextCanon::set_xy_rotation(double d) {
  call_ = "SET_XY_ROTATION(";
  fix4(call_, d);
  call_ += ')';
  out(call_);
}

void TextCanon::set_feed_reference(FeedReference r) {
  out(r == FeedReference::Xyz ? "SET_FEED_REFERENCE(CANON_XYZ)" : "SET_FEED_REFERENCE(CANON_WORKPIECE)");
}

void TextCanon::use_tool_length_offset(const Pose& o) {
  call_ = "USE_TOOL_LENGTH_OFFSET(";
  nine_grouped(call_, o);
  call_ += ')';
  out(call_);
}

void TextCanon::set_feed_rate(double rate) {
  call_ = "SET_FEED_RATE(";
  fix4(call_, rate);
  call_ += ')';
  out(call_);
}

void TextCanon::set_feed_mode(int spindle, FeedMode mode) {
  call_ = "SET_FEED_MODE(";
  integer(call_, spindle);
  call_ += ", ";
  integer(call_, mode == FeedMode::UnitsPerRev ? 1 : 0);
  call_ += ')';
  out(call_);
}

void TextCanon::set_motion_control_mode(MotionMode mode, double tolerance) {
  if (mode == MotionMode::Continuous) {
    call_ = "SET_MOTION_CONTROL_MODE(CANON_CONTINUOUS, ";
    fix6(call_, tolerance);
    call_ += ')';
    out(call_);
  } else {
    out(mode == MotionMode::ExactPath ? "SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)" : "SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)");
  }
}

void TextCanon::set_naivecam_tolerance(double tolerance) {
  call_ = "SET_NAIVECAM_TOLERANCE(";
  fix4(call_, tolerance);
  call_ += ')';
  out(call_);
}

void TextCanon::straight_traverse(int line, const Pose& end) {
  call_ = "STRAIGHT_TRAVERSE(";
  six_axes(call_, end);
  call_ += ')';
  out(call_);
  segment('T', line, end);
  move_to(end);
}

void TextCanon::straight_feed(int line, const Pose& end) {
  call_ = "STRAIGHT_FEED(";
  six_axes(call_, end);
  call_ += ')';
  out(call_);
  segment('F', line, end);
  move_to(end);
}

void TextCanon::arc_feed(int line, double first_end, double second_end, double first_axis, double second_axis,
                         int rotation, double axis_end, const Pose& end) {
  call_ = "ARC_FEED(";
  fix4(call_, first_end);
  call_ += ", ";
  fix4(call_, second_end);
  call_ += ", ";
  fix4(call_, first_axis);
  call_ += ", ";
  fix4(call_, second_axis);
  call_ += ", ";
  integer(call_, rotation);
  call_ += ", ";
  fix4(call_, axis_end);
  for (int i = 3; i < 6; ++i) {
    call_ += ", ";
    fix4(call_, end[i]);
  }
  call_ += ')';
  out(call_);
  segment('A', line, end);
  move_to(end);
}

void TextCanon::nurbs_feed(int line, int, const std::vector<ControlPoint>& points, const Pose& end) {
  // rs274 prints only the number of control points
  call_ = "NURBS_FEED(";
  integer(call_, static_cast<long>(points.size()));
  call_ += ", ...)";
  out(call_);
  segment('N', line, end);
  move_to(end);
}

void TextCanon::straight_probe(int line, const Pose& end, ProbeKind) {
  call_ = "STRAIGHT_PROBE(";
  six_axes(call_, end);
  call_ += ')';
  out(call_);
  segment('P', line, end);
  // saicanon ends a probe move backed off 0.01 inch from the target.
  probe_ = end;
  // Its arithmetic: XYZ distance, target + backoff * (d / distance).
  Pose stop = end;
  const double dx = pos_[0] - end[0], dy = pos_[1] - end[1], dz = pos_[2] - end[2];
  const double distance = std::sqrt((dx * dx) + (dy * dy) + (dz * dz));
  if (distance != 0) {
    const double backoff = units_ == Units::Mm ? 0.254 : 0.01;
    stop[0] = end[0] + backoff * (dx / distance);
    stop[1] = end[1] + backoff * (dy / distance);
    stop[2] = end[2] + backoff * (dz / distance);
  }
  move_to(stop);
}

void TextCanon::rigid_tap(int line, const Pose& end, double) {
  call_ = "RIGID_TAP(";
  for (int i = 0; i < 3; ++i) {
    if (i) call_ += ", ";
    fix4(call_, end[i]);
  }
  call_ += ')';
  out(call_);
  segment('R', line, end);
}

void TextCanon::start_speed_feed_synch(int spindle, double feed_per_rev, bool velocity_mode) {
  call_ = "START_SPEED_FEED_SYNC(";
  fix6(call_, feed_per_rev);
  call_ += ',';
  integer(call_, velocity_mode ? 1 : 0);
  (void)spindle;
  call_ += ')';
  out(call_);
}

void TextCanon::dwell(double seconds) {
  call_ = "DWELL(";
  fix4(call_, seconds);
  call_ += ')';
  out(call_);
}

void TextCanon::set_spindle_speed(int spindle, double rpm) {
  call_ = "SET_SPINDLE_SPEED(";
  integer(call_, spindle);
  call_ += ", ";
  fix4(call_, rpm);
  call_ += ')';
  out(call_);
}

void TextCanon::set_spindle_mode(int spindle, double css_max_rpm) {
  call_ = "SET_SPINDLE_MODE(";
  integer(call_, spindle);
  call_ += ' ';
  fix4(call_, css_max_rpm);
  call_ += ')';
  out(call_);
}

void TextCanon::wait_spindle_orient_complete(int spindle, double timeout_s) {
  call_ = "SPINDLE.";
  integer(call_, spindle);
  call_ += ".WAIT_ORIENT_COMPLETE(";
  fix4(call_, timeout_s);
  call_ += ')';
  out(call_);
}

void TextCanon::orient_spindle(int spindle, double degrees, int mode) {
  call_ = "ORIENT_SPINDLE(";
  integer(call_, spindle);
  call_ += ", ";
  fix4(call_, degrees);
  call_ += ", ";
  integer(call_, mode);
  call_ += ')';
  out(call_);
}

void TextCanon::select_tool(int tool_number) {
  selected_ = tool_number;
  call_ = "SELECT_TOOL(";
  integer(call_, tool_number);
  call_ += ')';
  out(call_);
}

void TextCanon::change_tool(int index) {
  call_ = "CHANGE_TOOL(";
  integer(call_, index);
  call_ += ')';
  out(call_);
  tools_.change_tool(index);
  slot_ = index;
}

void TextCanon::change_tool_number(int index) {
  call_ = "CHANGE_TOOL_NUMBER(";
  integer(call_, index);
  call_ += ')';
  out(call_);
  if (m61_loads_tool_data_) tools_.set_spindle_tool(index);
  slot_ = index;
}

void TextCanon::set_tool_table_entry(int index, const ToolData& t) {
  call_ = "SET_TOOL_TABLE_ENTRY(";
  integer(call_, index);
  call_ += ", ";
  integer(call_, t.number);
  call_ += ", ";
  for (int i = 0; i < 9; ++i) {
    if (i) call_ += ' ';
    fix4(call_, t.offset[i]);
  }
  call_ += ", ";
  fix4(call_, t.front_angle);
  call_ += ", ";
  fix4(call_, t.back_angle);
  call_ += ", ";
  integer(call_, t.orientation);
  call_ += ')';
  out(call_);
  if (index == 0) {
    tools_.set_slot(0, t);
  } else {
    tools_.update_tool(t);
  }
}

void TextCanon::set_motion_output_value(int index, double value) {
  call_ = "SET_MOTION_OUTPUT_VALUE(";
  integer(call_, index);
  call_ += ',';
  fix6(call_, value);
  call_ += ')';
  out(call_);
}

void TextCanon::set_aux_output_value(int index, double value) {
  call_ = "SET_AUX_OUTPUT_VALUE(";
  integer(call_, index);
  call_ += ',';
  fix6(call_, value);
  call_ += ')';
  out(call_);
}

void TextCanon::wait_input(int, bool, WaitType, double) {
  // saicanon prints nothing for WAIT; the result is input_value().
}

void TextCanon::comment(std::string_view text) {
  call_ = "COMMENT(\"";
  call_ += text;
  call_ += "\")";
  out(call_);
}

void TextCanon::message(std::string_view text) {
  call_ = "MESSAGE(\"";
  call_ += text;
  call_ += "\")";
  out(call_);
}

void TextCanon::canon_error(std::string_view text) {
  // as rs274's saicanon: the text as given, no quotes
  call_ = "CANON_ERROR(";
  call_ += text;
  call_ += ')';
  out(call_);
}

void TextCanon::print(std::string_view text) {
  // rs274 writes (PRINT,...) text on its standard output, unnumbered.
  if (file_ != nullptr) {
    buf_.append(text);
    buf_.push_back('\n');
  }
}

void TextCanon::log_open(std::string_view path, bool append) {
  call_ = append ? "LOGAPPEND(\"" : "LOGOPEN(\"";
  call_ += path;
  call_ += "\")";
  out(call_);
}

void TextCanon::log(std::string_view text) {
  call_ = "LOG(\"";
  call_ += text;
  call_ += "\")";
  out(call_);
}

void TextCanon::user_m_code(int code, double p, double q) {
  call_ = "USER_M_CODE(";
  integer(call_, code);
  call_ += ", ";
  fix4(call_, p);
  call_ += ", ";
  fix4(call_, q);
  call_ += ')';
  out(call_);
}

}  // namespace cnc::interp
