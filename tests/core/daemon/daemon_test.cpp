// The controller daemon as a user meets it: the cncd, cnc and halcmd
// programs of this build, run as separate processes.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
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

using Output = cnc::testing::CommandOutput;
using cnc::testing::run_shell;
Output run(const std::string& command) { return run_shell(command); }

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
    "addf siggen.0.update servo-thread\naddf scale.0 servo-thread\n"
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

// Numbers that would wrap, overflow or mean nothing are refused by the CLI
// as typed, and by the controller whatever client sent them.
TEST(Daemon, OutOfRangeArgumentsAreRefusedByTheCliAndTheController) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  const auto wraps = run(d.cnc("home 4294967296"));  // used to home joint 0
  EXPECT_EQ(wraps.code, 2);
  EXPECT_NE(wraps.text.find("joint: 4294967296 is out of range (expected 0 to 15)"), std::string::npos) << wraps.text;
  const auto macro = run(d.cnc("macro 4294967297"));  // used to run macro 1
  EXPECT_EQ(macro.code, 2);
  EXPECT_NE(macro.text.find("macro: 4294967297 is out of range"), std::string::npos) << macro.text;
  const auto huge = run(d.cnc("spindle 1e308"));
  EXPECT_EQ(huge.code, 2);
  EXPECT_NE(huge.text.find("rpm: 1e308 is out of range"), std::string::npos) << huge.text;
  EXPECT_EQ(run(d.cnc("watch --count -5")).code, 2);
  const auto extra = run(d.cnc("estop-reset extra args"));
  EXPECT_EQ(extra.code, 2);
  EXPECT_NE(extra.text.find("estop-reset takes no arguments"), std::string::npos) << extra.text;
  EXPECT_EQ(run(d.cnc("jog x 10 1 2")).code, 2);

  // A client that is not the CLI: the controller checks before anyone acts.
  ipc::Client client(d.instance());
  ipc::Command spin = ipc::make_command(ipc::CommandType::SpindleOn);
  spin.d[0] = 1e308;
  auto r = client.execute(spin, std::chrono::seconds(5));
  EXPECT_EQ(r.state, ipc::CommandState::Rejected);
  EXPECT_EQ(r.reason.view(), "spindle-on: speed (rpm) 1e+308 is out of range (expected -1e+06 to 1e+06)");
  ipc::Command home = ipc::make_command(ipc::CommandType::JointHome);
  home.i[0] = 99;
  r = client.execute(home, std::chrono::seconds(5));
  EXPECT_EQ(r.state, ipc::CommandState::Rejected);
  EXPECT_NE(std::string(r.reason.view()).find("joint 99 is out of range"), std::string::npos) << r.reason.view();
}

// An INI that is empty, a directory or names nothing to run stops start-up
// with the reason instead of running a controller with nothing loaded.
TEST(Daemon, AnIniWithNothingToRunIsRefused) {
  cnc::testing::TempDir dir;
  const auto empty = dir.write("empty.ini", "");
  auto r = run(bin("cncd") + " --instance " + cnc::testing::unique_name("e") + " " + empty.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("empty.ini: no [HAL]HALFILE or [HAL]HALCMD: nothing to run"), std::string::npos) << r.text;
  r = run(bin("cncd") + " --instance " + cnc::testing::unique_name("e") + " " + dir.path().string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("cannot read INI file: is a directory, not a regular file"), std::string::npos) << r.text;
  dir.write("h.ini", "[HAL]\nHALFILE = /dev/zero\n");
  r = run(bin("cncd") + " --instance " + cnc::testing::unique_name("e") + " " + (dir / "h.ini").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("/dev/zero: cannot read HAL file: is a character device, not a regular file"), std::string::npos) << r.text;
}

