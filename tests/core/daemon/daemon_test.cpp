// The controller daemon as a user meets it: the cncd, cnc and halcmd
// programs of this build, run as separate processes.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <fstream>
#include <chrono>
#include <thread>

#include "core/ipc/client.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

namespace {

std::string bin(const std::string& name) { return (cnc::testing::binary_dir() / "bin" / name).string(); }

struct Output {
  int code;
  std::string text;
};

Output run(const std::string& command) {
  std::string text;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), buf.size(), p)) text += buf.data();
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text};
}

class Daemon {
 public:
  Daemon(const cnc::testing::TempDir& dir, const std::string& hal, const std::string& extra_ini = "")
      : instance_(cnc::testing::unique_name("d")) {
    dir.write("m.hal", hal);
    ini_ = dir.write("m.ini", "[EMC]\nMACHINE = test mill\n[EMCMOT]\nSERVO_PERIOD = 1000000\n[TASK]\nCYCLE_TIME = 0.002\n"
                              "[HAL]\nHALFILE = m.hal\n" + extra_ini);
    log_ = dir / "cncd.log";
    pid_ = ::fork();
    if (pid_ == 0) {
      std::freopen(log_.c_str(), "w", stderr);
      ::execl(bin("cncd").c_str(), "cncd", "--instance", instance_.c_str(), ini_.c_str(), nullptr);
      ::_exit(127);
    }
  }
  ~Daemon() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool wait_ready() { return run(cnc("wait-ready")).code == 0; }
  std::string cnc(const std::string& args) const { return bin("cnc") + " -i " + instance_ + " --timeout 10 " + args; }
  std::string halcmd(const std::string& args) const { return bin("halcmd") + " -i " + instance_ + " " + args; }
  // Waits for the process to end; returns its exit status.
  int wait_exit(int timeout_ms = 10000) {
    int status = 0;
    for (int i = 0; i < timeout_ms / 10; ++i) {
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return -1;
  }
  std::string log() const { return read_file(log_); }
  static std::string read_file(const std::filesystem::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  pid_t pid() const { return pid_; }
  const std::string& instance() const { return instance_; }

 private:
  std::string instance_;
  std::filesystem::path ini_, log_;
  pid_t pid_ = -1;
  bool exited_ = false;
};

const char* kBasicHal =
    "loadrt threads name1=servo-thread period1=[EMCMOT]SERVO_PERIOD\n"
    "loadrt siggen\nloadrt scale\n"
    "addf siggen.0 servo-thread\naddf scale.0 servo-thread\n"
    "net wave siggen.0.sine => scale.0.in\n";

}  // namespace

TEST(Daemon, StartsPublishesStatusAndStopsOnSigterm) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  {
    ipc::Client c(d.instance());
    const auto s1 = c.status();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const auto s2 = c.status();
    EXPECT_EQ(s1.health.pid, d.pid());
    EXPECT_GT(s2.health.heartbeat, s1.health.heartbeat);
    EXPECT_STREQ(s2.health.machine.c_str(), "test mill");
    EXPECT_STREQ(s2.threads[0].name.c_str(), "servo-thread");
    EXPECT_GT(s2.threads[0].cycles, s1.threads[0].cycles) << "the servo thread runs";
  }
  const auto st = run(d.cnc("status"));
  EXPECT_EQ(st.code, 0);
  EXPECT_NE(st.text.find("machine \"test mill\""), std::string::npos) << st.text;
  const auto js = run(d.cnc("status --json"));
  EXPECT_NE(js.text.find("\"machine\": \"test mill\""), std::string::npos) << js.text;
  ::kill(d.pid(), SIGTERM);
  EXPECT_EQ(d.wait_exit(), 0);
  EXPECT_NE(d.log().find("received SIGTERM, shutting down"), std::string::npos);
  const auto after = run(d.cnc("status"));
  EXPECT_EQ(after.code, 1);
  EXPECT_NE(after.text.find("controller not running"), std::string::npos) << after.text;
}

TEST(Daemon, SecondDaemonOnTheSameInstanceIsRefused) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  const auto second = run(bin("cncd") + " --instance " + d.instance() + " " + (dir / "m.ini").string());
  EXPECT_EQ(second.code, 1);
  EXPECT_NE(second.text.find("another controller is already running on instance"), std::string::npos) << second.text;
  // The first one is unharmed.
  EXPECT_EQ(run(d.cnc("ping")).code, 0);
}

