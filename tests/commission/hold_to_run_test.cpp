// Hold-to-run on a terminal (commission/hold_to_run.*): when a held key
// counts as let go, and the watcher on a pseudo-terminal, where the test
// plays the key's auto-repeat.
#include "commission/hold_to_run.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <stdexcept>
#include <thread>

#include "commission/controller.hpp"

namespace cnc::commission {
namespace {

constexpr int64_t kMs = 1'000'000;

TEST(HoldWatch, NothingIsReleasedBeforeTheFirstKey) {
  HoldWatch w(1000 * kMs, 250 * kMs);
  EXPECT_FALSE(w.is_held());
  EXPECT_FALSE(w.is_released(1'000'000 * kMs));
}

TEST(HoldWatch, TheFirstKeyWaitsForTheAutoRepeatDelay) {
  HoldWatch w(1000 * kMs, 250 * kMs);
  w.key(0);
  EXPECT_TRUE(w.is_held());
  EXPECT_FALSE(w.is_released(700 * kMs)) << "under X the first repeat comes 660 ms after the press";
  EXPECT_FALSE(w.is_released(1000 * kMs));
  EXPECT_TRUE(w.is_released(1001 * kMs));
}

TEST(HoldWatch, RepeatsKeepItHeldAndAGapInThemReleasesIt) {
  HoldWatch w(1000 * kMs, 250 * kMs);
  w.key(0);
  int64_t t = 660 * kMs;
  for (int i = 0; i < 50; ++i, t += 40 * kMs) {  // 25 repeats a second
    w.key(t);
    EXPECT_FALSE(w.is_released(t + 39 * kMs));
  }
  const int64_t last = t - 40 * kMs;
  EXPECT_FALSE(w.is_released(last + 250 * kMs));
  EXPECT_TRUE(w.is_released(last + 251 * kMs)) << "after repeats the short gap counts, not the first one";
}

// A pseudo-terminal: the watcher reads the slave side, the test types on
// the master side.
struct Pty {
  int master = -1, slave = -1;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) throw std::runtime_error("no pseudo-terminal");
    slave = ::open(::ptsname(master), O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (slave < 0) throw std::runtime_error("no pseudo-terminal slave");
  }
  ~Pty() {
    ::close(slave);
    ::close(master);
  }
  void type() const { ASSERT_EQ(::write(master, " ", 1), 1); }
};

bool abort_within(std::chrono::seconds s) {
  const auto until = std::chrono::steady_clock::now() + s;
  while (std::chrono::steady_clock::now() < until) {
    if (abort_requested()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return abort_requested();
}

TEST(HoldToRun, AFileThatIsNoTerminalIsRefused) {
  const int fd = ::open("/dev/null", O_RDONLY);
  try {
    HoldToRun h(fd, 100 * kMs);
    FAIL() << "accepted /dev/null";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("needs a terminal"), std::string::npos) << e.what();
  }
  ::close(fd);
}

TEST(HoldToRun, NoKeyPressedIsAnErrorAndTheTerminalIsPutBack) {
  Pty p;
  termios before{};
  ASSERT_EQ(::tcgetattr(p.slave, &before), 0);
  try {
    HoldToRun h(p.slave, 100 * kMs);
    FAIL() << "no key was pressed";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no key was pressed"), std::string::npos) << e.what();
  }
  termios after{};
  ASSERT_EQ(::tcgetattr(p.slave, &after), 0);
  EXPECT_EQ(after.c_lflag, before.c_lflag);
}

TEST(HoldToRun, HeldKeepsTheMotionAndLettingGoAbortsIt) {
  Pty p;
  clear_abort();
  termios before{};
  ASSERT_EQ(::tcgetattr(p.slave, &before), 0);
  std::atomic<bool> typing{true};
  std::thread keyboard([&] {
    while (typing.load()) {
      p.type();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  {
    // Generous gaps: the host may stall the typing thread; the test checks
    // the logic, not the terminal's timing.
    HoldToRun h(p.slave, 10'000 * kMs, HoldWatch(3000 * kMs, 1500 * kMs));
    termios raw{};
    ASSERT_EQ(::tcgetattr(p.slave, &raw), 0);
    EXPECT_EQ(raw.c_lflag & (ICANON | ECHO), 0u) << "keys are read one by one, not echoed";
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    EXPECT_FALSE(abort_requested()) << "the key is held";
    EXPECT_FALSE(h.was_released());
    typing.store(false);
    keyboard.join();
    EXPECT_TRUE(abort_within(std::chrono::seconds(30))) << "let go: the motion is asked to stop";
    EXPECT_TRUE(h.was_released());
    clear_abort();
    EXPECT_TRUE(abort_within(std::chrono::seconds(30))) << "asked again: a motion starting after the release stops too";
  }
  termios after{};
  ASSERT_EQ(::tcgetattr(p.slave, &after), 0);
  EXPECT_EQ(after.c_lflag, before.c_lflag) << "the terminal is put back";
  clear_abort();
}

TEST(HoldToRun, TheTerminalGoingAwayCountsAsLettingGo) {
  Pty p;
  clear_abort();
  std::thread press([&] {  // after the watcher has dropped what was typed before it
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    p.type();
  });
  {
    HoldToRun h(p.slave, 10'000 * kMs, HoldWatch(600'000 * kMs, 600'000 * kMs));
    press.join();
    ::close(p.master);  // the terminal hangs up: no gap would end this hold
    p.master = -1;
    EXPECT_TRUE(abort_within(std::chrono::seconds(30)));
    EXPECT_TRUE(h.was_released());
  }
  clear_abort();
}

}  // namespace
}  // namespace cnc::commission