// A misspelt key is reported with file, line and the key nearest in spelling
// that the controller reads, on the message channel; the controller runs.
TEST(Daemon, UnknownIniKeysAreReportedOnTheMessageChannelWithTheNearestKey) {
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal, "[TASK]\nCYCLE_TYME = 0.002\n[traj_notes]\nX = 1\n");
  ASSERT_TRUE(d.wait_ready()) << d.log();
  const auto listed = run(d.cnc("messages"));
  EXPECT_NE(listed.text.find("m.ini:10: [TASK]CYCLE_TYME: unknown key, ignored; did you mean [TASK]CYCLE_TIME?"),
            std::string::npos)
      << listed.text;
  EXPECT_EQ(listed.text.find("traj_notes"), std::string::npos) << "a section of the user's own is left alone";
}

namespace {
// The Daemon fixture's INI with `extra` appended, and cncd run on it to the end.
Output run_cncd(const cnc::testing::TempDir& dir, const std::string& options, const std::string& extra,
                const std::string& instance) {
  dir.write("m.hal", kBasicHal);
  const auto ini = dir.write("m.ini", "[EMC]\nMACHINE = test mill\n[EMCMOT]\nSERVO_PERIOD = 1000000\n[TASK]\n"
                                      "CYCLE_TIME = 0.002\n[HAL]\nHALFILE = m.hal\n" + extra);
  return run(bin("cncd") + " --instance " + instance + " " + options + " " + ini.string());
}
}  // namespace

TEST(Daemon, StrictRefusesToStartWithAnUnknownKey) {
  cnc::testing::TempDir dir;
  const std::string instance = cnc::testing::unique_name("s");
  const auto r = run_cncd(dir, "--strict", "[TASK]\nCYCLE_TYME = 0.002\n[JOINT_0]\nTYPE = LINEAR\n", instance);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("cncd: " + (dir / "m.ini").string() +
                        ":10: [TASK]CYCLE_TYME: unknown key, ignored; did you mean [TASK]CYCLE_TIME? (and 1 more, "
                        "listed above); unknown and unused keys are errors with cncd --strict"),
            std::string::npos)
      << r.text;
  EXPECT_NE(r.text.find("m.ini:11: [JOINT_0]: no loaded component reads this section"), std::string::npos) << r.text;
  EXPECT_FALSE(std::filesystem::exists("/dev/shm/cnc-" + instance));
}

TEST(Daemon, UnknownKeysErrorInTheIniRefusesToStart) {
  cnc::testing::TempDir dir;
  const auto r = run_cncd(dir, "", "[EMC]\nUNKNOWN_KEYS = ERROR\n[HAL]\nHALFILES = x.hal\n", cnc::testing::unique_name("s"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("m.ini:12: [HAL]HALFILES: unknown key, ignored; did you mean [HAL]HALFILE?; unknown and "
                        "unused keys are errors with [EMC]UNKNOWN_KEYS = ERROR"),
            std::string::npos)
      << r.text;
  const auto bad = run_cncd(dir, "", "[EMC]\nUNKNOWN_KEYS = MAYBE\n", cnc::testing::unique_name("s"));
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.text.find("m.ini:10: [EMC]UNKNOWN_KEYS: expected WARN or ERROR, got \"MAYBE\""), std::string::npos)
      << bad.text;
}

