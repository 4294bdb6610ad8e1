// cnc-comp as a user runs it: measurement in; tables, exports, report and
// plot out; programs for the measurement cycle; errors that name the file
// and line; exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>

#include "comp/comp_table.hpp"
#include "core/util/atomic_file.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

namespace {

struct Output {
  int code;
  std::string text;
};

Output run(const std::string& args) {
  const std::string cmd = (cnc::testing::binary_dir() / "bin" / "cnc-comp").string() + " " + args + " 2>&1";
  std::string text;
  FILE* p = ::popen(cmd.c_str(), "r");
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), buf.size(), p)) text += buf.data();
  const int status = ::pclose(p);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text};
}

}  // namespace

TEST(CompTool, SynthFitWritesTablesExportsReportAndPlot) {
  cnc::testing::TempDir dir;
  const std::string d = dir.path().string();
  auto r = run("synth --out " + d + "/m.csv --periodic-out " + d + "/p.csv --seed 4");
  ASSERT_EQ(r.code, 0) << r.text;
  r = run("fit " + d + "/m.csv " + d + "/p.csv --out-dir " + d + "/out --lead 5 --axis X");
  ASSERT_EQ(r.code, 0) << r.text;
  for (const char* f : {"comp.txt", "linuxcnc.comp", "siemens_lec.spf", "X.COM", "fanuc_pitch.txt", "report.txt",
                        "iso230.png"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / ("out/" + std::string(f)))) << f;
  }
  const comp::CompTable t = comp::load_comp_file(dir / "out/comp.txt", comp::CompFileType::Trims);
  EXPECT_GT(t.size(), 256u) << "the runtime table is not limited to LinuxCNC's 256 entries";
  EXPECT_LE(comp::load_comp_file(dir / "out/linuxcnc.comp", comp::CompFileType::Trims).size(), 256u);
  const std::string report = read_file(dir / "out/report.txt");
  EXPECT_NE(report.find("periodic amplitude"), std::string::npos);
  EXPECT_NE(report.find("Predicted after compensation"), std::string::npos);
  EXPECT_NE(report.find("Referred to 20.0 C"), std::string::npos) << "the synthetic axis warms up";
  r = run("report " + d + "/m.csv --out " + d + "/r.txt --plot " + d + "/r.png");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_NE(read_file(dir / "r.txt").find("A  ="), std::string::npos);
  r = run("compare " + d + "/m.csv " + d + "/m.csv");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("A   accuracy"), std::string::npos);
}

TEST(CompTool, CycleWritesTheMeasurementPrograms) {
  cnc::testing::TempDir dir;
  const auto r = run("cycle --min 0 --max 280 --axis y --out " + (dir / "iso.ngc").string() + " --lead 5 --periodic-out " +
                     (dir / "per.ngc").string());
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_NE(read_file(dir / "iso.ngc").find("G53 G1 Y0.0000"), std::string::npos);
  EXPECT_NE(read_file(dir / "per.ngc").find("Annex C"), std::string::npos);
}

TEST(CompTool, ErrorsNameTheFileAndLineAndExitNonZero) {
  cnc::testing::TempDir dir;
  dir.write("bad.csv", "target,run,direction,deviation_um\n1,1,+,0\n1,1,?,0\n");
  auto r = run("report " + (dir / "bad.csv").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("bad.csv:3: direction: expected + or -"), std::string::npos) << r.text;
  r = run("fit " + (dir / "bad.csv").string());
  EXPECT_EQ(r.code, 2) << "usage: no --out-dir";
  r = run("fit x.csv --out-dir y --bogus 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.text.find("unknown option --bogus"), std::string::npos);
  r = run("load --joint 0 " + (dir / "bad.csv").string() + " -i no-such-instance-" + std::to_string(::getpid()));
  EXPECT_EQ(r.code, 1) << "no controller: " << r.text;
  EXPECT_EQ(run("frobnicate").code, 2);
}
