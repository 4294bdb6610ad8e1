// The start-up check of the INI against what the controller read: each
// test loads a file, "reads" it as components would (typed getters with
// read tracking on), then looks at what the check reports.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>

#include "core/daemon/ini_check.hpp"
#include "core/util/error.hpp"
#include "tests/support/testing.hpp"

using cnc::daemon::find_unread_keys;
using cnc::daemon::IniIssue;
using cnc::ini::IniFile;

namespace {

// What motion and the task read of a small mill: the [JOINT_n] and [TRAJ]
// keys, present or not.
void read_like_the_controller(const IniFile& ini, int joints) {
  ini.get_string("EMC", "MACHINE", "");
  ini.find_all("HAL", "HALFILE");
  ini.get_double("TRAJ", "MAX_LINEAR_VELOCITY", 0);
  for (int j = 0; j < joints; ++j) {
    const std::string s = "JOINT_" + std::to_string(j);
    for (const char* k : {"TYPE", "MIN_LIMIT", "MAX_LIMIT", "MAX_VELOCITY", "MAX_ACCELERATION", "HOME_OFFSET"}) {
      ini.find(s, k);
    }
    if (ini.get_string(s, "HOME_MODE", "MOTION") == "MOTION") ini.find(s, "HOME_SEARCH_VEL");
  }
  ini.get_double("SPINDLE_0", "INCREMENT", 100);
}

std::vector<std::string> texts(const std::vector<IniIssue>& issues) {
  std::vector<std::string> out;
  for (const IniIssue& i : issues) out.push_back(i.where_and_what());
  return out;
}

std::vector<IniIssue> check(const std::string& text, int joints = 2) {
  IniFile ini = IniFile::parse(text, "m.ini");
  ini.record_reads(true);
  read_like_the_controller(ini, joints);
  return find_unread_keys(ini);
}

const char* kHead = "[EMC]\nMACHINE = m\n[HAL]\nHALFILE = m.hal\n[TRAJ]\nMAX_LINEAR_VELOCITY = 100\n";

}  // namespace

TEST(IniCheck, AMisspeltKeyIsReportedWithFileLineAndTheNearestKey) {
  const auto issues = check(std::string(kHead) + "[JOINT_0]\nMAX_VELOCTY = 100\nmax_limit = 5\n");
  EXPECT_EQ(texts(issues), (std::vector<std::string>{
                               "m.ini:8: [JOINT_0]MAX_VELOCTY: unknown key, ignored; did you mean [JOINT_0]MAX_VELOCITY?",
                               "m.ini:9: [JOINT_0]max_limit: unknown key, ignored; did you mean [JOINT_0]MAX_LIMIT?",
                           }));
  EXPECT_EQ(issues[0].kind, IniIssue::Kind::Unknown);
  EXPECT_TRUE(issues[0].is_mistake());
}

TEST(IniCheck, AKeyInTheWrongSectionNamesTheSectionThatReadsIt) {
  const auto issues = check(std::string(kHead) + "[JOINT_0]\nMAX_VELOCITY = 1\nINCREMENT = 50\n");
  EXPECT_EQ(texts(issues),
            (std::vector<std::string>{
                "m.ini:9: [JOINT_0]INCREMENT: unknown key here, ignored; [SPINDLE_0]INCREMENT is where it is read"}));
}

TEST(IniCheck, AKeyNobodyReadsAnywhereSaysSo) {
  const auto issues = check(std::string(kHead) + "[JOINT_1]\nREVERSE = YES\n");
  EXPECT_EQ(texts(issues), (std::vector<std::string>{
                               "m.ini:8: [JOINT_1]REVERSE: unknown key, ignored (no part of this controller reads it)"}));
}

