#include "core/interp/line_reader.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/interp/interp.hpp"
#include "core/util/atomic_file.hpp"

namespace cnc::interp {

namespace {
constexpr std::size_t kBufferSize = 1 << 16;
static_assert(kBufferSize > 2 * (kMaxLineLength + 2), "the buffer must hold a whole line and what follows it");
}  // namespace

int open_regular_file(const std::string& path) {
  try {
    return cnc::open_regular_file(path);
  } catch (const FileError& e) {
    // The interpreter's wording: "No such file or directory", "it is a
    // FIFO (named pipe), not a regular file".
    std::string why = e.reason();
    if (why.rfind("cannot open: ", 0) == 0) why.erase(0, 13);
    if (why.rfind("is ", 0) == 0) why = "it " + why;
    throw InterpError(why, path, 0, "");
  }
}

LineReader::LineReader(const std::string& path) : name_(path), buf_(kBufferSize) { fd_ = open_regular_file(path); }

LineReader LineReader::from_string(std::string text, std::string name) {
  LineReader r;
  r.name_ = std::move(name);
  r.buf_.assign(text.begin(), text.end());
  r.len_ = r.buf_.size();
  r.eof_ = true;
  r.from_string_ = true;
  return r;
}

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

LineReader::LineReader(LineReader&& o) noexcept
    : fd_(o.fd_), name_(std::move(o.name_)), buf_(std::move(o.buf_)), pos_(o.pos_), len_(o.len_),
      offset_(o.offset_), line_no_(o.line_no_), eof_(o.eof_), from_string_(o.from_string_) {
  o.fd_ = -1;
}

void LineReader::too_long() const {
  throw InterpError("Command too long (a line may hold at most " + std::to_string(kMaxLineLength) + " characters)",
                    name_, line_no_ + 1, "");
}

bool LineReader::fill() {
  if (eof_ || from_string_) return false;
  // Keep the unread tail (less than a line) at the front of the buffer.
  if (pos_ > 0) {
    std::memmove(buf_.data(), buf_.data() + pos_, len_ - pos_);
    len_ -= pos_;
    pos_ = 0;
  }
  if (len_ == buf_.size()) too_long();  // next() refuses long lines before this
  for (;;) {
    const ssize_t n = ::read(fd_, buf_.data() + len_, buf_.size() - len_);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw InterpError(std::string("read error: ") + std::strerror(errno), name_, line_no_ + 1, "");
    if (n == 0) {
      eof_ = true;
      return false;
    }
    len_ += static_cast<std::size_t>(n);
    return true;
  }
}

bool LineReader::next(std::string_view& line) {
  for (;;) {
    const char* start = buf_.data() + pos_;
    const std::size_t avail = len_ - pos_;
    const void* nl = avail > 0 ? std::memchr(start, '\n', avail) : nullptr;
    if (nl != nullptr) {
      const std::size_t n = static_cast<std::size_t>(static_cast<const char*>(nl) - start);
      std::size_t m = n;
      if (m > 0 && start[m - 1] == '\r') --m;
      if (m > kMaxLineLength) too_long();
      line = std::string_view(start, m);
      pos_ += n + 1;
      offset_ += static_cast<int64_t>(n + 1);
      ++line_no_;
      return true;
    }
    // No line end yet: more than a line's worth (and a '\r') is too long
    // whatever follows.
    if (avail > kMaxLineLength + 1) too_long();
    if (!fill()) {
      if (pos_ >= len_) return false;
      std::size_t m = len_ - pos_;
      const char* s = buf_.data() + pos_;
      if (m > 0 && s[m - 1] == '\r') --m;
      if (m > kMaxLineLength) too_long();
      line = std::string_view(s, m);
      offset_ += static_cast<int64_t>(len_ - pos_);
      pos_ = len_;
      ++line_no_;
      return true;
    }
  }
}

void LineReader::seek(int64_t offset, int line_number_before) {
  // The buffer holds the file from offset_ - pos_ to there + len_ (and the
  // descriptor stands at its end): a jump back into it (a loop) needs no
  // system call.
  const int64_t buffer_start = offset_ - static_cast<int64_t>(pos_);
  if (from_string_ || (offset >= buffer_start && offset <= buffer_start + static_cast<int64_t>(len_))) {
    pos_ = static_cast<std::size_t>(offset - (from_string_ ? 0 : buffer_start));
  } else {
    if (::lseek(fd_, offset, SEEK_SET) < 0) {
      throw InterpError(std::string("seek failed: ") + std::strerror(errno), name_, line_number_before + 1, "");
    }
    pos_ = len_ = 0;
    eof_ = false;
  }
  offset_ = offset;
  line_no_ = line_number_before;
}

}  // namespace cnc::interp
