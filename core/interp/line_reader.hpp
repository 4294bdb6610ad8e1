// Buffered line reader over a file descriptor with byte offsets, so that the
// interpreter can stream a program and jump back for loops and subroutines.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::interp {

class LineReader {
 public:
  // Opens a file; throws std::runtime_error naming it on failure.
  explicit LineReader(const std::string& path);
  // Reads from a string (MDI, tests).
  static LineReader from_string(std::string text);
  ~LineReader();
  LineReader(LineReader&&) noexcept;
  LineReader& operator=(LineReader&&) = delete;
  LineReader(const LineReader&) = delete;

  // Next line without its end-of-line; false at end of file. The view is
  // valid until the next call.
  bool next(std::string_view& line);
  // Offset of the line `next` will return, and its 1-based number.
  int64_t offset() const noexcept { return offset_; }
  int line_number() const noexcept { return line_no_; }  // of the last line returned
  void seek(int64_t offset, int line_number_before);

 private:
  LineReader() = default;
  bool fill();

  int fd_ = -1;
  std::vector<char> buf_;
  std::size_t pos_ = 0, len_ = 0;
  int64_t offset_ = 0;
  int line_no_ = 0;
  bool eof_ = false;
  bool from_string_ = false;
};

}  // namespace cnc::interp