TEST(IniCheck, AKeyOtherSectionsOfItsFamilyUseIsReportedAsUnusedHere) {
  const auto issues = check(std::string(kHead) +
                            "[JOINT_0]\nHOME_SEARCH_VEL = 10\n[JOINT_1]\nHOME_MODE = DRIVE\nHOME_SEARCH_VEL = 10\n");
  ASSERT_EQ(issues.size(), 1u) << ::testing::PrintToString(texts(issues));
  EXPECT_EQ(issues[0].kind, IniIssue::Kind::Unused);
  EXPECT_EQ(issues[0].where_and_what(),
            "m.ini:11: [JOINT_1]HOME_SEARCH_VEL: not used in this configuration (read for other [JOINT_n] sections; "
            "see docs/configuration.md for when it applies)");
}

TEST(IniCheck, ARepeatedScalarKeyNamesTheOccurrenceThatIsUsed) {
  const auto issues = check(std::string(kHead) + "[JOINT_0]\nMAX_VELOCITY = 1\nMAX_VELOCITY = 2\n");
  EXPECT_EQ(texts(issues),
            (std::vector<std::string>{"m.ini:9: [JOINT_0]MAX_VELOCITY: repeated; only the first occurrence (m.ini:8) is used"}));
}

TEST(IniCheck, AControllerSectionNoComponentReadsIsReportedOnce) {
  const auto issues = check(std::string(kHead) + "[JOINT_2]\nMAX_VELOCITY = 1\nMIN_LIMIT = 0\n[CIA402_SIM]\nNODE = 1\n");
  EXPECT_EQ(texts(issues),
            (std::vector<std::string>{
                "m.ini:7: [JOINT_2]: no loaded component reads this section; none of its keys has an effect (is its "
                "component loaded, and JOINTS, NODE or DRIVE right?)",
                "m.ini:10: [CIA402_SIM]: no loaded component reads this section; none of its keys has an effect (is "
                "its component loaded, and JOINTS, NODE or DRIVE right?)"}));
  EXPECT_EQ(issues[0].kind, IniIssue::Kind::UnusedSection);
}

TEST(IniCheck, TheScreensSectionsAndKeysAreLeftToTheScreen) {
  const auto issues = check(std::string(kHead) +
                            "[HAL]\nPOSTGUI_HALFILE = p.hal\n[DISPLAY]\nWHATEVER = 1\n[FILTER]\nPROGRAM_EXTENSION = .ngc\n"
                            "[MDI_COMMAND_LIST]\nMDI_COMMAND = G0 X0\n",
                            0);
  EXPECT_TRUE(issues.empty()) << ::testing::PrintToString(texts(issues));
}

TEST(IniCheck, KeysReadOnlyWhenUsedAreNotReported) {
  const auto issues = check(std::string(kHead) + "[HAL]\nLOADUSR_PATH = bin\n", 0);
  EXPECT_TRUE(issues.empty()) << ::testing::PrintToString(texts(issues));
}

TEST(IniCheck, LinuxCncKeysIgnoredHereAreInformationNotMistakes) {
  const auto issues = check("[EMC]\nVERSION = 1.1\nMACHINE = m\n[TRAJ]\nARC_BLEND_ENABLE = 1\n[HALUI]\nMDI_COMMAND = G0\n", 0);
  EXPECT_EQ(texts(issues), (std::vector<std::string>{
                               "m.ini:2: [EMC]VERSION: a LinuxCNC key this controller does not use",
                               "m.ini:5: [TRAJ]ARC_BLEND_ENABLE: a LinuxCNC key this controller does not use",
                               "m.ini:7: [HALUI]MDI_COMMAND: a LinuxCNC key this controller does not use",
                           }));
  for (const IniIssue& i : issues) EXPECT_FALSE(i.is_mistake());
}

TEST(IniCheck, UsersOwnSectionsAreLeftAloneUnlessNamedLikeAReadSection) {
  const auto issues = check(std::string(kHead) + "[JOINT_0]\nTYPE = LINEAR\n[PROBE]\nX = 1\n[JIONT_0]\nTYPE = LINEAR\n");
  EXPECT_EQ(texts(issues), (std::vector<std::string>{
                               "m.ini:11: [JIONT_0]: no loaded component reads this section; did you mean [JOINT_0]?"}));
}

