#include "core/interp/line_reader.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace cnc::interp {

namespace {
constexpr std::size_t kBufferSize = 1 << 16;
}

LineReader::LineReader(const std::string& path) : buf_(kBufferSize) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw std::runtime_error(path + ": " + std::strerror(errno));
}

LineReader LineReader::from_string(std::string text) {
  LineReader r;
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
    : fd_(o.fd_), buf_(std::move(o.buf_)), pos_(o.pos_), len_(o.len_), offset_(o.offset_), line_no_(o.line_no_),
      eof_(o.eof_), from_string_(o.from_string_) {
  o.fd_ = -1;
}

bool LineReader::fill() {
  if (eof_ || from_string_) return false;
  // Keep the unread tail at the front of the buffer.
  if (pos_ > 0) {
    std::memmove(buf_.data(), buf_.data() + pos_, len_ - pos_);
    len_ -= pos_;
    pos_ = 0;
  }
  if (len_ == buf_.size()) buf_.resize(buf_.size() * 2);
  for (;;) {
    const ssize_t n = ::read(fd_, buf_.data() + len_, buf_.size() - len_);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
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
    const void* nl = len_ > pos_ ? std::memchr(start, '\n', len_ - pos_) : nullptr;
    if (nl != nullptr) {
      const std::size_t n = static_cast<std::size_t>(static_cast<const char*>(nl) - start);
      std::size_t m = n;
      if (m > 0 && start[m - 1] == '\r') --m;
      line = std::string_view(start, m);
      pos_ += n + 1;
      offset_ += static_cast<int64_t>(n + 1);
      ++line_no_;
      return true;
    }
    if (!fill()) {
      if (pos_ >= len_) return false;
      std::size_t m = len_ - pos_;
      const char* s = buf_.data() + pos_;
      if (m > 0 && s[m - 1] == '\r') --m;
      line = std::string_view(s, m);
      offset_ += static_cast<int64_t>(len_ - pos_);
      pos_ = len_;
      ++line_no_;
      return true;
    }
  }
}

void LineReader::seek(int64_t offset, int line_number_before) {
  if (from_string_) {
    pos_ = static_cast<std::size_t>(offset);
  } else {
    if (::lseek(fd_, offset, SEEK_SET) < 0) throw std::runtime_error(std::string("seek failed: ") + std::strerror(errno));
    pos_ = len_ = 0;
    eof_ = false;
  }
  offset_ = offset;
  line_no_ = line_number_before;
}

}  // namespace cnc::interp
