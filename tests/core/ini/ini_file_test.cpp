#include <gtest/gtest.h>

#include "core/ini/ini_file.hpp"
#include "tests/support/testing.hpp"

using cnc::ConfigError;
using cnc::ini::IniFile;

namespace {
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}
}  // namespace

TEST(IniFile, SectionsKeysAndComments) {
  const auto ini = IniFile::parse(
      "# comment\n; another\n[EMC]\nMACHINE = My Mill  \n\n[TRAJ]\nCOORDINATES=X Y Z\nLINEAR_UNITS = mm\n", "t.ini");
  EXPECT_EQ(ini.find("EMC", "MACHINE"), "My Mill");
  EXPECT_EQ(ini.find("TRAJ", "COORDINATES"), "X Y Z");
  EXPECT_FALSE(ini.find("TRAJ", "MISSING"));
  EXPECT_FALSE(ini.find("traj", "COORDINATES")) << "sections are case-sensitive";
  EXPECT_EQ(ini.sections(), (std::vector<std::string>{"EMC", "TRAJ"}));
}

TEST(IniFile, RepeatedKeysKeepOrderAndFirstWinsForScalars) {
  const auto ini = IniFile::parse("[HAL]\nHALFILE = a.hal\nHALFILE = b.hal\nHALFILE = c.hal\n", "t.ini");
  EXPECT_EQ(ini.find_all("HAL", "HALFILE"), (std::vector<std::string>{"a.hal", "b.hal", "c.hal"}));
  EXPECT_EQ(ini.find("HAL", "HALFILE"), "a.hal");
}

// LinuxCNC keeps a trailing comment in the value; here it is refused, never
// silently part of a number, a file name or a drive name.
TEST(IniFile, ACommentAfterAValueIsRefusedNamingFileAndLine) {
  EXPECT_EQ(error_of([] { IniFile::parse("[CANOPEN]\nNODE = 1\nBITRATE = 1000000   # every device\n", "t.ini"); }),
            "t.ini:3: [CANOPEN]BITRATE: \"1000000   # every device\" has a comment after the value (\"# every "
            "device\"), which LinuxCNC keeps as part of the value: put the comment on a line of its own (\\x23 "
            "writes a '#' that belongs to the value)");
  EXPECT_NE(error_of([] { IniFile::parse("[X]\nA = 5 ; not a value\n", "t.ini"); }).find("t.ini:2: [X]A: "),
            std::string::npos);
  EXPECT_NE(error_of([] { IniFile::parse("[X]\nA = drives/x.eds\t#vendor\n", "t.ini"); }).find("t.ini:2: [X]A: "),
            std::string::npos);
  EXPECT_NE(error_of([] { IniFile::parse("[X]\nA = 5 #\n", "t.ini"); }).find("t.ini:2: [X]A: "), std::string::npos);
}

TEST(IniFile, GcodeParametersAndMarksWithoutABlankStayInTheValue) {
  const auto ini = IniFile::parse(
      "[X]\nA = G0 X #1 Y #<_y> Z #[1 + 2]\nB = G0 Z0;G0 X1\nC = a#b\nD = 5 \\x23 five\n", "t.ini");
  EXPECT_EQ(ini.find("X", "A"), "G0 X #1 Y #<_y> Z #[1 + 2]");
  EXPECT_EQ(ini.find("X", "B"), "G0 Z0;G0 X1");
  EXPECT_EQ(ini.find("X", "C"), "a#b");
  EXPECT_EQ(ini.find("X", "D"), "5 # five");
}

TEST(IniFile, ACommentAfterASectionHeaderIsRefusedWithTheReason) {
  EXPECT_EQ(error_of([] { IniFile::parse("[JOINT_1]   # Y, left motor\nA = 1\n", "t.ini"); }),
            "t.ini:1: a comment after the section header [JOINT_1]: put the comment on a line of its own");
  EXPECT_EQ(error_of([] { IniFile::parse("[A] b\n", "t.ini"); }), "t.ini:1: text after section header");
}

TEST(IniFile, NothingIsRecordedUnlessAsked) {
  const auto ini = IniFile::parse("[X]\nA = 1\n", "t.ini");
  EXPECT_EQ(ini.get_int("X", "A", 0), 1);
  EXPECT_EQ(ini.unread_entries().size(), 1u) << "recording is off by default";
  EXPECT_FALSE(ini.section_asked("X"));
}

