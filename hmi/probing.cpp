#include "hmi/probing.hpp"

#include <algorithm>
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
    case Kind::TipCalibration: return "tip calibration";
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
  // To the midpoint of hits a and b along X (CentreX) or Y (CentreY).
  auto centre = [this](Op o, std::size_t a, std::size_t b, std::string what) {
    Step st;
    st.op = o;
    st.hit_a = a;
    st.hit_b = b;
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
    case Kind::TipCalibration:
      need(r_.gauge_diameter > 0, "tip calibration: the ring gauge's diameter must be above 0");
      [[fallthrough]];
    case Kind::Bore:
      // X across a chord at the start's Y (its midpoint is the centre's X
      // whatever the chord), Y across the diameter from there, then X again
      // across the diameter: hits 0, 1 (X), 2, 3 (Y), 4, 5 (X).
      probe(0, 1, s_.search_distance);
      lines({"G53 G0 X" + n(sx)}, "back to the start");
      probe(0, -1, s_.search_distance);
      centre(Op::CentreX, 0, 1, "to the X centre");
      probe(1, 1, s_.search_distance);
      lines({"G53 G0 Y" + n(sy)}, "back to the start");
      probe(1, -1, s_.search_distance);
      centre(Op::CentreY, 2, 3, "to the Y centre");
      probe(0, 1, s_.search_distance);
      centre(Op::CentreX, 0, 1, "back to the centre");
      probe(0, -1, s_.search_distance);
      centre(Op::CentreX, 4, 5, "to the X centre");
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
      centre(Op::CentreX, 0, 1, "to the X centre");
      lines({"G53 G0 Y" + n(sy - off), down}, "down beside the boss (Y-)");
      probe(1, 1, search);
      lines({up, "G53 G0 Y" + n(sy + off), down}, "down beside the boss (Y+)");
      probe(1, -1, search);
      lines({up}, "up");
      centre(Op::CentreY, 2, 3, "to the Y centre");
      break;
    }
  }
  op(Op::Finish, "result");
  advance();
}

void Routine::advance() {
  advance_steps();
  // The first stage sent saves the modal state and sets what the numbers
  // mean; the result stage restores it.
  if (!done_ && !prologue_sent_ && !stage_.lines.empty()) {
    prologue_sent_ = true;
    std::vector<std::string> l = {"M70", std::string(s_.inch ? "G20" : "G21") + " G90 G94"};
    l.insert(l.end(), stage_.lines.begin(), stage_.lines.end());
    stage_.lines = std::move(l);
  }
}

std::vector<std::string> Routine::cleanup_lines() const {
  const auto& g = start_.gcodes;
  if (g.empty()) return {"G90"};
  const auto has = [&g](int code) { return std::find(g.begin(), g.end(), code) != g.end(); };
  std::string modes = has(200) ? "G20" : "G21";
  modes += has(910) ? " G91" : " G90";
  modes += has(930) ? " G93" : has(950) ? " G95" : " G94";
  modes += has(180) ? " G18" : has(190) ? " G19" : " G17";
  return {modes, "F" + gcode_number(start_.feed)};
}

void Routine::advance_steps() {
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
        const double centre = (hit(st.hit_a) + hit(st.hit_b)) / 2;
        stage_.lines = {std::string("G53 G0 ") + (st.op == Op::CentreX ? "X" : "Y") + gcode_number(centre)};
        return;
      }
      case Op::Finish:
        finish();
        if (!stage_.lines.empty() && error_.empty()) return;
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
    case Kind::TipCalibration: {
      // Hits (probe centres): X+, X- across a chord, Y+, Y-, X+, X- across
      // the diameter. The walls are a radius beyond the hits.
      res.has_x = res.has_y = true;
      res.x = (hit(4) + hit(5)) / 2;
      res.y = (hit(2) + hit(3)) / 2;
      res.diameter_x = hit(4) - hit(5) + 2 * r;
      res.diameter_y = hit(2) - hit(3) + 2 * r;
      if (r_.kind == Kind::Bore) {
        std::snprintf(buf, sizeof buf, "centre at machine X %.4f Y %.4f, diameter X %.4f Y %.4f", res.x, res.y,
                      res.diameter_x, res.diameter_y);
        res.summary = buf;
        break;
      }
      // The gauge's diameter less the probe centre's travel between the
      // walls: the tip as the machine sees it (its ball, its deflection
      // before the switch, the latch's lag, the backlash).
      res.tip_diameter_x = r_.gauge_diameter - (hit(4) - hit(5));
      res.tip_diameter_y = r_.gauge_diameter - (hit(2) - hit(3));
      res.tip_diameter = (res.tip_diameter_x + res.tip_diameter_y) / 2;
      if (res.tip_diameter_x <= 0 || res.tip_diameter_y <= 0) {
        std::snprintf(buf, sizeof buf,
                      "the probe centre travelled X %.4f Y %.4f between the walls, not less than the gauge's %.4f: "
                      "is the gauge diameter right?",
                      hit(4) - hit(5), hit(2) - hit(3), r_.gauge_diameter);
        fail(buf);
        return;
      }
      std::snprintf(buf, sizeof buf, "tip diameter %.4f (X %.4f, Y %.4f) in the %.4f gauge centred at machine X %.4f Y %.4f",
                    res.tip_diameter, res.tip_diameter_x, res.tip_diameter_y, r_.gauge_diameter, res.x, res.y);
      res.summary = buf;
      break;
    }
    case Kind::Boss: {
      // Hits: X+ probe, X- probe, Y+ probe, Y- probe (probe centres),
      // around the boss a radius before its wall.
      res.has_x = res.has_y = true;
      res.x = (hit(0) + hit(1)) / 2;
      res.y = (hit(2) + hit(3)) / 2;
      res.diameter_x = hit(1) - hit(0) - 2 * r;
      res.diameter_y = hit(3) - hit(2) - 2 * r;
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
  out.push_back("M72");  // the modal state of the start (M70 in the first stage)
  out.push_back("M71");  // and no saved context left for a later M72 to restore
  stage_.lines = std::move(out);
  stage_.what = "result";
}

Start start_from(const ipc::Status& st) {
  Start start;
  start.position = st.motion.position;
  start.g92_offset = st.task.g92_offset;
  start.tool_offset = st.task.tool_offset;
  start.rotation_xy = st.task.rotation_xy;
  start.tool_in_spindle = st.io.tool_in_spindle;
  start.gcodes.assign(std::begin(st.task.active_gcodes), std::end(st.task.active_gcodes));
  start.feed = st.task.active_settings[1];
  return start;
}

}  // namespace cnc::hmi::probing
