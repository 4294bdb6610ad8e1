// Golden tests: every program of data/programs and data/errors run through
// the rs274-compatible runner must print exactly what LinuxCNC 2.9's rs274
// printed (data/golden/, see data/regenerate.sh); data/own/ holds programs
// whose output deliberately differs from LinuxCNC.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "core/interp/rs274_run.hpp"
#include "tests/support/testing.hpp"

namespace fs = std::filesystem;
using cnc::interp::Rs274Options;

namespace {

fs::path data_dir() { return cnc::testing::source_dir() / "tests/core/interp/data"; }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Result {
  std::string canon;
  std::string err;
};

Result run(const fs::path& program) {
  // Per-program options (own/*.args): "-r" and "-t table" as cnc-rs274 takes.
  fs::path table = data_dir() / "tool.tbl";
  bool random = false;
  const fs::path args = fs::path(program).replace_extension(".args");
  if (fs::exists(args)) {
    std::istringstream in(slurp(args));
    std::string word;
    while (in >> word) {
      if (word == "-r") random = true;
      if (word == "-t" && in >> word) table = program.parent_path() / word;
    }
  }
  char* buf = nullptr;
  std::size_t size = 0;
  std::FILE* mem = open_memstream(&buf, &size);
  char* ebuf = nullptr;
  std::size_t esize = 0;
  std::FILE* emem = open_memstream(&ebuf, &esize);
  // rs274 is run inside the program's folder with a relative name; so are we
  // (messages show the name as given).
  const fs::path back = fs::current_path();
  fs::current_path(program.parent_path());
  Rs274Options o;
  o.program = program.filename();
  o.tool_table = table;
  o.random_toolchanger = random;
  std::string error;
  cnc::interp::run_rs274(o, mem, error, emem);
  fs::current_path(back);
  std::fclose(mem);
  std::fclose(emem);
  Result r{std::string(buf, size), std::string(ebuf, esize)};
  std::free(buf);
  std::free(ebuf);
  return r;
}

// First differing line, for a readable failure.
std::string first_difference(const std::string& want, const std::string& got) {
  std::istringstream a(want), b(got);
  std::string la, lb;
  for (int n = 1;; ++n) {
    const bool ha = static_cast<bool>(std::getline(a, la));
    const bool hb = static_cast<bool>(std::getline(b, lb));
    if (!ha && !hb) return "(same)";
    if (!ha || !hb || la != lb) return "line " + std::to_string(n) + ":\n  want: " + (ha ? la : "<end>") + "\n  got:  " + (hb ? lb : "<end>");
  }
}

void check_dir(const std::string& dir, const fs::path& golden_dir, const std::set<std::string>& canon_may_differ) {
  int count = 0;
  for (const auto& e : fs::directory_iterator(data_dir() / dir)) {
    if (e.path().extension() != ".ngc" || e.path().stem() == "filesub") continue;
    const std::string name = e.path().stem().string();
    SCOPED_TRACE(dir + "/" + name);
    const fs::path want_canon = golden_dir / (name + ".canon");
    ASSERT_TRUE(fs::exists(want_canon)) << "no golden file " << want_canon << ": run data/regenerate.sh";
    const Result r = run(e.path());
    if (!canon_may_differ.count(name)) {
      const std::string want = slurp(want_canon);
      EXPECT_EQ(want, r.canon) << first_difference(want, r.canon);
    }
    EXPECT_EQ(slurp(golden_dir / (name + ".err")), r.err);
    ++count;
  }
  EXPECT_GT(count, 0);
}

}  // namespace

TEST(InterpGolden, ProgramsMatchLinuxCncRs274) { check_dir("programs", data_dir() / "golden/programs", {}); }

// Error cases: message and line as rs274 prints them, and every call made
// before the error.
TEST(InterpGolden, ErrorsMatchLinuxCncRs274) { check_dir("errors", data_dir() / "golden/errors", {}); }

// The parameter file LinuxCNC's rs274 -v leaves behind after params.ngc.
TEST(InterpGolden, ParameterFileMatchesLinuxCncRs274) {
  cnc::testing::TempDir dir;
  const fs::path var = dir / "p.var";
  fs::copy_file(data_dir() / "params/start.var", var);
  const fs::path back = fs::current_path();
  fs::current_path(data_dir() / "params");
  Rs274Options o;
  o.program = "params.ngc";
  o.parameter_file = var;
  std::string error;
  const bool ok = cnc::interp::run_rs274(o, nullptr, error);
  fs::current_path(back);
  ASSERT_TRUE(ok) << error;
  const std::string want = slurp(data_dir() / "golden/params/expected.var");
  const std::string got = slurp(var);
  EXPECT_EQ(want, got) << first_difference(want, got);
}

TEST(InterpGolden, DeliberateDifferencesAreStable) { check_dir("own", data_dir() / "own", {}); }

// cnc-rs274 names the file and line of an error (of the program, or of the
// parameter file); as `rs274` it prints exactly what LinuxCNC's does.
TEST(InterpTool, ErrorsNameTheFileAndLineUnlessInRs274Format) {
  cnc::testing::TempDir dir;
  Rs274Options o;
  o.program = dir.write("bad.ngc", "G0 X1\nG1 X2 Y\n");
  o.rs274_error_format = false;
  std::string error;
  EXPECT_FALSE(cnc::interp::run_rs274(o, nullptr, error));
  EXPECT_EQ(error, o.program.string() + ":2: No characters found in reading real value\nG1 X2 Y");
  o.rs274_error_format = true;
  EXPECT_FALSE(cnc::interp::run_rs274(o, nullptr, error));
  EXPECT_EQ(error, "No characters found in reading real value\nG1 X2 Y");
  o.rs274_error_format = false;
  o.program = dir.write("ok.ngc", "G0 X1\n");
  o.parameter_file = dir.write("bad.var", "5221 1\n5220 abc\n");
  try {
    cnc::interp::run_rs274(o, nullptr, error);
    EXPECT_EQ(error.substr(0, o.parameter_file.string().size() + 3), o.parameter_file.string() + ":2:") << error;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "thrown: " << e.what();
  }
}
