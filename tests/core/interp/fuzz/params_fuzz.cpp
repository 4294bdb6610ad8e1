// libFuzzer entry point: arbitrary bytes as the interpreter's parameter
// (var) file ([RS274NGC]PARAMETER_FILE), read by init(). A file that loads
// is saved and must load again. Anything but InterpError from the loader,
// a crash, a sanitizer report or a hang is a bug.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "core/interp/interp.hpp"
#include "core/interp/recording_canon.hpp"
#include "core/util/atomic_file.hpp"

namespace {

// A folder of this process's own for the file the interpreter reads and
// saves, removed at exit.
struct Folder {
  std::filesystem::path path;
  Folder() {
    std::string t = (std::filesystem::temp_directory_path() / "cnc-params-fuzz-XXXXXX").string();
    if (!::mkdtemp(t.data())) std::abort();
    path = t;
  }
  ~Folder() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

std::filesystem::path var_file() {
  static const Folder folder;
  return folder.path / "fuzz.var";
}

// True when the interpreter starts with `file` as its parameter file; then
// writes the parameters back when `save`.
bool loads(const std::filesystem::path& file, bool save) {
  static const cnc::tooltable::ToolTable table =
      cnc::tooltable::ToolTable::parse("T1 P1 Z1 D0.25\n", "fuzz.tbl", cnc::tooltable::ChangerKind::NonRandom);
  cnc::interp::RecordingCanon canon(table);
  cnc::interp::Config config;
  config.parameter_file = file;
  cnc::interp::Interpreter in(canon, config);
  try {
    in.init();
  } catch (const cnc::interp::InterpError&) {
    return false;
  }
  if (save) in.save_parameters();
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::filesystem::path file = var_file();
  cnc::write_file_atomically(file, std::string(reinterpret_cast<const char*>(data), size));
  if (loads(file, true) && !loads(file, false)) std::abort();  // what was saved must load
  return 0;
}
