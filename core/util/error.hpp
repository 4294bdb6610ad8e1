// Errors raised while loading what a user wrote (INI, HAL files, tool
// tables, device descriptions). The message always starts with the place:
// "file:line: " (or "file: " when no line applies), then what was expected.
// Non-realtime only: the servo thread never throws.
#pragma once

#include <stdexcept>
#include <string>

namespace cnc {

class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, int line, const std::string& what);
  const std::string& file() const noexcept { return file_; }
  int line() const noexcept { return line_; }
  // The message without the "file:line: " prefix.
  const std::string& reason() const noexcept { return reason_; }

 private:
  std::string file_;
  int line_;
  std::string reason_;
};

}  // namespace cnc
