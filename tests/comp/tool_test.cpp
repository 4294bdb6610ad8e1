// cnc-comp as a user runs it: measurement in; tables, exports, report and
// plot out; programs for the measurement cycle; errors that name the file
// and line; exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <sstream>

#include "comp/comp_table.hpp"
#include "core/util/atomic_file.hpp"
#include "core/util/strings.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;

namespace {

using Output = cnc::testing::CommandOutput;

Output run(const std::string& args) {
  return cnc::testing::run_shell((cnc::testing::binary_dir() / "bin" / "cnc-comp").string() + " " + args);
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

namespace {

// The synthetic measurement with every deviation multiplied by `scale` and
// the axis renamed, keeping only the points moving `only` (0: all).
std::string transformed(const std::string& csv, double scale, const std::string& axis, int only = 0) {
  std::string out;
  std::istringstream in(csv);
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("# axis:", 0) == 0) {
      out += "# axis: " + axis + "\n";
      continue;
    }
    const auto cells = split(l, ',');
    if (l[0] == '#' || cells.size() < 4 || cells[0] == "target") {
      out += l + "\n";
      continue;
    }
    if (only != 0 && (cells[2] == "+") != (only > 0)) continue;
    std::string row;
    for (std::size_t k = 0; k < cells.size(); ++k) {
      row += (k ? "," : "") + (k == 3 ? format_double(std::stod(cells[k]) * scale) : cells[k]);
    }
    out += row + "\n";
  }
  return out;
}

}  // namespace

// Nanometres read as micrometres used to pass report and fit, and the
// exports carried 6 mm trims.
TEST(CompTool, DeviationsInNanometresAreRefusedByReportAndFitAndNothingIsWritten) {
  cnc::testing::TempDir dir;
  const std::string d = dir.path().string();
  ASSERT_EQ(run("synth --out " + d + "/m.csv --seed 4").code, 0);
  dir.write("nm.csv", transformed(read_file(dir / "m.csv"), 1000, "X"));
  auto r = run("report " + d + "/nm.csv");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.text.find("nm.csv:4: deviation_um: "), std::string::npos) << r.text;
  EXPECT_NE(r.text.find("are these nanometres?"), std::string::npos) << r.text;
  r = run("fit " + d + "/nm.csv --out-dir " + d + "/out");
  EXPECT_EQ(r.code, 1) << r.text;
  EXPECT_FALSE(std::filesystem::exists(dir / "out/comp.txt"));
  r = run("compare " + d + "/m.csv " + d + "/nm.csv");
  EXPECT_EQ(r.code, 1) << r.text;
  r = run("report " + d + "/nm.csv --max-deviation 100000");
  EXPECT_EQ(r.code, 0) << "raised knowingly: " << r.text;
  dir.write("huge.csv", "target,run,direction,deviation_um\n0,1,+,1e300\n0,2,+,-1e300\n0,1,-,0\n0,2,-,0\n");
  r = run("report " + d + "/huge.csv --max-deviation 1000000");
  EXPECT_EQ(r.code, 1) << "not A = inf with rc 0: " << r.text;
  EXPECT_EQ(run("report " + d + "/m.csv --max-deviation 0").code, 2);
}

TEST(CompTool, FanucTapeFollowsTheMeasuredAxisAndItsOptions) {
  cnc::testing::TempDir dir;
  const std::string d = dir.path().string();
  ASSERT_EQ(run("synth --out " + d + "/m.csv --seed 4").code, 0);
  dir.write("y.csv", transformed(read_file(dir / "m.csv"), 1, "Y"));
  auto r = run("fit " + d + "/y.csv --out-dir " + d + "/y --fanuc-unit 0.1 --fanuc-magnification 2");
  ASSERT_EQ(r.code, 0) << r.text;
  const std::string y = read_file(dir / "y/fanuc_pitch.txt");
  EXPECT_NE(y.find("N03620A2P256\n"), std::string::npos) << y.substr(0, 200);
  EXPECT_NE(y.find("N03623A2P2\n"), std::string::npos);
  EXPECT_EQ(y.find("A1P"), std::string::npos) << "nothing for axis 1 (X)";
  EXPECT_NE(r.text.find("Fanuc tape: axis 2, reference point 256 (3620)"), std::string::npos) << r.text;
  // An axis whose number the tool cannot know: no tape, and why.
  dir.write("a.csv", transformed(read_file(dir / "m.csv"), 1, "A"));
  r = run("fit " + d + "/a.csv --out-dir " + d + "/a");
  EXPECT_EQ(r.code, 0) << r.text;
  EXPECT_FALSE(std::filesystem::exists(dir / "a/fanuc_pitch.txt"));
  EXPECT_NE(r.text.find("fanuc_pitch.txt not written: Fanuc export: the controlled-axis number of axis A is not known"),
            std::string::npos)
      << r.text;
  r = run("fit " + d + "/a.csv --out-dir " + d + "/a --fanuc-axis 4 --fanuc-reference-point 800 --fanuc-unidirectional");
  ASSERT_EQ(r.code, 0) << r.text;
  const std::string a = read_file(dir / "a/fanuc_pitch.txt");
  EXPECT_NE(a.find("N03620A4P800\n"), std::string::npos) << a.substr(0, 200);
  EXPECT_EQ(a.find("N03605"), std::string::npos) << "unidirectional";
  EXPECT_EQ(run("fit " + d + "/a.csv --out-dir " + d + "/a --fanuc-magnification 0").code, 2);
  EXPECT_EQ(run("fit " + d + "/a.csv --out-dir " + d + "/a --fanuc-unit -1").code, 2);
}

TEST(CompTool, FitOfOneDirectionWarnsThatBacklashIsNotMeasured) {
  cnc::testing::TempDir dir;
  const std::string d = dir.path().string();
  ASSERT_EQ(run("synth --out " + d + "/m.csv --seed 4").code, 0);
  dir.write("up.csv", transformed(read_file(dir / "m.csv"), 1, "X", 1));
  const auto r = run("fit " + d + "/up.csv --out-dir " + d + "/out");
  ASSERT_EQ(r.code, 0) << r.text;
  EXPECT_NE(r.text.find("warning: no target was approached from both directions: backlash is not measured"),
            std::string::npos)
      << r.text;
  const comp::CompTable t = comp::load_comp_file(dir / "out/comp.txt", comp::CompFileType::Trims);
  for (std::size_t i = 0; i < t.size(); ++i) EXPECT_EQ(t.forward[i], t.reverse[i]) << i;
  EXPECT_NE(read_file(dir / "out/comp.txt").find("# backlash not measured"), std::string::npos);
}
