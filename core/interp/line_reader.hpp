// Buffered line reader over a file descriptor with byte offsets, so that the
// interpreter can stream a program and jump back for loops and subroutines.
//
// Programs, subroutine files and the parameter file are read only from
// regular files: a FIFO, a device, a socket or a directory is refused when
// it is opened (a FIFO without a writer would block the caller, /dev/zero
// never ends). A line holds at most kMaxLineLength characters, so a file
// without line ends cannot grow the buffer without bound.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace cnc::interp {

// Longest line (without its end-of-line), as LinuxCNC's LINELEN (255 with
// the line end); a longer line is the error "Command too long".
inline constexpr std::size_t kMaxLineLength = 256;

// Opens `path` for reading without blocking and checks that it is a
// regular file. Returns the descriptor (close-on-exec, blocking mode
// restored). Throws InterpError naming the path: its message says why
// ("No such file or directory", "it is a FIFO (named pipe), not a regular
// file", ...).
int open_regular_file(const std::string& path);

class LineReader {
 public:
  // Opens a regular file (open_regular_file); throws InterpError.
  explicit LineReader(const std::string& path);
  // Reads from a string (MDI, tests); `name` is used in errors.
  static LineReader from_string(std::string text, std::string name = "<mdi>");
  ~LineReader();
  LineReader(LineReader&&) noexcept;
  LineReader& operator=(LineReader&&) = delete;
  LineReader(const LineReader&) = delete;

  // Next line without its end-of-line; false at end of file. The view is
  // valid until the next call. Throws InterpError (file, line) for a line
  // longer than kMaxLineLength and for a read error.
  bool next(std::string_view& line);
  // Offset of the line `next` will return, and its 1-based number.
  int64_t offset() const noexcept { return offset_; }
  int line_number() const noexcept { return line_no_; }  // of the last line returned
  void seek(int64_t offset, int line_number_before);

 private:
  LineReader() = default;
  bool fill();
  [[noreturn]] void too_long() const;

  int fd_ = -1;
  std::string name_;
  std::vector<char> buf_;
  std::size_t pos_ = 0, len_ = 0;
  int64_t offset_ = 0;
  int line_no_ = 0;
  bool eof_ = false;
  bool from_string_ = false;
};

}  // namespace cnc::interp