TEST(IniCheck, AControllerSectionInLowerCaseIsRefusedWithTheRightName) {
  const auto ini = IniFile::parse("[EMC]\nMACHINE = m\n\n[traj]\nMAX_LINEAR_VELOCITY = 10\n", "m.ini");
  try {
    cnc::daemon::check_section_names(ini);
    FAIL() << "accepted";
  } catch (const cnc::ConfigError& e) {
    EXPECT_STREQ(e.what(),
                 "m.ini:4: [traj]: section names are case-sensitive; this controller (as LinuxCNC) reads [TRAJ], so "
                 "every key in [traj] would be ignored. Write [TRAJ]");
  }
  EXPECT_THROW(cnc::daemon::check_section_names(IniFile::parse("[Joint_0]\nA = 1\n", "m.ini")), cnc::ConfigError);
  EXPECT_THROW(cnc::daemon::check_section_names(IniFile::parse("[display]\nA = 1\n", "m.ini")), cnc::ConfigError);
  EXPECT_NO_THROW(cnc::daemon::check_section_names(IniFile::parse("[probe]\nA = 1\n", "m.ini")))
      << "a section of the user's own";
}

TEST(IniCheck, SectionFamiliesDropNumbersAndTheAxisLetter) {
  using cnc::daemon::section_family;
  EXPECT_EQ(section_family("JOINT_12"), "JOINT");
  EXPECT_EQ(section_family("AXIS_X"), "AXIS");
  EXPECT_EQ(section_family("CANOPEN_1_NODE_4"), "CANOPEN_NODE");
  EXPECT_EQ(section_family("CIA402_1_DRIVE_0"), "CIA402_DRIVE");
  EXPECT_EQ(section_family("CIA402_SIM_NODE_3"), "CIA402_SIM_NODE");
  EXPECT_EQ(section_family("RS274NGC"), "RS274NGC");
}

// The list compiled into the check and the page that documents it are one:
// docs/configuration.md, "Keys LinuxCNC reads that are ignored here" (the
// keys before a ';' in each row; those after it are read).
TEST(IniCheck, TheIgnoredKeysAreTheOnesTheConfigurationPageLists) {
  std::ifstream in(cnc::testing::source_dir() / "docs" / "configuration.md");
  std::string line;
  bool in_table = false;
  std::set<std::string> documented;
  const std::regex row(R"(^\| `\[([A-Za-z0-9_]+)\]` \| (.*) \|$)");
  const std::regex key("`([A-Z0-9_*]+)`");
  while (std::getline(in, line)) {
    if (line.rfind("## ", 0) == 0) in_table = line == "## Keys LinuxCNC reads that are ignored here";
    std::smatch m;
    if (!in_table || !std::regex_match(line, m, row)) continue;
    std::string family = m[1];
    if (family == "DISPLAY") continue;  // the screen's section
    if (family == "AXIS_L") family = "AXIS";
    if (family.size() > 2 && family.substr(family.size() - 2) == "_n") family.resize(family.size() - 2);
    std::string cell = m[2];
    cell = cell.substr(0, cell.find(';'));
    if (cell.find("the whole section") != std::string::npos) {
      documented.insert(family + ".*");
      continue;
    }
    for (std::sregex_iterator it(cell.begin(), cell.end(), key), end; it != end; ++it) {
      documented.insert(family + "." + (*it)[1].str());
    }
  }
  std::set<std::string> compiled;
  for (const auto& k : cnc::daemon::ignored_linuxcnc_keys()) compiled.insert(std::string(k.family) + "." + k.key);
  EXPECT_FALSE(documented.empty());
  EXPECT_EQ(documented, compiled);
}
