#include "commission/hold_to_run.hpp"

#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "commission/controller.hpp"
#include "core/util/time.hpp"

namespace cnc::commission {

void HoldWatch::key(int64_t t_ns) noexcept {
  last_ns_ = t_ns;
  ++keys_;
}

bool HoldWatch::is_released(int64_t now_ns) const noexcept {
  if (keys_ == 0) return false;
  return now_ns - last_ns_ > (keys_ == 1 ? first_gap_ns_ : repeat_gap_ns_);
}

namespace {

// Reads what the terminal has (the keys themselves do not matter).
// Returns how many characters came, 0 when none, -1 when the terminal went
// away (end of file or an error).
int drain(int fd) noexcept {
  char buf[64];
  int n_total = 0;
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n > 0) {
      n_total += static_cast<int>(n);
      continue;
    }
    if (n == 0) return n_total > 0 ? n_total : -1;
    if (errno == EINTR) continue;
    if (errno == EAGAIN || errno == EWOULDBLOCK) return n_total;
    return n_total > 0 ? n_total : -1;
  }
}

// Waits up to `timeout_ns` for the terminal to become readable.
bool readable_within(int fd, int64_t timeout_ns) noexcept {
  pollfd p{fd, POLLIN, 0};
  const int ms = static_cast<int>(timeout_ns > 0 ? (timeout_ns + 999'999) / 1'000'000 : 0);
  const int r = ::poll(&p, 1, ms);
  return r > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR));
}

}  // namespace

HoldToRun::HoldToRun(int fd, int64_t wait_first_ns, HoldWatch watch) : fd_(fd), watch_(watch) {
  if (!::isatty(fd_)) throw std::runtime_error("hold-to-run needs a terminal to hold a key on (standard input is not one)");
  if (::tcgetattr(fd_, &saved_) != 0) throw std::runtime_error(std::string("hold-to-run: the terminal's settings: ") + std::strerror(errno));
  termios raw = saved_;
  raw.c_lflag &= ~static_cast<tcflag_t>(ICANON | ECHO);
  raw.c_cc[VMIN] = 0;
  raw.c_cc[VTIME] = 0;
  if (::tcsetattr(fd_, TCSANOW, &raw) != 0) throw std::runtime_error(std::string("hold-to-run: setting the terminal: ") + std::strerror(errno));
  restore_ = true;
  ::tcflush(fd_, TCIFLUSH);  // keys typed before do not count as held
  const int64_t until = monotonic_ns() + wait_first_ns;
  for (;;) {
    const int64_t left = until - monotonic_ns();
    if (left <= 0) {
      ::tcsetattr(fd_, TCSANOW, &saved_);
      throw std::runtime_error("hold-to-run: no key was pressed within " + std::to_string(wait_first_ns / 1'000'000'000) +
                               " s: nothing moved");
    }
    if (readable_within(fd_, left)) {
      const int n = drain(fd_);
      if (n < 0) {
        ::tcsetattr(fd_, TCSANOW, &saved_);
        throw std::runtime_error("hold-to-run: the terminal closed before a key was held: nothing moved");
      }
      if (n > 0) {
        watch_.key(monotonic_ns());
        break;
      }
    }
  }
  thread_ = std::thread([this] { run(); });
}

HoldToRun::~HoldToRun() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  if (restore_) {
    ::tcflush(fd_, TCIFLUSH);  // the repeats still queued are no input for what follows
    ::tcsetattr(fd_, TCSANOW, &saved_);
  }
}

void HoldToRun::run() noexcept {
  constexpr int64_t kCheckNs = 20'000'000;
  while (!stop_.load()) {
    if (readable_within(fd_, kCheckNs)) {
      const int n = drain(fd_);
      if (n > 0) watch_.key(monotonic_ns());
      if (n < 0) {  // the terminal went away: nobody holds a key
        released_.store(true);
        ::usleep(kCheckNs / 1000);  // a hung-up terminal stays readable
      }
    }
    if (!released_.load() && watch_.is_released(monotonic_ns())) released_.store(true);
    // Said again at every check: a motion that starts after the release
    // (and clears the request as it starts) stops as well.
    if (released_.load()) request_abort();
  }
}

}  // namespace cnc::commission
