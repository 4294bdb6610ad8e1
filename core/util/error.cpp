#include "core/util/error.hpp"

namespace cnc {
namespace {
std::string place(const std::string& file, int line) {
  std::string p = file.empty() ? std::string("<input>") : file;
  if (line > 0) p += ":" + std::to_string(line);
  return p + ": ";
}
}  // namespace

ConfigError::ConfigError(const std::string& file, int line, const std::string& what)
    : std::runtime_error(place(file, line) + what), file_(file), line_(line), reason_(what) {}

}  // namespace cnc