TEST(IniFile, LookupsAreRecordedWhileRecordingIsOn) {
  auto ini = IniFile::parse("[X]\nA = 1\nB = 2\nL = a\nL = b\n[Y]\nC = 3\n[Z]\nD = 4\n", "t.ini");
  ini.record_reads(true);
  EXPECT_EQ(ini.get_int("X", "A", 0), 1);
  EXPECT_EQ(ini.get_int("X", "MISSING", 7), 7);
  EXPECT_EQ(ini.find_all("X", "L").size(), 2u);
  EXPECT_EQ(ini.section_entries("Y").size(), 1u);
  ini.record_reads(false);
  EXPECT_EQ(ini.get_int("Z", "D", 0), 4) << "not recorded any more";
  std::vector<std::string> unread;
  for (const auto* e : ini.unread_entries()) unread.push_back(e->section + "." + e->key);
  EXPECT_EQ(unread, (std::vector<std::string>{"X.B", "Z.D"}));
  EXPECT_EQ(ini.keys_asked("X"), (std::vector<std::string>{"A", "L", "MISSING"}));
  EXPECT_TRUE(ini.section_asked("Y"));
  EXPECT_FALSE(ini.section_asked("Z"));
}

TEST(IniFile, SectionHeadersAreLocated) {
  const auto ini = IniFile::parse("# x\n[A]\nK = 1\n\n[B]\n[A]\nL = 2\n", "t.ini");
  ASSERT_NE(ini.section_header("B"), nullptr);
  EXPECT_EQ(ini.section_header("A")->line, 2);
  EXPECT_EQ(ini.section_header("B")->line, 5);
  EXPECT_EQ(ini.section_header("C"), nullptr);
}

TEST(IniFile, NearestNameFindsTyposSwapsAndCase) {
  const std::vector<std::string> keys = {"MAX_VELOCITY", "MAX_ACCELERATION", "MIN_LIMIT", "MAX_LIMIT", "HOME_OFFSET",
                                         "TYPE"};
  EXPECT_EQ(cnc::ini::nearest_name("MAX_VELOCTY", keys), "MAX_VELOCITY");
  EXPECT_EQ(cnc::ini::nearest_name("MAX_VLEOCITY", keys), "MAX_VELOCITY");
  EXPECT_EQ(cnc::ini::nearest_name("max_velocity", keys), "MAX_VELOCITY");
  EXPECT_EQ(cnc::ini::nearest_name("TYP", keys), "TYPE");
  EXPECT_EQ(cnc::ini::nearest_name("ACCELERATION", keys), "MAX_ACCELERATION") << "contained in a known key";
  EXPECT_EQ(cnc::ini::nearest_name("REVERSE", keys), std::nullopt);
  EXPECT_EQ(cnc::ini::name_distance("ab", "ba"), 1u);
  EXPECT_EQ(cnc::ini::name_distance("", "abc"), 3u);
}

TEST(IniFile, ContinuationAndEscapes) {
  const auto ini = IniFile::parse("[MDI_COMMAND_LIST]\nMDI_COMMAND_MACRO0 = G0 Z25;X0 Y0, Go\\nHome\nK = a \\\n  b\n", "t.ini");
  EXPECT_EQ(ini.find("MDI_COMMAND_LIST", "MDI_COMMAND_MACRO0"), "G0 Z25;X0 Y0, Go\nHome");
  EXPECT_EQ(ini.find("MDI_COMMAND_LIST", "K"), "a b");
  const auto esc = IniFile::parse("[X]\nT = a\\tb\\x41\\u00e9\n", "t.ini");
  EXPECT_EQ(esc.find("X", "T"), "a\tbA\xc3\xa9");
}

TEST(IniFile, IncludeResolvesRelativeToIncludingFile) {
  cnc::testing::TempDir dir;
  dir.write("sub/axes.inc", "[AXIS_X]\nMAX_VELOCITY = 50\n");
  const auto main = dir.write("mill.ini", "[EMC]\nMACHINE = m\n#INCLUDE sub/axes.inc\n[TRAJ]\nX = 1\n");
  const auto ini = IniFile::load(main);
  EXPECT_EQ(ini.find("AXIS_X", "MAX_VELOCITY"), "50");
  EXPECT_EQ(ini.find("TRAJ", "X"), "1");
  EXPECT_EQ(ini.find_entry("AXIS_X", "MAX_VELOCITY")->file, (dir.path() / "sub/axes.inc").string());
  EXPECT_EQ(ini.find_entry("AXIS_X", "MAX_VELOCITY")->line, 2);
}

