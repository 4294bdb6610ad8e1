#include "core/tooltable/tool_table.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <set>

#include "core/util/atomic_file.hpp"
#include "core/util/error.hpp"
#include "core/util/strings.hpp"

namespace cnc::tooltable {
namespace {

const Tool kEmpty{};

std::string fmt_real(char letter, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, " %c%+f", letter, v);
  return buf;
}

struct LineParser {
  const std::string& file;
  int line;
  [[noreturn]] void fail(const std::string& what) const { throw ConfigError(file, line, what); }

  double real(char letter, std::string_view text) const {
    const auto v = parse_double(text);
    if (!v) fail(std::string("bad number '") + std::string(text) + "' after " + letter + ", expected a real number");
    return *v;
  }
  int integer(char letter, std::string_view text) const {
    const auto v = parse_int(text);
    if (!v || *v < -2147483647 || *v > 2147483647) {
      fail(std::string("bad number '") + std::string(text) + "' after " + letter + ", expected an integer");
    }
    return static_cast<int>(*v);
  }
};

}  // namespace

std::string format_tool(const Tool& t) {
  std::string out = "T" + std::to_string(t.number) + " P" + std::to_string(t.pocket);
  for (int i = 0; i < kNumAxes; ++i) {
    if (t.offset[i] != 0.0) out += fmt_real(kAxisLetters[i], t.offset[i]);
  }
  if (t.diameter != 0.0) out += fmt_real('D', t.diameter);
  if (t.front_angle != 0.0) out += fmt_real('I', t.front_angle);
  if (t.back_angle != 0.0) out += fmt_real('J', t.back_angle);
  if (t.orientation != 0) out += " Q" + std::to_string(t.orientation);
  out += " ;";
  out += t.comment;
  return out;
}

ToolTable::ToolTable(ChangerKind kind) : kind_(kind), slots_(1) {}

ToolTable ToolTable::parse(std::string_view text, const std::string& filename, ChangerKind kind) {
  ToolTable table(kind);
  const bool random = kind == ChangerKind::Random;
  std::set<int> seen_tools, seen_pockets;
  int line_no = 0;
  int next_index = 1;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const LineParser p{filename, line_no};
    Tool tool;
    const std::size_t semi = line.find(';');
    if (semi != std::string_view::npos) {
      tool.comment = std::string(trim(line.substr(semi + 1)));
      line = line.substr(0, semi);
    }
    line = trim(line);
    if (line.empty()) {
      if (end >= text.size()) break;
      continue;
    }
    bool has_t = false, has_p = false;
    std::set<char> letters;
    for (const std::string& word : split_blanks(line)) {
      const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(word[0])));
      const std::string_view value = std::string_view(word).substr(1);
      if (!letters.insert(letter).second) p.fail(std::string("word ") + letter + " appears twice");
      if (value.empty()) p.fail(std::string("missing value after ") + letter);
      const int axis = axis_index(letter);
      if (letter == 'T') {
        tool.number = p.integer(letter, value);
        has_t = true;
      } else if (letter == 'P') {
        tool.pocket = p.integer(letter, value);
        has_p = true;
      } else if (axis >= 0) {
        tool.offset[axis] = p.real(letter, value);
      } else if (letter == 'D') {
        tool.diameter = p.real(letter, value);
      } else if (letter == 'I') {
        tool.front_angle = p.real(letter, value);
      } else if (letter == 'J') {
        tool.back_angle = p.real(letter, value);
      } else if (letter == 'Q') {
        tool.orientation = p.integer(letter, value);
        if (tool.orientation < 0 || tool.orientation > 9) p.fail("orientation Q" + std::to_string(tool.orientation) + " out of range, expected 0 to 9");
      } else {
        p.fail("unexpected word '" + word + "', expected T, P, X Y Z A B C U V W, D, I, J, Q or a ;comment");
      }
    }
    if (!has_t) p.fail("missing T word (tool number)");
    if (!has_p) p.fail("missing P word (pocket number)");
    if (random) {
      if (tool.number < 0) p.fail("tool number T" + std::to_string(tool.number) + " is negative");
      if (tool.pocket < 0 || tool.pocket > kMaxPocket) {
        p.fail("pocket P" + std::to_string(tool.pocket) + " out of range, expected 0 to " + std::to_string(kMaxPocket));
      }
    } else {
      if (tool.number <= 0) p.fail("tool number T" + std::to_string(tool.number) + " not allowed, expected a positive number (T0 means no tool)");
      if (tool.pocket <= 0) p.fail("pocket P" + std::to_string(tool.pocket) + " not allowed, expected a positive pocket number");
    }
    if (!seen_tools.insert(tool.number).second) p.fail("tool T" + std::to_string(tool.number) + " defined twice");
    if (!seen_pockets.insert(tool.pocket).second) p.fail("pocket P" + std::to_string(tool.pocket) + " used twice");
    if (random) {
      table.set_slot(tool.pocket, tool);
    } else {
      if (next_index > kMaxPocket) p.fail("too many tools, at most " + std::to_string(kMaxPocket));
      table.set_slot(next_index++, tool);
    }
    if (end >= text.size()) break;
  }
  return table;
}

