// LinuxCNC's tool table: the file format ("T1 P1 D6 Z+1.5 ;comment") and the
// in-memory table that the interpreter and the I/O controller share, for
// random and non-random tool changers (manual section 3.24). Non-realtime:
// loading throws ConfigError with file:line; saving is atomic.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/util/pose.hpp"

namespace cnc::tooltable {

// [EMCIO]RANDOM_TOOLCHANGER: a random changer swaps the spindle tool into
// the pocket the new tool came from; a non-random one returns every tool to
// its own pocket.
enum class ChangerKind { NonRandom, Random };

inline constexpr int kMaxPocket = 1000;  // LinuxCNC's CANON_POCKETS_MAX - 1
inline constexpr int kNoTool = -1;

struct Tool {
  int number = kNoTool;  // T word; kNoTool: the slot is empty
  int pocket = 0;        // P word; 0 is the spindle
  Pose offset{};         // tool length offsets X..W, machine units
  double diameter = 0;   // D
  double front_angle = 0;  // I (lathe)
  double back_angle = 0;   // J (lathe)
  int orientation = 0;     // Q (lathe, 0-9)
  std::string comment;

  bool is_empty() const noexcept { return number == kNoTool; }
  bool operator==(const Tool&) const = default;
};

// Formats one tool as a tool table line (no newline).
std::string format_tool(const Tool& tool);

// Tools are addressed by "tooldata index" as in LinuxCNC: index 0 is the
// spindle; on a non-random changer indices 1.. are the file's tools in order
// (pocket numbers kept but compacted away), on a random changer the index is
// the pocket number.
class ToolTable {
 public:
  explicit ToolTable(ChangerKind kind = ChangerKind::NonRandom);

  // Parses a tool table; `filename` names the file in errors. Throws
  // ConfigError "file:line: ..." for bad words, numbers, duplicates.
  static ToolTable parse(std::string_view text, const std::string& filename, ChangerKind kind);
  static ToolTable load(const std::filesystem::path& path, ChangerKind kind);

  // The file text: each tool in its home pocket (non-random) or where it is
  // now, spindle included (random). Sorted by pocket for random changers.
  std::string to_text() const;
  // Writes to_text() atomically.
  void save(const std::filesystem::path& path) const;

  ChangerKind kind() const noexcept { return kind_; }
  bool is_random() const noexcept { return kind_ == ChangerKind::Random; }
  // One past the highest index in use (at least 1: the spindle).
  int size() const noexcept { return static_cast<int>(slots_.size()); }
  // Slot at a tooldata index; an empty Tool when out of range or unused.
  const Tool& at(int index) const noexcept;
  const Tool& spindle() const noexcept { return slots_[0]; }
  // Tooldata index (>= 1, never the spindle) of a tool number, if present.
  std::optional<int> find_tool(int number) const noexcept;
  // Index of a tool number, the spindle included (random changers keep the
  // loaded tool only there).
  std::optional<int> find_tool_anywhere(int number) const noexcept;
  // Index of the slot holding a pocket number (spindle excluded).
  std::optional<int> find_pocket(int pocket) const noexcept;

  // Places a tool at an index (growing the table); used by loaders and by
  // G10 L1/L10/L11 through update_tool().
  void set_slot(int index, const Tool& tool);
  // Replaces the data (offsets, diameter, angles, orientation, comment) of
  // a tool number wherever it is; adds it in a new slot when unknown (a new
  // pocket on random changers must be free). Non-random: when the tool is in
  // the spindle the spindle copy is updated too. Returns the index written.
  int update_tool(const Tool& tool);
  // M6: non-random copies the slot into the spindle; random swaps the
  // spindle's tool into the slot (pocket numbers follow). Index 0 unloads
  // the spindle on non-random changers.
  void change_tool(int index);
  // M61: records that the tool at `index` is in the spindle without moving
  // anything: its data is copied into the spindle slot (both kinds).
  void set_spindle_tool(int index);

  // All non-empty slots except the spindle, by index.
  std::vector<Tool> tools() const;

 private:
  ChangerKind kind_;
  std::vector<Tool> slots_;  // [0] spindle
};

}  // namespace cnc::tooltable
