#include "hmi/probing.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "core/ini/ini_file.hpp"

namespace cnc::hmi::probing {

namespace {

char letter(int axis) { return kAxisLetters[axis]; }

}  // namespace

const char* to_string(Kind k) {
  switch (k) {
    case Kind::ToolLength: return "tool length";
    case Kind::Edge: return "edge";
    case Kind::InsideCorner: return "inside corner";
    case Kind::OutsideCorner: return "outside corner";
    case Kind::Bore: return "bore centre";
    case Kind::Boss: return "boss centre";
  }
  return "?";
}

std::string gcode_number(double v) {
  if (std::fabs(v) < 0.00005) v = 0;  // no "-0.0000"
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

std::string coordinate_system_name(int index) {
  static const char* names[] = {"G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"};
  if (index < 1 || index > 9) return "?";
  return names[index - 1];
}

std::string touch_off_line(int coordinate_system, int axis, double value) {
  if (coordinate_system < 1 || coordinate_system > 9) {
    throw std::invalid_argument("coordinate system " + std::to_string(coordinate_system) + " is not 1..9 (G54..G59.3)");
  }
  if (axis < 0 || axis >= kNumAxes) throw std::invalid_argument("axis " + std::to_string(axis) + " is not 0..8");
  return "G10 L20 P" + std::to_string(coordinate_system) + " " + letter(axis) + gcode_number(value);
}

Settings Settings::from_ini(const ini::IniFile& ini) {
  Settings s;
  const ini::Range positive{1e-9, 1e9};
  s.tip_diameter = ini.get_double("PROBE", "TIP_DIAMETER", s.tip_diameter, {0, 1e9});
  s.search_distance = ini.get_double("PROBE", "SEARCH_DISTANCE", s.search_distance, positive);
  s.latch_distance = ini.get_double("PROBE", "LATCH_DISTANCE", s.latch_distance, positive);
  s.search_feed = ini.get_double("PROBE", "SEARCH_FEED", s.search_feed, positive);
  s.latch_feed = ini.get_double("PROBE", "LATCH_FEED", s.latch_feed, positive);
  s.clearance = ini.get_double("PROBE", "CLEARANCE", s.clearance, {0, 1e9});
  if (s.latch_distance >= s.search_distance) {
    ini.fail(ini.find_entry("PROBE", "LATCH_DISTANCE") ? ini.find_entry("PROBE", "LATCH_DISTANCE")
                                                        : ini.find_entry("PROBE", "SEARCH_DISTANCE"),
             "[PROBE]LATCH_DISTANCE (" + gcode_number(s.latch_distance) + ") must be below [PROBE]SEARCH_DISTANCE (" +
                 gcode_number(s.search_distance) + ")");
  }
  const ini::Entry* sx = ini.find_entry("PROBE", "SETTER_X");
  const ini::Entry* sy = ini.find_entry("PROBE", "SETTER_Y");
  const ini::Entry* sz = ini.find_entry("PROBE", "SETTER_Z");
  const ini::Entry* sref = ini.find_entry("PROBE", "SETTER_REFERENCE_Z");
  if (sx || sy || sz || sref) {
    for (const char* key : {"SETTER_X", "SETTER_Y", "SETTER_Z", "SETTER_REFERENCE_Z"}) {
      if (!ini.find_entry("PROBE", key)) {
        ini.fail(sx ? sx : sy ? sy : sz ? sz : sref,
                 std::string("[PROBE]") + key + " missing: a tool setter needs SETTER_X, SETTER_Y, SETTER_Z and SETTER_REFERENCE_Z");
      }
    }
    s.setter = true;
    s.setter_x = ini.get_double("PROBE", "SETTER_X", 0);
    s.setter_y = ini.get_double("PROBE", "SETTER_Y", 0);
    s.setter_z = ini.get_double("PROBE", "SETTER_Z", 0);
    s.setter_reference_z = ini.get_double("PROBE", "SETTER_REFERENCE_Z", 0);
    s.setter_safe_z = ini.get_double("PROBE", "SETTER_SAFE_Z", 0);
    s.setter_search_distance = ini.get_double("PROBE", "SETTER_SEARCH_DISTANCE", s.search_distance, positive);
    if (s.setter_safe_z < s.setter_z) {
      ini.fail(ini.find_entry("PROBE", "SETTER_SAFE_Z") ? ini.find_entry("PROBE", "SETTER_SAFE_Z") : sz,
               "[PROBE]SETTER_SAFE_Z (" + gcode_number(s.setter_safe_z) + ") is below [PROBE]SETTER_Z (" +
                   gcode_number(s.setter_z) + ")");
    }
    if (s.setter_reference_z >= s.setter_z) {
      ini.fail(sref, "[PROBE]SETTER_REFERENCE_Z (" + gcode_number(s.setter_reference_z) +
                         ") must be below SETTER_Z (" + gcode_number(s.setter_z) + "), where the search starts");
    }
  } else {
    s.setter_search_distance = s.search_distance;
  }
  return s;
}

std::vector<std::string> Routine::probe_lines(const Settings& s, int axis, int direction, double search) {
  const std::string a(1, letter(axis));
  const double d = direction;
  return {
      "G91 G38.2 " + a + gcode_number(d * search) + " F" + gcode_number(s.search_feed),
      "G0 " + a + gcode_number(-d * s.latch_distance),
      "G38.2 " + a + gcode_number(d * 2 * s.latch_distance) + " F" + gcode_number(s.latch_feed),
      "G0 " + a + gcode_number(-d * s.latch_distance),
      "G90",
  };
}

Routine::Routine(const Settings& settings, const Request& request, const Start& start)
    : s_(settings), r_(request), start_(start) {
  const auto need = [](bool ok, const std::string& why) {
    if (!ok) throw std::invalid_argument(why);
  };
  const auto unit = [](int d) { return d == 1 || d == -1; };
  need(r_.coordinate_system >= 0 && r_.coordinate_system <= 9, "coordinate system must be G54..G59.3");
  need(r_.coordinate_system == 0 || r_.kind == Kind::ToolLength || std::fabs(start_.rotation_xy) < 1e-9,
       "an XY rotation is in force: the probed edges are machine X/Y, not the rotated axes; remove the rotation first");
  const double sx = start_.position[0], sy = start_.position[1], sz = start_.position[2];
  auto lines = [this](std::vector<std::string> l, std::string what) {
    Step st;
    st.op = Op::Lines;
    st.lines = std::move(l);
    st.what = std::move(what);
    steps_.push_back(std::move(st));
  };
  auto probe = [this](int axis, int dir, double search) {
    Step st;
    st.op = Op::Probe;
    st.axis = axis;
    st.direction = dir;
    st.search = search;
    st.what = std::string("probe ") + letter(axis) + (dir > 0 ? "+" : "-");
    steps_.push_back(std::move(st));
  };
  auto op = [this](Op o, std::string what) {
    Step st;
    st.op = o;
    st.what = std::move(what);
    steps_.push_back(std::move(st));
  };
  const auto n = gcode_number;
  switch (r_.kind) {
    case Kind::ToolLength:
      need(s_.setter, "no tool setter configured ([PROBE]SETTER_X, SETTER_Y, SETTER_Z, SETTER_REFERENCE_Z)");
      need(r_.tool > 0, "tool length: no tool number (the tool in the spindle is T0)");
      lines({"G53 G0 Z" + n(s_.setter_safe_z), "G53 G0 X" + n(s_.setter_x) + " Y" + n(s_.setter_y),
             "G53 G0 Z" + n(s_.setter_z)},
            "to the tool setter");
      probe(2, -1, s_.setter_search_distance);
      break;
    case Kind::Edge:
      need(r_.axis == 0 || r_.axis == 1, "edge: axis must be X or Y");
      need(unit(r_.direction), "edge: direction must be + or -");
      probe(r_.axis, r_.direction, s_.search_distance);
      break;
    case Kind::InsideCorner:
      need(unit(r_.corner_x) && unit(r_.corner_y), "corner: directions must be + or -");
      probe(0, r_.corner_x, s_.search_distance);
      lines({"G53 G0 X" + n(sx)}, "back to the start");
      probe(1, r_.corner_y, s_.search_distance);
      lines({"G53 G0 Y" + n(sy)}, "back to the start");
      break;
    case Kind::OutsideCorner:
      need(unit(r_.corner_x) && unit(r_.corner_y), "corner: directions must be + or -");
      need(r_.corner_step > 0, "outside corner: the step along the faces must be above 0");
      lines({"G53 G0 Y" + n(sy + r_.corner_y * r_.corner_step)}, "along the X face");
      probe(0, r_.corner_x, s_.search_distance);
      lines({"G53 G0 Y" + n(sy), "G53 G0 X" + n(sx)}, "back to the start");
      lines({"G53 G0 X" + n(sx + r_.corner_x * r_.corner_step)}, "along the Y face");
      probe(1, r_.corner_y, s_.search_distance);
      lines({"G53 G0 X" + n(sx), "G53 G0 Y" + n(sy)}, "back to the start");
      break;
    case Kind::Bore:
      probe(0, 1, s_.search_distance);
      lines({"G53 G0 X" + n(sx)}, "back to the start");
      probe(0, -1, s_.search_distance);
      op(Op::CentreX, "to the X centre");
      probe(1, 1, s_.search_distance);
      lines({"G53 G0 Y" + n(sy)}, "back to the start");
      probe(1, -1, s_.search_distance);
      op(Op::CentreY, "to the Y centre");
      break;
    case Kind::Boss: {
      need(r_.boss_diameter > 0, "boss: the approximate diameter must be above 0");
      need(r_.boss_depth > 0, "boss: the probing depth must be above 0");
      const double off = r_.boss_diameter / 2 + s_.tip_radius() + s_.clearance;
      // Far enough to reach a boss up to SEARCH_DISTANCE smaller than
      // given, never past the centre.
      const double search = std::min(off, s_.clearance + s_.search_distance);
      const std::string down = "G53 G1 Z" + n(sz - r_.boss_depth) + " F" + n(s_.search_feed);
      const std::string up = "G53 G0 Z" + n(sz);
      lines({"G53 G0 X" + n(sx - off), down}, "down beside the boss (X-)");
      probe(0, 1, search);
      lines({up, "G53 G0 X" + n(sx + off), down}, "down beside the boss (X+)");
      probe(0, -1, search);
      lines({up}, "up");
      op(Op::CentreX, "to the X centre");
      lines({"G53 G0 Y" + n(sy - off), down}, "down beside the boss (Y-)");
      probe(1, 1, search);
      lines({up, "G53 G0 Y" + n(sy + off), down}, "down beside the boss (Y+)");
      probe(1, -1, search);
      lines({up}, "up");
      op(Op::CentreY, "to the Y centre");
      break;
    }
  }
  op(Op::Finish, "result");
  advance();
}

void Routine::advance() {
  while (next_ < steps_.size()) {
    Step& st = steps_[next_++];
    stage_ = Stage{};
    stage_.what = st.what;
    switch (st.op) {
      case Op::Lines:
        stage_.lines = st.lines;
        return;
      case Op::Probe:
        stage_.lines = probe_lines(s_, st.axis, st.direction, st.search);
        stage_.probe_axis = st.axis;
        return;
      case Op::CentreX:
      case Op::CentreY: {
        const std::size_t n = result_.hits.size();
        const double centre = (hit(n - 2) + hit(n - 1)) / 2;
        stage_.lines = {std::string("G53 G0 ") + (st.op == Op::CentreX ? "X" : "Y") + gcode_number(centre)};
        return;
      }
      case Op::Finish:
        finish();
        if (!stage_.lines.empty()) return;
        break;
    }
  }
  done_ = true;
}

void Routine::completed(bool tripped, const Pose& probed) {
  if (done_) return;
  if (stage_.probe_axis >= 0) {
    if (!tripped) {
      fail(stage_.what + ": no contact within the search distance");
      return;
    }
    result_.hits.push_back(probed[stage_.probe_axis]);
  }
  advance();
}

void Routine::fail(const std::string& why) {
  error_ = std::string(to_string(r_.kind)) + ": " + why;
  done_ = true;
}

void Routine::finish() {
  const double r = s_.tip_radius();
  Result& res = result_;
  std::vector<std::string> out;
  char buf[256];
  // The origin in coordinate system P for "this machine position reads
  // `value`": displayed = machine - origin - G92 - tool offset.
  const auto origin_line = [&](int axis, double machine, double value) {
    const double origin = machine - value - start_.g92_offset[axis] - start_.tool_offset[axis];
    return std::string(" ") + letter(axis) + gcode_number(origin);
  };
  switch (r_.kind) {
    case Kind::ToolLength:
      res.has_z = true;
      res.z = hit(0);
      res.tool_length = hit(0) - s_.setter_reference_z;
      out = {"G53 G0 Z" + gcode_number(s_.setter_safe_z),
             "G10 L1 P" + std::to_string(r_.tool) + " Z" + gcode_number(res.tool_length)};
      if (r_.tool == start_.tool_in_spindle) out.push_back("G43 H" + std::to_string(r_.tool));
      std::snprintf(buf, sizeof buf, "T%d length %.4f (setter contact at machine Z %.4f)", r_.tool, res.tool_length,
                    res.z);
      res.summary = buf;
      break;
    case Kind::Edge: {
      const double e = hit(0) + r_.direction * r;
      (r_.axis == 0 ? res.has_x : res.has_y) = true;
      (r_.axis == 0 ? res.x : res.y) = e;
      std::snprintf(buf, sizeof buf, "%c edge at machine %.4f", letter(r_.axis), e);
      res.summary = buf;
      break;
    }
    case Kind::InsideCorner:
    case Kind::OutsideCorner:
      res.has_x = res.has_y = true;
      res.x = hit(0) + r_.corner_x * r;
      res.y = hit(1) + r_.corner_y * r;
      std::snprintf(buf, sizeof buf, "corner at machine X %.4f Y %.4f", res.x, res.y);
      res.summary = buf;
      break;
    case Kind::Bore:
    case Kind::Boss: {
      // Hits: X+ probe, X- probe, Y+ probe, Y- probe (probe centres). In a
      // bore the walls are a radius beyond the hits, around a boss a radius
      // before them.
      const double sign = r_.kind == Kind::Bore ? 1 : -1;
      res.has_x = res.has_y = true;
      res.x = (hit(0) + hit(1)) / 2;
      res.y = (hit(2) + hit(3)) / 2;
      res.diameter_x = sign * (hit(0) - hit(1)) + 2 * r * (r_.kind == Kind::Bore ? 1 : -1);
      res.diameter_y = sign * (hit(2) - hit(3)) + 2 * r * (r_.kind == Kind::Bore ? 1 : -1);
      std::snprintf(buf, sizeof buf, "centre at machine X %.4f Y %.4f, diameter X %.4f Y %.4f", res.x, res.y,
                    res.diameter_x, res.diameter_y);
      res.summary = buf;
      break;
    }
  }
  if (r_.coordinate_system > 0 && r_.kind != Kind::ToolLength) {
    std::string line = "G10 L2 P" + std::to_string(r_.coordinate_system);
    if (res.has_x) line += origin_line(0, res.x, r_.value_x);
    if (res.has_y) line += origin_line(1, res.y, r_.value_y);
    out.push_back(line);
    res.summary += "; " + coordinate_system_name(r_.coordinate_system) + " set so that it reads";
    if (res.has_x) res.summary += " X" + gcode_number(r_.value_x);
    if (res.has_y) res.summary += " Y" + gcode_number(r_.value_y);
  }
  stage_.lines = std::move(out);
  stage_.what = "result";
}

}  // namespace cnc::hmi::probing
