// The screen's scope page without widgets: the halcmd lines that drive the
// controller's HAL scope (core/hal/scope.*, docs/hal.md "Scope and
// watch": `scope setup`, `arm`, `state`, `csv`, `stop`; the same capture
// `cnc-scope` uses, no second implementation) and the reading of its
// answers: the state line and the CSV of a finished capture.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace cnc::hmi::scope {

enum class Edge { Rising, Falling, Level, None };
enum class Mode { Single, Normal, Auto };
const char* to_string(Edge e);
const char* to_string(Mode m);

struct Settings {
  std::vector<std::string> pins;  // channels, 1..16 with the trigger
  std::string trigger;            // empty: no trigger (a capture starts at once)
  Edge edge = Edge::Rising;
  double level = 0.5;
  int pre_percent = 10;
  int samples = 0;  // 0: the buffer's size
  Mode mode = Mode::Single;
};

// "a, b ,c" -> {"a","b","c"} (commas or blanks separate).
std::vector<std::string> split_pins(std::string_view text);

// "scope setup PINS [trigger=.. edge=.. level=..] pre=.. [samples=..] mode=..".
// Throws std::invalid_argument naming the field: no pins, more than 16
// (with the trigger), a name with a character halcmd would split on, pre
// outside 0..100, samples 1.
std::string setup_line(const Settings& s);

// The answer to "scope state": "waiting samples=2000 pre=200 channels=2 forced".
struct State {
  std::string name;  // idle, filling, waiting, triggered, done
  int samples = 0, pre = 0, channels = 0;
  bool forced = false;  // auto mode: no trigger came, the capture was forced
  bool done() const { return name == "done"; }
};
// Throws std::invalid_argument for text that is not a state line.
State parse_state(std::string_view text);

// A finished capture: time relative to the trigger (s), one column per pin.
struct Capture {
  std::vector<std::string> names;
  std::vector<double> time;
  std::vector<std::vector<double>> columns;  // [channel][row]
  std::string csv;                           // as the controller sent it (exported as is)
};
// Parses "time_s,PIN,...\n" rows; throws std::invalid_argument naming the
// line of a row that cannot be read.
Capture parse_csv(std::string text);

}  // namespace cnc::hmi::scope