TEST(IniFile, IncludeCycleIsAnError) {
  cnc::testing::TempDir dir;
  dir.write("a.inc", "#INCLUDE b.inc\n");
  dir.write("b.inc", "#INCLUDE a.inc\n");
  const auto main = dir.write("m.ini", "#INCLUDE a.inc\n");
  EXPECT_NE(error_of([&] { IniFile::load(main); }).find("nested deeper"), std::string::npos);
}

TEST(IniFile, TypedGettersWithDefaultsAndRanges) {
  const auto ini = IniFile::parse(
      "[EMCMOT]\nSERVO_PERIOD = 1000000\n[JOINT_0]\nMAX_VELOCITY = 166.7\nHOME_USE_INDEX = YES\nADDR = 0x10\n", "m.ini");
  EXPECT_EQ(ini.get_int("EMCMOT", "SERVO_PERIOD", 0, {1, 1e9}), 1000000);
  EXPECT_DOUBLE_EQ(ini.get_double("JOINT_0", "MAX_VELOCITY", 0), 166.7);
  EXPECT_DOUBLE_EQ(ini.get_double("JOINT_0", "MAX_ACCELERATION", 750.0), 750.0);
  EXPECT_TRUE(ini.get_bool("JOINT_0", "HOME_USE_INDEX", false));
  EXPECT_EQ(ini.get_int("JOINT_0", "ADDR", 0), 16);
}

TEST(IniFile, BadValueNamesFileLineAndKey) {
  const auto ini = IniFile::parse("[EMC]\nX=1\n[JOINT_2]\nMAX_VELOCITY = fast\nFERROR = -1\n", "mill.ini");
  EXPECT_EQ(error_of([&] { ini.get_double("JOINT_2", "MAX_VELOCITY", 0); }),
            "mill.ini:4: [JOINT_2]MAX_VELOCITY: expected a number, got \"fast\"");
  EXPECT_EQ(error_of([&] { ini.get_double("JOINT_2", "FERROR", 1, {0, 1000}); }),
            "mill.ini:5: [JOINT_2]FERROR: expected a number between 0 and 1000, got \"-1\"");
  EXPECT_EQ(error_of([&] { ini.require_double("JOINT_2", "MAX_ACCELERATION", {0, 1e6}); }),
            "mill.ini: [JOINT_2]MAX_ACCELERATION: missing, expected a number between 0 and 1000000");
}

TEST(IniFile, SyntaxErrorsNameTheLine) {
  EXPECT_EQ(error_of([] { IniFile::parse("[EMC]\nthis is not a key\n", "bad.ini"); }),
            "bad.ini:2: expected KEY = value, a [SECTION] header or a comment");
  EXPECT_EQ(error_of([] { IniFile::parse("[EMC\n", "bad.ini"); }), "bad.ini:1: section header without ']'");
  EXPECT_EQ(error_of([] { IniFile::parse("KEY = 1\n", "bad.ini"); }), "bad.ini:1: key KEY before any [SECTION]");
  EXPECT_NE(error_of([] { IniFile::parse("[A]\n9KEY = 1\n", "bad.ini"); }).find("bad.ini:2: key \"9KEY\""),
            std::string::npos);
}

TEST(IniFile, MissingFileIsAClearError) {
  EXPECT_EQ(error_of([] { IniFile::load("/nonexistent/mill.ini"); }), "/nonexistent/mill.ini: cannot read INI file: cannot open: No such file or directory");
}

TEST(IniFile, ResolvePathIsRelativeToTheIniFolder) {
  cnc::testing::TempDir dir;
  const auto p = dir.write("cfg/mill.ini", "[EMCIO]\nTOOL_TABLE = tool.tbl\n");
  const auto ini = IniFile::load(p);
  EXPECT_EQ(ini.resolve_path(*ini.find("EMCIO", "TOOL_TABLE")), dir.path() / "cfg/tool.tbl");
  EXPECT_EQ(ini.resolve_path("/abs/x"), std::filesystem::path("/abs/x"));
}

TEST(IniFile, SpecialFilesAreRefusedNamingWhy) {
  cnc::testing::TempDir dir;
  EXPECT_EQ(error_of([&] { IniFile::load(dir.path()); }),
            dir.path().string() + ": cannot read INI file: is a directory, not a regular file");
  const auto ini = dir.write("m.ini", "[EMC]\nMACHINE = m\n#INCLUDE /dev/zero\n");
  EXPECT_EQ(error_of([&] { IniFile::load(ini); }),
            ini.string() + ":3: #INCLUDE: cannot read \"/dev/zero\": is a character device, not a regular file");
}
