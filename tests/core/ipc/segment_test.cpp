#include <gtest/gtest.h>
#include <grp.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/ipc/client.hpp"
#include "core/ipc/server.hpp"
#include "tests/support/testing.hpp"

using namespace cnc::ipc;

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(Segment, InstanceNamesAreChecked) {
  EXPECT_NO_THROW(validate_instance_name("mill-2_a"));
  EXPECT_THROW(validate_instance_name(""), std::invalid_argument);
  EXPECT_THROW(validate_instance_name("a/b"), std::invalid_argument);
  EXPECT_THROW(validate_instance_name(std::string(49, 'a')), std::invalid_argument);
}

TEST(Segment, ClientWithoutControllerSeesNotRunning) {
  const auto inst = cnc::testing::unique_name("none");
  EXPECT_EQ(error_of([&] { Client c(inst); }), "controller not running (instance \"" + inst + "\")");
}

// The owner's alone by default; group-readable and -writable, owned by the
// group, with a trusted group (docs/security.md).
TEST(Segment, SegmentIsCreatedForItsOwnerOrTheTrustedGroupAndRemovedOnExit) {
  const auto inst = cnc::testing::unique_name("mode");
  {
    ::umask(022);
    Server s(inst);
    struct stat st {};
    ASSERT_EQ(::stat(("/dev/shm/cnc-" + inst).c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0600u);
    Client c(inst);
    EXPECT_TRUE(c.controller_alive());
  }
  struct stat st {};
  EXPECT_NE(::stat(("/dev/shm/cnc-" + inst).c_str(), &st), 0);
  EXPECT_NE(::stat(lock_path(inst).c_str(), &st), 0);
  {
    // A group the current user belongs to: its primary group.
    ::group* g = ::getgrgid(::getegid());
    ASSERT_NE(g, nullptr);
    Server s(inst, cnc::ipc::AccessPolicy::for_current_user(g->gr_name));
    ASSERT_EQ(::stat(("/dev/shm/cnc-" + inst).c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0660u);
    EXPECT_EQ(st.st_gid, ::getegid());
  }
  EXPECT_THROW(cnc::ipc::AccessPolicy::for_current_user("no-such-group-here"), std::runtime_error);
}

TEST(Segment, SecondControllerOnTheSameInstanceIsRefused) {
  const auto inst = cnc::testing::unique_name("dup");
  Server first(inst);
  EXPECT_EQ(error_of([&] { Server second(inst); }),
            "another controller is already running on instance \"" + inst + "\" (lock " + lock_path(inst) + " is held)");
}

TEST(Segment, StaleSegmentOfACrashedControllerIsDetectedAndReplaced) {
  const auto inst = cnc::testing::unique_name("stale");
  const pid_t pid = ::fork();
  if (pid == 0) {
    auto* s = new Server(inst);  // never destroyed: a crash
    s->set_ready(true);
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  const std::string err = error_of([&] { Client c(inst); });
  EXPECT_NE(err.find("is gone and left a stale segment"), std::string::npos) << err;
  // A new controller takes over the instance.
  Server fresh(inst);
  Client c(inst);
  EXPECT_TRUE(c.controller_alive());
}

TEST(Segment, ClientOfAnotherLayoutVersionIsRefused) {
  const auto inst = cnc::testing::unique_name("ver");
  const int fd = ::shm_open(shm_name(inst).c_str(), O_RDWR | O_CREAT | O_EXCL, 0660);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, 4096), 0);
  auto* h = static_cast<SegmentHeader*>(::mmap(nullptr, 4096, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0));
  new (h) SegmentHeader();
  h->magic = kSegmentMagic;
  h->layout_version = kLayoutVersion + 7;
  const std::string err = error_of([&] { Client c(inst); });
  ::munmap(h, 4096);
  ::close(fd);
  ::shm_unlink(shm_name(inst).c_str());
  EXPECT_NE(err.find("uses shared-segment layout version " + std::to_string(kLayoutVersion + 7)), std::string::npos) << err;
  EXPECT_NE(err.find("this client expects version " + std::to_string(kLayoutVersion)), std::string::npos) << err;
}

TEST(Segment, StatusIsNeverTornAcrossProcesses) {
  const auto inst = cnc::testing::unique_name("torn");
  Server server(inst);
  server.set_ready(true);
  Client client(inst);
  const pid_t reader = ::fork();
  if (reader == 0) {
    // Child: reads while the parent writes.
    Client c(inst);
    int torn = 0;
    for (int i = 0; i < 20000; ++i) {
      const Status s = c.status();
      for (const JointStatus& j : s.joints) torn += j.pos_cmd != s.joints[0].pos_cmd ? 1 : 0;
      torn += s.motion.position[0] != s.joints[0].pos_cmd ? 1 : 0;
    }
    ::_exit(torn == 0 ? 0 : 1);
  }
  auto st = std::make_unique<Status>();
  int status = 0;
  for (double v = 0; ::waitpid(reader, &status, WNOHANG) == 0; v += 1) {
    for (JointStatus& j : st->joints) j.pos_cmd = v;
    st->motion.position[0] = v;
    server.publish(*st);
  }
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the reader saw a torn status block";
}
