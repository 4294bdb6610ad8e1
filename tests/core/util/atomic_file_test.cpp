#include <gtest/gtest.h>
#include <sys/stat.h>

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