ToolTable ToolTable::load(const std::filesystem::path& path, ChangerKind kind) {
  std::string text;
  try {
    text = read_file(path);
  } catch (const FileError& e) {
    throw ConfigError(path.string(), 0, "cannot read tool table: " + e.reason());
  }
  return parse(text, path.string(), kind);
}

std::string ToolTable::to_text() const {
  std::vector<const Tool*> out;
  if (is_random()) {
    for (const Tool& t : slots_) {
      if (!t.is_empty()) out.push_back(&t);
    }
  } else {
    for (std::size_t i = 1; i < slots_.size(); ++i) {
      if (!slots_[i].is_empty()) out.push_back(&slots_[i]);
    }
  }
  std::string text;
  for (const Tool* t : out) {
    text += format_tool(*t);
    text += '\n';
  }
  return text;
}

void ToolTable::save(const std::filesystem::path& path) const { write_file_atomically(path, to_text()); }

const Tool& ToolTable::at(int index) const noexcept {
  if (index < 0 || index >= size()) return kEmpty;
  return slots_[static_cast<std::size_t>(index)];
}

std::optional<int> ToolTable::find_tool(int number) const noexcept {
  for (int i = 1; i < size(); ++i) {
    if (slots_[static_cast<std::size_t>(i)].number == number && number != kNoTool) return i;
  }
  return std::nullopt;
}

std::optional<int> ToolTable::find_tool_anywhere(int number) const noexcept {
  if (number != kNoTool && slots_[0].number == number) return 0;
  return find_tool(number);
}

std::optional<int> ToolTable::find_pocket(int pocket) const noexcept {
  for (int i = 1; i < size(); ++i) {
    const Tool& t = slots_[static_cast<std::size_t>(i)];
    if (!t.is_empty() && t.pocket == pocket) return i;
  }
  return std::nullopt;
}

void ToolTable::set_slot(int index, const Tool& tool) {
  if (index < 0 || index > kMaxPocket) return;
  if (index >= size()) slots_.resize(static_cast<std::size_t>(index) + 1);
  slots_[static_cast<std::size_t>(index)] = tool;
}

int ToolTable::update_tool(const Tool& tool) {
  auto copy_data = [&](Tool& dst) {
    dst.offset = tool.offset;
    dst.diameter = tool.diameter;
    dst.front_angle = tool.front_angle;
    dst.back_angle = tool.back_angle;
    dst.orientation = tool.orientation;
    if (!tool.comment.empty()) dst.comment = tool.comment;
  };
  const bool in_spindle = tool.number != kNoTool && slots_[0].number == tool.number;
  if (is_random() && in_spindle) {
    // A random changer's loaded tool has no other home.
    copy_data(slots_[0]);
    return 0;
  }
  if (const auto idx = find_tool(tool.number)) {
    copy_data(slots_[static_cast<std::size_t>(*idx)]);
    // Manual 3.24.3.4 buglet fixed: the spindle copy is refreshed only on
    // non-random changers, and only when this very tool is loaded.
    if (in_spindle) copy_data(slots_[0]);
    return *idx;
  }
  int index = 0;
  if (is_random()) {
    index = tool.pocket;
    if (index <= 0 || index > kMaxPocket || !at(index).is_empty()) return -1;
  } else {
    index = size();
    for (int i = 1; i < size(); ++i) {
      if (slots_[static_cast<std::size_t>(i)].is_empty()) {
        index = i;
        break;
      }
    }
    if (index > kMaxPocket) return -1;
  }
  Tool t = tool;
  if (!is_random() && t.pocket <= 0) t.pocket = index;
  set_slot(index, t);
  return index;
}

void ToolTable::change_tool(int index) {
  if (index < 0 || index >= size()) {
    if (!is_random() && index == 0) slots_[0] = Tool{};
    return;
  }
  if (index == 0) {
    if (!is_random()) {
      slots_[0] = Tool{};
      slots_[0].number = 0;
    }
    return;
  }
  if (is_random()) {
    Tool incoming = slots_[static_cast<std::size_t>(index)];
    Tool outgoing = slots_[0];
    const int pocket = incoming.pocket;
    incoming.pocket = 0;
    if (!outgoing.is_empty()) outgoing.pocket = pocket;
    slots_[0] = incoming;
    slots_[static_cast<std::size_t>(index)] = outgoing;
  } else {
    slots_[0] = slots_[static_cast<std::size_t>(index)];
  }
}

void ToolTable::set_spindle_tool(int index) {
  if (index <= 0 || index >= size()) {
    slots_[0] = Tool{};
    slots_[0].number = 0;
    return;
  }
  slots_[0] = slots_[static_cast<std::size_t>(index)];
}

std::vector<Tool> ToolTable::tools() const {
  std::vector<Tool> out;
  for (std::size_t i = 1; i < slots_.size(); ++i) {
    if (!slots_[i].is_empty()) out.push_back(slots_[i]);
  }
  return out;
}

}  // namespace cnc::tooltable
