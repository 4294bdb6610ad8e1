// Test support shared by every test program: an allocation counter that
// proves realtime code does not allocate, temporary folders, paths.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace cnc::testing {

// Counts malloc/calloc/realloc/new calls made by armed threads (or by every
// thread while armed globally). Works because the test program's own malloc
// family wraps glibc's.
class AllocationCounter {
 public:
  static void arm_this_thread() noexcept;
  static void disarm_this_thread() noexcept;
  static void arm_all_threads() noexcept;
  static void disarm_all_threads() noexcept;
  static uint64_t count() noexcept;
  static void reset() noexcept;
  // False in sanitizer builds, where the wrappers are not installed.
  static bool available() noexcept;
};

// Arms the current thread for its lifetime; allocations() tells how many.
class ScopedAllocationCheck {
 public:
  ScopedAllocationCheck() noexcept;
  ~ScopedAllocationCheck();
  uint64_t allocations() const noexcept;

 private:
  uint64_t start_;
};

// A fresh folder under the build tree, removed by the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const noexcept { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }
  // Writes a file inside the folder and returns its path.
  std::filesystem::path write(const std::string& name, const std::string& content) const;

 private:
  std::filesystem::path path_;
};

inline std::filesystem::path source_dir() { return CNC_SOURCE_DIR; }
inline std::filesystem::path binary_dir() { return CNC_BINARY_DIR; }
// A name no other test process uses at the same time (for instances, sockets).
std::string unique_name(const std::string& prefix);

// What a shell command printed (stdout and stderr together) and its exit
// status (-1 when it did not exit normally).
struct CommandOutput {
  int code = -1;
  std::string text;
};
CommandOutput run_shell(const std::string& command);

}  // namespace cnc::testing
