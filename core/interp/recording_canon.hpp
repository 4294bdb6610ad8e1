// A Canon for tests: records every call as text (rs274 format, without the
// index and N columns) and every motion segment with its source line.
#pragma once

#include <string>
#include <vector>

#include "core/interp/text_canon.hpp"

namespace cnc::interp {

struct RecordedSegment {
  char kind;  // 'T' traverse, 'F' feed, 'A' arc, 'P' probe, 'R' rigid tap
  int line;
  Pose end;
};

class RecordingCanon : public TextCanon {
 public:
  explicit RecordingCanon(cnc::tooltable::ToolTable tools = cnc::tooltable::ToolTable(), Units machine_units = Units::Mm)
      : TextCanon(nullptr, std::move(tools), machine_units) {}

  std::vector<std::string> calls;
  std::vector<RecordedSegment> segments;

  // The calls joined by newlines.
  std::string text() const;
  // Calls whose name starts with `prefix`.
  std::vector<std::string> calls_starting(const std::string& prefix) const;

 protected:
  void emit(std::string_view call) override { calls.emplace_back(call); }
  void segment(char kind, int line, const Pose& end) override { segments.push_back({kind, line, end}); }
};

}  // namespace cnc::interp
