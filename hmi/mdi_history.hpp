// The MDI history ([DISPLAY]MDI_HISTORY_FILE): one command per line, oldest
// first, no duplicates (G-code is compared without case and blanks; the
// newest spelling is kept, at the end), only commands the controller
// accepted are added (the caller decides), written atomically after each
// change so a crash never truncates it. No Qt.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::hmi {

class MdiHistory {
 public:
  explicit MdiHistory(std::filesystem::path file = {}, std::size_t max_entries = 1000);

  // Reads the file (a missing file is an empty history). False with
  // error() set when it exists but cannot be read.
  bool load();
  // Adds a command (moving an earlier equal one to the end) and saves.
  // False with error() set when saving failed; the entry is kept in memory.
  bool add(std::string_view command);
  bool clear();

  const std::vector<std::string>& entries() const noexcept { return entries_; }
  const std::filesystem::path& file() const noexcept { return file_; }
  const std::string& error() const noexcept { return error_; }

  // The comparison key: upper case, blanks removed outside comments.
  static std::string key(std::string_view command);

 private:
  bool save();

  std::filesystem::path file_;
  std::size_t max_;
  std::vector<std::string> entries_;
  std::string error_;
};

}  // namespace cnc::hmi
