// Writing files so that a crash never leaves a truncated one: write a
// temporary file beside the target, fsync it, rename it over the target,
// fsync the directory. Never used from the servo thread.
#pragma once

#include <filesystem>
#include <string_view>

namespace cnc {

// Replaces `path` with `content` atomically; throws std::runtime_error naming
// the path and the failing step.
void write_file_atomically(const std::filesystem::path& path, std::string_view content);

// Reads a whole file; throws std::runtime_error naming the path.
std::string read_file(const std::filesystem::path& path);

}  // namespace cnc
