// libFuzzer entry point: arbitrary bytes as a tool table, read for a
// non-random and a random changer. A table that loads is written out
// (to_text) and must load again with the same tools. Anything but
// ConfigError, a crash, a sanitizer report or a hang is a bug.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "core/tooltable/tool_table.hpp"
#include "core/util/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::tooltable;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  for (const ChangerKind kind : {ChangerKind::NonRandom, ChangerKind::Random}) {
    ToolTable t(kind);
    try {
      t = ToolTable::parse(text, "fuzz.tbl", kind);
    } catch (const cnc::ConfigError&) {
      continue;
    }
    const std::string written = t.to_text();
    ToolTable back(kind);
    try {
      back = ToolTable::parse(written, "written.tbl", kind);
    } catch (const cnc::ConfigError&) {
      std::abort();  // what it writes, it must read
    }
    if (back.tools().size() != t.tools().size()) std::abort();
  }
  return 0;
}