TEST(Daemon, ALowerCaseControllerSectionIsRefusedWithTheRightName) {
  cnc::testing::TempDir dir;
  const auto r = run_cncd(dir, "", "[traj]\nMAX_LINEAR_VELOCITY = 10\n", cnc::testing::unique_name("s"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("m.ini:9: [traj]: section names are case-sensitive; this controller (as LinuxCNC) reads "
                        "[TRAJ]"),
            std::string::npos)
      << r.text;
}

// --check loads everything and stops: no instance is used, so it runs beside
// a live controller of the same instance; a bad file fails it.
TEST(Daemon, CheckLoadsTheConfigurationWithoutRunningIt) {
  cnc::testing::TempDir dir;
  Daemon live(dir, kBasicHal);
  ASSERT_TRUE(live.wait_ready()) << live.log();
  auto r = run(bin("cncd") + " --check --instance " + live.instance() + " " + (dir / "m.ini").string());
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("cncd: " + (dir / "m.ini").string() + " loads"), std::string::npos) << r.text;
  EXPECT_EQ(run(live.cnc("ping")).code, 0) << "the live controller is unharmed";
  cnc::testing::TempDir other;
  const std::string instance = cnc::testing::unique_name("c");
  r = run_cncd(other, "--check", "[HAL]\nHALCMD = net x nosuch.pin\n", instance);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("m.ini:10: [HAL]HALCMD: "), std::string::npos) << r.text;
  EXPECT_FALSE(std::filesystem::exists("/dev/shm/cnc-" + instance));
}

// The local security model (docs/security.md): only the controller's user
// (and root) may command it; another user's files where the lock belongs
// neither redirect nor block the controller. These run only as root, which
// can act as another user (runuser); otherwise they are skipped.
namespace {
bool can_switch_user() { return ::geteuid() == 0 && ::access("/usr/sbin/runuser", X_OK) == 0; }
std::string as_nobody(const std::string& command) { return "/usr/sbin/runuser -u nobody -- " + command; }
}  // namespace

