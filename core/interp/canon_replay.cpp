#include "core/interp/canon_replay.hpp"

#include <cctype>
#include <charconv>
#include <fstream>
#include <string_view>
#include <vector>

namespace cnc::interp {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// Skips one blank-separated field; returns the rest.
std::string_view skip_field(std::string_view s) {
  s = trim(s);
  std::size_t i = 0;
  while (i < s.size() && !std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.substr(i);
}

class Replayer {
 public:
  Replayer(const std::string& file, Canon& canon) : file_(file), canon_(canon) {}

  // Returns false after PROGRAM_END.
  bool line(int number, const std::string& text) {
    line_ = number;
    text_ = text;
    std::string_view s = trim(text);
    if (s.empty()) return true;
    // the sequence number and the N word column
    s = trim(skip_field(skip_field(s)));
    const std::size_t open = s.find('(');
    if (open == std::string_view::npos || s.back() != ')') {
      fail("expected two leading fields and then NAME(arguments), as rs274 -g prints a canonical call");
    }
    name_ = std::string(trim(s.substr(0, open)));
    args_ = s.substr(open + 1, s.size() - open - 2);
    canon_.begin_block(line_, -1, {});
    return call();
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw InterpError(what, file_, line_, text_); }

  // Arguments as numbers (separated by commas and/or blanks); `counts` the
  // numbers of arguments the call accepts.
  std::vector<double> numbers(std::initializer_list<std::size_t> counts) const {
    std::vector<double> out;
    std::string_view s = args_;
    for (;;) {
      while (!s.empty() && (s.front() == ',' || std::isspace(static_cast<unsigned char>(s.front())))) s.remove_prefix(1);
      if (s.empty()) break;
      std::size_t n = 0;
      while (n < s.size() && s[n] != ',' && !std::isspace(static_cast<unsigned char>(s[n]))) ++n;
      const std::string_view token = s.substr(0, n);
      double v = 0;
      const char* first = token.data();
      if (!token.empty() && token.front() == '+') ++first;
      const auto [end, ec] = std::from_chars(first, token.data() + token.size(), v);
      if (ec != std::errc() || end != token.data() + token.size()) {
        fail(name_ + ": argument " + std::to_string(out.size() + 1) + " '" + std::string(token) + "' is not a number");
      }
      out.push_back(v);
      s.remove_prefix(n);
    }
    for (std::size_t c : counts) {
      if (out.size() == c) return out;
    }
    std::string expected;
    for (std::size_t c : counts) expected += (expected.empty() ? "" : " or ") + std::to_string(c);
    fail(name_ + ": expected " + expected + " numbers, found " + std::to_string(out.size()));
  }

  int integer(double v, const char* what) const {
    if (v != static_cast<double>(static_cast<int>(v))) fail(name_ + ": " + what + " must be a whole number");
    return static_cast<int>(v);
  }

  // X Y Z A B C [U V W] from `n` starting at `first`.
  static Pose pose(const std::vector<double>& n, std::size_t first) {
    Pose p;
    for (std::size_t i = first; i < n.size() && i - first < static_cast<std::size_t>(kNumAxes); ++i) {
      p[static_cast<int>(i - first)] = n[i];
    }
    return p;
  }

  std::string_view word() const { return trim(args_); }

  std::string text_argument() const {
    std::string_view s = trim(args_);
    if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
    return std::string(s);
  }

  bool call() {
    const std::string& n = name_;
    if (n == "COMMENT") {
      canon_.comment(text_argument());
    } else if (n == "MESSAGE") {
      canon_.message(text_argument());
    } else if (n == "USE_LENGTH_UNITS") {
      const std::string_view w = word();
      if (w == "CANON_UNITS_INCHES") {
        canon_.use_length_units(Units::Inch);
      } else if (w == "CANON_UNITS_MM") {
        canon_.use_length_units(Units::Mm);
      } else if (w == "CANON_UNITS_CM") {
        canon_.use_length_units(Units::Cm);
      } else {
        fail(n + ": expected CANON_UNITS_INCHES, CANON_UNITS_MM or CANON_UNITS_CM");
      }
    } else if (n == "SELECT_PLANE") {
      static constexpr Plane kPlanes[] = {Plane::XY, Plane::YZ, Plane::XZ, Plane::UV, Plane::VW, Plane::UW};
      bool found = false;
      for (Plane p : kPlanes) {
        if (word() == to_string(p)) {
          plane_ = p;
          canon_.select_plane(p);
          found = true;
        }
      }
      if (!found) fail(n + ": expected CANON_PLANE_XY, _YZ, _XZ, _UV, _VW or _UW");
    } else if (n == "SET_FEED_REFERENCE") {
      if (word() == "CANON_XYZ") {
        canon_.set_feed_reference(FeedReference::Xyz);
      } else if (word() == "CANON_WORKPIECE") {
        canon_.set_feed_reference(FeedReference::Workpiece);
      } else {
        fail(n + ": expected CANON_XYZ or CANON_WORKPIECE");
      }
    } else if (n == "SET_MOTION_CONTROL_MODE") {
      motion_control_mode();
    } else if (n == "SET_NAIVECAM_TOLERANCE") {
      canon_.set_naivecam_tolerance(numbers({1})[0]);
    } else if (n == "SET_G5X_OFFSET") {
      const auto v = numbers({7, 10});
      const int origin = integer(v[0], "the coordinate system");
      if (origin < 1 || origin > 9) fail(n + ": the coordinate system must be 1 (G54) to 9 (G59.3)");
      canon_.set_g5x_offset(origin, pose(v, 1));
    } else if (n == "SET_G92_OFFSET") {
      canon_.set_g92_offset(pose(numbers({6, 9}), 0));
    } else if (n == "SET_XY_ROTATION") {
      canon_.set_xy_rotation(numbers({1})[0]);
    } else if (n == "USE_TOOL_LENGTH_OFFSET") {
      canon_.use_tool_length_offset(pose(numbers({6, 9}), 0));
    } else if (n == "SET_FEED_RATE") {
      canon_.set_feed_rate(numbers({1})[0]);
    } else if (n == "SET_FEED_MODE") {
      const auto v = numbers({2});
      const int mode = integer(v[1], "the feed mode");
      if (mode != 0 && mode != 1) fail(n + ": the feed mode must be 0 (per minute) or 1 (per revolution)");
      canon_.set_feed_mode(integer(v[0], "the spindle"), mode == 1 ? FeedMode::UnitsPerRev : FeedMode::UnitsPerMinute);
    } else if (n == "STRAIGHT_TRAVERSE") {
      canon_.straight_traverse(line_, pose(numbers({6, 9}), 0));
    } else if (n == "STRAIGHT_FEED") {
      canon_.straight_feed(line_, pose(numbers({6, 9}), 0));
    } else if (n == "ARC_FEED") {
      arc_feed();
    } else if (n == "DWELL") {
      canon_.dwell(numbers({1})[0]);
    } else if (n == "SET_SPINDLE_SPEED") {
      const auto v = numbers({2});
      canon_.set_spindle_speed(integer(v[0], "the spindle"), v[1]);
    } else if (n == "SET_SPINDLE_MODE") {
      const auto v = numbers({2});
      canon_.set_spindle_mode(integer(v[0], "the spindle"), v[1]);
    } else if (n == "START_SPINDLE_CLOCKWISE") {
      canon_.start_spindle_clockwise(integer(numbers({1})[0], "the spindle"));
    } else if (n == "START_SPINDLE_COUNTERCLOCKWISE") {
      canon_.start_spindle_counterclockwise(integer(numbers({1})[0], "the spindle"));
    } else if (n == "STOP_SPINDLE_TURNING") {
      canon_.stop_spindle_turning(integer(numbers({1})[0], "the spindle"));
    } else if (n == "SELECT_TOOL") {
      canon_.select_tool(integer(numbers({1})[0], "the tool number"));
    } else if (n == "CHANGE_TOOL") {
      canon_.change_tool(integer(numbers({1})[0], "the tool index"));
    } else if (no_arguments()) {
      // handled
    } else if (n == "PROGRAM_END") {
      numbers({0});
      canon_.program_end();
      return false;
    } else {
      fail("unknown canonical call '" + n + "' (docs/interpreter.md, \"Canon replay\", lists the calls replayed)");
    }
    return true;
  }

  // Calls without arguments; true when `name_` is one.
  bool no_arguments() {
    struct Simple {
      const char* name;
      void (Canon::*call)();
    };
    static constexpr Simple kSimple[] = {
        {"MIST_ON", &Canon::mist_on},
        {"MIST_OFF", &Canon::mist_off},
        {"FLOOD_ON", &Canon::flood_on},
        {"FLOOD_OFF", &Canon::flood_off},
        {"ENABLE_FEED_OVERRIDE", &Canon::enable_feed_override},
        {"DISABLE_FEED_OVERRIDE", &Canon::disable_feed_override},
        {"PROGRAM_STOP", &Canon::program_stop},
        {"OPTIONAL_PROGRAM_STOP", &Canon::optional_program_stop},
        {"ON_RESET", &Canon::on_reset},
    };
    for (const Simple& s : kSimple) {
      if (name_ == s.name) {
        numbers({0});
        (canon_.*s.call)();
        return true;
      }
    }
    return false;
  }

  void motion_control_mode() {
    std::string_view s = trim(args_);
    const std::size_t comma = s.find(',');
    const std::string_view mode = trim(s.substr(0, comma));
    if (mode == "CANON_EXACT_STOP" && comma == std::string_view::npos) {
      canon_.set_motion_control_mode(MotionMode::ExactStop, 0.0);
    } else if (mode == "CANON_EXACT_PATH" && comma == std::string_view::npos) {
      canon_.set_motion_control_mode(MotionMode::ExactPath, 0.0);
    } else if (mode == "CANON_CONTINUOUS" && comma != std::string_view::npos) {
      args_ = s.substr(comma + 1);
      canon_.set_motion_control_mode(MotionMode::Continuous, numbers({1})[0]);
    } else {
      fail(name_ + ": expected CANON_EXACT_STOP, CANON_EXACT_PATH or CANON_CONTINUOUS, tolerance");
    }
  }

  // ARC_FEED(first_end, second_end, first_axis, second_axis, rotation,
  // axis_end, A B C [U V W]) in the selected plane.
  void arc_feed() {
    const auto v = numbers({9, 12});
    Pose end;
    for (std::size_t i = 6; i < v.size(); ++i) end[static_cast<int>(i) - 3] = v[i];  // A B C [U V W]
    int first = 0, second = 1, normal = 2;
    switch (plane_) {
      case Plane::XY: first = 0; second = 1; normal = 2; break;
      case Plane::YZ: first = 1; second = 2; normal = 0; break;
      case Plane::XZ: first = 2; second = 0; normal = 1; break;
      case Plane::UV: first = 6; second = 7; normal = 8; break;
      case Plane::VW: first = 7; second = 8; normal = 6; break;
      case Plane::UW: first = 8; second = 6; normal = 7; break;
    }
    // X Y Z not among the plane's axes keep the current position
    const Pose here = canon_.current_position();
    for (int i = 0; i < 3; ++i) end[i] = here[i];
    end[first] = v[0];
    end[second] = v[1];
    end[normal] = v[5];
    canon_.arc_feed(line_, v[0], v[1], v[2], v[3], integer(v[4], "the rotation"), v[5], end);
  }

  const std::string& file_;
  Canon& canon_;
  int line_ = 0;
  std::string text_;
  std::string name_;
  std::string_view args_;
  Plane plane_ = Plane::XY;
};

}  // namespace

void replay_canon(std::istream& in, const std::string& file, Canon& canon) {
  Replayer r(file, canon);
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (!r.line(number, text)) return;
  }
}

void replay_canon_file(const std::filesystem::path& path, Canon& canon) {
  std::ifstream in(path);
  if (!in) throw InterpError("cannot open the canon file: " + path.string(), path.string(), 0, {});
  replay_canon(in, path.string(), canon);
}

}  // namespace cnc::interp
