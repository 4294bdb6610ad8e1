// Writing files so that a crash never leaves a truncated one: write a
// temporary file beside the target, fsync it, rename it over the target,
// fsync the directory. Never used from the servo thread.
#pragma once

#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <string_view>

namespace cnc {

// A file that cannot be read or written: what() is "<path>: <reason>".
class FileError : public std::runtime_error {
 public:
  FileError(const std::filesystem::path& path, std::string reason)
      : std::runtime_error(path.string() + ": " + reason), reason_(std::move(reason)) {}
  // Without the path: "is a directory, not a regular file", "cannot open: ...".
  const std::string& reason() const noexcept { return reason_; }

 private:
  std::string reason_;
};

// Replaces `path` with `content` atomically; throws FileError naming
// the path and the failing step.
void write_file_atomically(const std::filesystem::path& path, std::string_view content);

// Removes the temporary files write_file_atomically left beside `path` when
// the process was killed between creating and renaming them (".<name>.XXXXXX",
// owned by this user, not modified for `min_age_s`). Returns how many.
int remove_stale_temporaries(const std::filesystem::path& path, int min_age_s = 10);

// Why a file of this mode is not a regular file ("is a directory, not a
// regular file", ...), or nullptr when it is one.
const char* not_regular_reason(unsigned mode) noexcept;

// Opens a regular file for reading without ever blocking on a FIFO or a
// device; refuses directories, FIFOs, sockets and devices (and symbolic
// links when `no_follow`: for paths in folders other users may write).
// Returns the descriptor (O_CLOEXEC); throws FileError.
int open_regular_file(const std::filesystem::path& path, bool no_follow = false);

// Reads a whole regular file of at most `max_bytes` (configuration files,
// tables: 64 MiB is far beyond any real one, and /dev/zero or a FIFO never
// gets here); throws FileError.
inline constexpr std::size_t kMaxReadFileBytes = std::size_t{64} << 20;
std::string read_file(const std::filesystem::path& path, std::size_t max_bytes = kMaxReadFileBytes);

}  // namespace cnc