TEST(Security, OtherUsersCannotCommandTheController) {
  if (!can_switch_user()) GTEST_SKIP() << "needs root and runuser";
  cnc::testing::TempDir dir;
  Daemon d(dir, kBasicHal);
  ASSERT_TRUE(d.wait_ready()) << d.log();
  struct stat st {};
  ASSERT_EQ(::stat(("/dev/shm/cnc-" + d.instance()).c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u) << "the segment is the owner's alone without [EMC]OPERATOR_GROUP";
  ASSERT_EQ(::stat(("/dev/shm/cnc-" + d.instance() + ".hal").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  const auto shell = run(as_nobody(d.halcmd("loadusr -w /bin/sh -c id")));
  EXPECT_NE(shell.code, 0);
  EXPECT_EQ(shell.text.find("uid=0"), std::string::npos) << shell.text;
  const auto status = run(as_nobody(d.cnc("estop-reset")));
  EXPECT_NE(status.code, 0) << status.text;
  // The controller's own user cannot start a shell through halcmd either.
  const auto own = run(d.halcmd("loadusr -w /bin/sh -c id"));
  EXPECT_NE(own.code, 0);
  EXPECT_NE(own.text.find("outside the allowed folders"), std::string::npos) << own.text;
  // halcmd reads a sourced file itself: what its user cannot read, it cannot show.
  const auto shadow = run(as_nobody(d.halcmd("source /etc/shadow")));
  EXPECT_NE(shadow.code, 0);
  EXPECT_EQ(shadow.text.find("root:"), std::string::npos) << shadow.text;
}

TEST(Security, AnotherUsersFileWhereTheLockBelongsIsRemovedByRoot) {
  if (!can_switch_user()) GTEST_SKIP() << "needs root and runuser";
  cnc::testing::TempDir dir;
  const std::string instance = cnc::testing::unique_name("sq");
  const std::string lock = "/dev/shm/cnc-" + instance + ".lock";
  const auto target = dir / "victim";
  // A symbolic link planted by another user must not make root create or
  // truncate the file it points to.
  ASSERT_EQ(::symlink(target.c_str(), lock.c_str()), 0);
  ASSERT_EQ(::lchown(lock.c_str(), 65534, 65534), 0);
  dir.write("m.hal", kBasicHal);
  const auto ini = dir.write("m.ini", "[EMCMOT]\nSERVO_PERIOD = 1000000\n[HAL]\nHALFILE = m.hal\n");
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen((dir / "log").c_str(), "w", stderr);
    ::execl(bin("cncd").c_str(), "cncd", "--instance", instance.c_str(), ini.c_str(), nullptr);
    ::_exit(127);
  }
  const auto ready = run(bin("cnc") + " -i " + instance + " --timeout 10 wait-ready");
  EXPECT_EQ(ready.code, 0) << ready.text << Daemon::read_file(dir / "log");
  EXPECT_FALSE(std::filesystem::exists(target)) << "root followed the planted link";
  struct stat st {};
  ASSERT_EQ(::lstat(lock.c_str(), &st), 0);
  EXPECT_TRUE(S_ISREG(st.st_mode));
  EXPECT_EQ(st.st_uid, 0u);
  run(bin("cnc") + " -i " + instance + " shutdown");
  int status = 0;
  ::waitpid(pid, &status, 0);
}

TEST(Security, AnotherUsersLockIsNamedWhenItCannotBeRemoved) {
  if (!can_switch_user()) GTEST_SKIP() << "needs root and runuser";
  cnc::testing::TempDir dir;
  std::filesystem::permissions(dir.path(), std::filesystem::perms::all);
  const std::string instance = cnc::testing::unique_name("sq");
  const std::string lock = "/dev/shm/cnc-" + instance + ".lock";
  { std::ofstream(lock) << ""; }  // root's file: nobody's controller may not use it
  dir.write("m.hal", kBasicHal);
  const auto ini = dir.write("m.ini", "[EMCMOT]\nSERVO_PERIOD = 1000000\n[HAL]\nHALFILE = m.hal\n");
  std::filesystem::permissions(dir / "m.hal", std::filesystem::perms::all);
  std::filesystem::permissions(ini, std::filesystem::perms::all);
  const auto r = run(as_nobody(bin("cncd") + " --instance " + instance + " " + ini.string()));
  ::unlink(lock.c_str());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("it is a file of root (uid 0), not of this user; only that user or root can remove it"),
            std::string::npos) << r.text;
}

// `cnc wait-ready` says at once that a controller it saw starting died
// before it was ready, instead of waiting its whole timeout.
TEST(Daemon, WaitReadySaysWhenTheControllerDiesDuringStartup) {
  cnc::testing::TempDir dir;
  const auto slow = dir.write("slow.sh", "#!/bin/sh\nsleep 1.5\n");
  std::filesystem::permissions(slow, std::filesystem::perms::owner_all);
  Daemon d(dir, "loadrt threads name1=servo-thread period1=1000000\nloadusr -w slow.sh\nnet x nosuch.pin\n");
  const auto r = run(bin("cnc") + " -i " + d.instance() + " --timeout 30 wait-ready");
  EXPECT_EQ(r.code, 1);
  // Not "not ready after 30 s": it saw the controller go.
  EXPECT_NE(r.text.find("stopped during start-up, before it was ready"), std::string::npos) << r.text;
  EXPECT_EQ(d.wait_exit(), 1);
}

// [HAL]HALUI = halui loads the halui component after the HAL files (as
// LinuxCNC's launcher starts halui); other values, or halui loaded twice,
// stop the start naming the key.
TEST(Daemon, HalHaluiKeyLoadsHaluiAndOtherValuesAreRefused) {
  cnc::testing::TempDir dir;
  auto r = run_cncd(dir, "--check --strict", "HALUI = halui\n", cnc::testing::unique_name("hu"));
  EXPECT_EQ(r.code, 0) << r.text;
  r = run_cncd(dir, "--check", "HALUI = axisui\n", cnc::testing::unique_name("hu"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("m.ini:9: [HAL]HALUI = axisui: only halui"), std::string::npos) << r.text;
  r = run_cncd(dir, "--check", "HALUI = halui\nHALCMD = loadrt halui\n", cnc::testing::unique_name("hu"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("m.ini:9: [HAL]HALUI = halui, and a HAL file or [HAL]HALCMD loads halui too"), std::string::npos) << r.text;
}
