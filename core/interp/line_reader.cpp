#include "core/interp/line_reader.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/interp/interp.hpp"

namespace cnc::interp {

namespace {
constexpr std::size_t kBufferSize = 1 << 16;
static_assert(kBufferSize > 2 * (kMaxLineLength + 2), "the buffer must hold a whole line and what follows it");

const char* kind_of(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a plain file";
}
}  // namespace

int open_regular_file(const std::string& path) {
  // O_NONBLOCK: opening a FIFO without a writer (or a serial device waiting
  // for carrier) must not block; O_NOCTTY: a terminal never becomes ours.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) throw InterpError(std::strerror(errno), path, 0, "");
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw InterpError(std::strerror(e), path, 0, "");
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw InterpError(std::string("it is ") + kind_of(st.st_mode) + ", not a regular file", path, 0, "");
  }
  // Back to blocking reads (no effect on a regular file, but explicit).
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
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
