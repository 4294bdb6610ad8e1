// Internal state of the interpreter (not a public header): the parsed block,
// the modal settings, parameters, call frames and the streamed sources.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/interp/interp.hpp"
#include "core/interp/line_reader.hpp"
#include "core/tooltable/tool_table.hpp"

namespace cnc::interp {

inline constexpr int kMaxParameters = 5602;
// Motion mode values besides G codes x10: -1 is G80; after G5.3 there is none.
inline constexpr int kMotionNone = -2;
inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kTiny = 1e-12;
inline constexpr double kMmPerInch = 25.4;
// Axis word letters in axis order (X Y Z A B C U V W).
inline constexpr char kLetters[] = "xyzabcuvw";

// Rounds to the nearest int, saturating (never undefined for huge values).
inline int round_to_int(double v) {
  if (!(v > -2147483647.0)) return -2147483647;
  if (!(v < 2147483647.0)) return 2147483647;
  return static_cast<int>(v < 0 ? v - 0.5 : v + 0.5);
}

enum class OType : uint8_t {
  None, Sub, EndSub, Call, Return, If, ElseIf, Else, EndIf, Do, While, EndWhile, Repeat, EndRepeat, Break, Continue,
  FanucSub  // a bare O-word line: a Fanuc-style subprogram (called with M98, ended by M99) or a program title
};

// Modal groups, indexed as LinuxCNC does.
enum GGroup : int {
  kGNonModal = 0, kGMotion = 1, kGPlane = 2, kGDistance = 3, kGIjk = 4, kGFeedMode = 5, kGUnits = 6,
  kGCutter = 7, kGToolOffset = 8, kGRetract = 10, kGCoordSys = 12, kGControl = 13, kGSpindleMode = 14,
  kGLathe = 15, kGNumGroups = 16
};
enum MGroup : int {
  kMStop = 4, kMIo = 5, kMToolChange = 6, kMSpindle = 7, kMCoolant = 8, kMOverride = 9, kMUser = 10,
  kMState = 3, kMNumGroups = 11
};

struct Assignment {
  int index = -1;    // numbered parameter, or -1 for named
  std::string name;  // named parameter (lower case)
  double value = 0;
};

struct Block {
  int line = 0;
  int n_number = -1;
  std::string n_text;  // the N word's digits as written
  uint32_t has = 0;  // bit (letter - 'a') set when the word is present
  std::array<double, 26> v{};
  std::array<int, kGNumGroups> g{};  // code x10 or -1
  std::array<int, kMNumGroups> m{};  // code or -1
  int m_count = 0;
  int dollar = -1;  // $ spindle number (-1 with has_dollar: all spindles)
  bool has_dollar = false;
  bool has_polar_r = false, has_polar_a = false;  // @ radius, ^ angle
  double polar_r = 0, polar_a = 0;
  bool has_comment = false;
  std::string comment;
  // A `;py,` comment: the script statement after "py," (raw text).
  bool has_py = false;
  std::string py_code;
  OType o_type = OType::None;
  std::string o_name;
  bool o_has_value = false;
  double o_value = 0;
  std::vector<double> call_args;
  std::vector<Assignment> assigns;
  int motion = -1;  // motion G code x10 used by this block (-1 none)

  void clear();
  bool has_word(char c) const noexcept { return (has >> (c - 'a')) & 1u; }
  double get(char c) const noexcept { return v[static_cast<std::size_t>(c - 'a')]; }
  void set(char c, double x) noexcept {
    has |= 1u << (c - 'a');
    v[static_cast<std::size_t>(c - 'a')] = x;
  }
  void unset(char c) noexcept { has &= ~(1u << (c - 'a')); }
  bool any_axis(unsigned mask) const noexcept;
};

enum class LoopKind : uint8_t { While, Do, Repeat };

struct Loop {
  std::string label;
  LoopKind kind;
  int64_t offset;  // start of the loop's opening line
  int line;        // its line number
  int64_t body_offset;  // first line of the body
  int body_line;
  int remaining = 0;  // repeat
  int source = 0;     // SourceFile::id the loop lives in
};

struct SubDef {
  std::string file;
  int64_t offset = 0;  // first body line
  int line = 0;
  bool fanuc = false;  // O<n> ... M99 (M98) rather than O<n> sub ... endsub (call)
  std::string text;    // the defining line, for errors
};

// Modal state saved by M70/M73 (and restored by M72 / at return).
struct ModalSnapshot {
  bool valid = false;
  Units units = Units::Mm;
  Plane plane = Plane::XY;
  bool absolute = true;
  bool ijk_absolute = false;
  FeedMode feed_mode = FeedMode::UnitsPerMinute;
  double feed = 0;
  double speed = 0;
  Direction spindle = Direction::Stopped;
  bool mist = false, flood = false;
  MotionMode control = MotionMode::ExactPath;
  double tolerance = 0, naive_tolerance = 0;
  int origin = 1;
  bool retract_old_z = true;
  bool feed_override = true, speed_override = true;
};

// A remapped code being carried out: the block it came from (finished
// after the procedures return, from resume_step on), its arguments, and
// which procedure runs (prolog, body, epilog).
struct RemapCall {
  const RemapSpec* spec = nullptr;
  Block block;
  int resume_step = 0;
  int line = 0;
  std::string file, text;
  int stage = 1;  // 0 prolog, 1 body, 2 epilog
  std::vector<double> positional;                        // argspec with @
  std::vector<std::pair<std::string, double>> named;     // #<p>, #<q>, ...
  std::vector<std::pair<std::string, double>> words;     // the argspec words present (Python's **words)
  bool epilog_done = false;  // a Python epilog ran before the body's frame was left
  int seq = 0;               // start order (the remap stack of self.blocks[n])
};

struct Frame {
  std::string sub_name;
  std::unordered_map<std::string, double> locals;
  std::array<double, 30> saved_args{};
  int file_depth = 0;  // files_.size() of the caller
  int64_t return_offset = 0;
  int return_line = 0;
  std::vector<Loop> loops;
  std::unordered_map<std::string, bool> if_done;  // label -> a branch ran
  ModalSnapshot saved_modal;  // M70/M73 at this call level
  bool restore_on_return = false;  // M73: restored when the subroutine returns
  bool is_user_m = false;
  std::shared_ptr<RemapCall> remap;  // set when this call carries out a remapped code
  bool fanuc = false;      // an M98 call: numbered parameters are shared, M99 returns
  int fanuc_repeats = 0;   // M98 L: times the body runs again after this one
  SubDef fanuc_def;        // where the body starts (for L)
};

struct SourceFile {
  std::unique_ptr<LineReader> reader;
  std::string path;
  int id = 0;  // unique per opened source
};

// Cutter compensation queue entry (LinuxCNC-style one-move look-ahead).
struct CompMove {
  enum Kind : uint8_t { Traverse, Feed, Arc } kind = Feed;
  int line = 0;
  Pose end{};
  double dir1 = 0, dir2 = 0;        // a line's programmed direction in the plane (not unit)
  double original_sweep = 0;       // an arc's signed sweep (radians) when held back; 0: not checked
  double first_end = 0, second_end = 0, center1 = 0, center2 = 0, axis_end = 0;
  int rotation = 0;
};

}  // namespace cnc::interp