TEST(Daemon, ShutdownCommandStopsItCleanly) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  EXPECT_EQ(run(d.cnc("shutdown")).code, 0);
  EXPECT_EQ(d.wait_exit(), 0);
  EXPECT_FALSE(std::filesystem::exists("/dev/shm/cnc-" + d.instance()));
  EXPECT_FALSE(std::filesystem::exists("/dev/shm/cnc-" + d.instance() + ".hal"));
}

TEST(Daemon, BadHalFileStopsStartupNamingFileAndLine) {
  cnc::testing::TempDir dir;
  Daemon d(dir, "loadrt threads name1=servo-thread period1=1000000\nnet x nosuch.pin\n");
  EXPECT_EQ(d.wait_exit(), 1);
  EXPECT_NE(d.log().find("m.hal:2: pin \"nosuch.pin\" does not exist"), std::string::npos) << d.log();
  EXPECT_FALSE(std::filesystem::exists("/dev/shm/cnc-" + d.instance()));
}

TEST(Daemon, BadIniValueStopsStartupNamingTheKey) {
  cnc::testing::TempDir dir;
  dir.write("m.hal", kBasicHal);
  const auto ini = dir.write("bad.ini", "[TASK]\nCYCLE_TIME = soon\n[HAL]\nHALFILE = m.hal\n");
  const auto r = run(bin("cncd") + " --instance " + cnc::testing::unique_name("bad") + " " + ini.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("bad.ini:2: [TASK]CYCLE_TIME: expected a number between 0.0001 and 1, got \"soon\""),
            std::string::npos) << r.text;
}

TEST(Daemon, UnhandledCommandsAreRejectedWithAReason) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  const auto r = run(d.cnc("home all"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("home rejected: no part of this controller handles 'home'"), std::string::npos) << r.text;
}

TEST(Daemon, OperatorMessagesReachEveryReader) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  ipc::Client reader(d.instance());
  EXPECT_EQ(run(d.cnc("error spindle belt broken")).code, 0);
  // Other parts may speak meanwhile (e.g. the servo thread reporting a late
  // spell on a loaded host): the operator's message is the one looked for.
  Message m;
  bool got = false;
  for (int i = 0; i < 200 && !got; ++i) {
    while (!got && reader.next_message(m)) got = m.source.view() == "operator";
    if (!got) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(got);
  EXPECT_EQ(m.kind, MessageKind::Error);
  EXPECT_EQ(m.text.view(), "spindle belt broken");
  const auto listed = run(d.cnc("messages"));
  EXPECT_NE(listed.text.find("error   [operator] spindle belt broken"), std::string::npos) << listed.text;
}

TEST(Halcmd, WorksAgainstALiveController) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  auto r = run(d.halcmd("show pin scale.0"));
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.text.find("scale.0.in <== wave"), std::string::npos) << r.text;
  EXPECT_EQ(run(d.halcmd("setp scale.0.gain 3")).code, 0);
  EXPECT_EQ(run(d.halcmd("getp scale.0.gain")).text, "3\n");
  EXPECT_EQ(run(d.halcmd("setp siggen.0.amplitude 0")).code, 0);
  EXPECT_EQ(run(d.halcmd("setp siggen.0.offset 2")).code, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(run(d.halcmd("getp scale.0.out")).text, "6\n") << "the servo thread computed 2 * 3";
  // Changing the graph while running.
  EXPECT_EQ(run(d.halcmd("loadrt not")).code, 0);
  EXPECT_EQ(run(d.halcmd("addf not.0 servo-thread")).code, 0);
  EXPECT_EQ(run(d.halcmd("net inverted not.0.out")).code, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(run(d.halcmd("gets inverted")).text, "TRUE\n");
  EXPECT_EQ(run(d.halcmd("delf not.0 servo-thread")).code, 0);
  r = run(d.halcmd("show thread"));
  EXPECT_EQ(r.text.find("not.0"), std::string::npos) << r.text;
  // Errors: non-zero exit and the reason.
  r = run(d.halcmd("setp scale.0.out 1"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("pin scale.0.out is an output"), std::string::npos);
  // Script mode names the file and line of an error.
  const auto script = dir.write("x.hal", "setp scale.0.offset 1\n# comment\nsetp nosuch 1\n");
  r = run(d.halcmd("-f " + script.string()));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("x.hal:3: pin or parameter \"nosuch\" does not exist"), std::string::npos) << r.text;
  EXPECT_EQ(run(d.halcmd("getp scale.0.offset")).text, "1\n");
}

TEST(Halcmd, SaysWhenTheControllerIsNotRunning) {
  const auto r = run(bin("halcmd") + " -i " + cnc::testing::unique_name("gone") + " show");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("controller not running"), std::string::npos) << r.text;
}
