// libFuzzer entry point: feeds arbitrary bytes to the interpreter as an MDI
// program, line by line, with a canon that answers queries like rs274's.
// Any crash, sanitizer report, hang or exception other than InterpError is
// a bug.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/interp/interp.hpp"
#include "core/interp/recording_canon.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace cnc::interp;
  static const cnc::tooltable::ToolTable table =
      cnc::tooltable::ToolTable::parse("T1 P1 Z1 D0.25\nT2 P2 Z2 D0.5\n", "fuzz.tbl", cnc::tooltable::ChangerKind::NonRandom);
  RecordingCanon canon(table);
  Interpreter in(canon);
  in.init();
  std::string_view text(reinterpret_cast<const char*>(data), size);
  int lines = 0;
  while (!text.empty() && lines < 64) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view() : text.substr(nl + 1);
    ++lines;
    try {
      in.execute(line);
    } catch (const InterpError&) {
      in.reset();
    }
    if (canon.calls.size() > 100000) canon.calls.clear();
  }
  return 0;
}
