#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/util/atomic_file.hpp"
#include "tests/support/testing.hpp"

TEST(AtomicFile, ReplacesContentAndKeepsMode) {
  cnc::testing::TempDir dir;
  const auto p = dir.write("table.tbl", "old\n");
  ::chmod(p.c_str(), 0640);
  cnc::write_file_atomically(p, "new content\n");
  EXPECT_EQ(cnc::read_file(p), "new content\n");
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  // No temporary files are left behind.
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) { (void)e; ++files; }
  EXPECT_EQ(files, 1);
}

TEST(AtomicFile, FailureNamesThePath) {
  try {
    cnc::write_file_atomically("/nonexistent-dir/x.txt", "x");
    FAIL() << "expected an exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.txt"), std::string::npos);
  }
}

// Configuration and table readers see only regular files: a directory, a
// FIFO (which would block for a writer) or a device such as /dev/zero
// (endless) is refused at once with the reason.
TEST(ReadFile, OnlyRegularFilesAreRead) {
  cnc::testing::TempDir dir;
  auto reason = [](const std::filesystem::path& p) {
    try {
      cnc::read_file(p);
    } catch (const cnc::FileError& e) {
      return e.reason();
    }
    return std::string("(read)");
  };
  EXPECT_EQ(reason(dir.path()), "is a directory, not a regular file");
  const auto fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(reason(fifo), "is a FIFO (named pipe), not a regular file");
  EXPECT_EQ(reason("/dev/zero"), "is a character device, not a regular file");
  EXPECT_EQ(reason(dir / "missing"), "cannot open: No such file or directory");
  EXPECT_EQ(cnc::read_file(dir.write("ok.txt", "text\n")), "text\n");
}

TEST(ReadFile, AFileLargerThanTheLimitIsRefused) {
  cnc::testing::TempDir dir;
  const auto p = dir.write("big.txt", std::string(3000, 'x'));
  EXPECT_THROW(cnc::read_file(p, 2048), cnc::FileError);
  EXPECT_EQ(cnc::read_file(p, 4096).size(), 3000u);
}

TEST(ReadFile, NoFollowRefusesASymbolicLink) {
  cnc::testing::TempDir dir;
  const auto target = dir.write("target.txt", "x");
  std::filesystem::create_symlink(target, dir / "link");
  EXPECT_THROW(::close(cnc::open_regular_file(dir / "link", true)), cnc::FileError);
  const int fd = cnc::open_regular_file(dir / "link");
  EXPECT_GE(fd, 0);
  ::close(fd);
}
