// COMP_FILE tables: LinuxCNC's two file types read unchanged, lookups as
// LinuxCNC's (linear between entries, ends held), no size limit, and
// errors that name the file and the line.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "comp/comp_table.hpp"
#include "core/util/error.hpp"
#include "tests/support/testing.hpp"

using namespace cnc;
using namespace cnc::comp;

namespace {

std::string error_of(const std::string& text, CompFileType type = CompFileType::Trims) {
  try {
    parse_comp_table(text, type, "x.comp");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(CompTable, TypeZeroPositionsBecomeTrimsAsLinuxCncConvertsThem) {
  // The reference's example: type 0 "1.00 1.01 0.99" is type 1 "1.00 -0.01 0.01".
  const CompTable t0 = parse_comp_table("1.00 1.01 0.99\n", CompFileType::Positions, "a");
  const CompTable t1 = parse_comp_table("1.00 -0.01 0.01\n", CompFileType::Trims, "b");
  ASSERT_EQ(t0.size(), 1u);
  EXPECT_NEAR(t0.forward[0], -0.01, 1e-12);
  EXPECT_NEAR(t0.reverse[0], 0.01, 1e-12);
  EXPECT_NEAR(t0.forward[0], t1.forward[0], 1e-12);
  EXPECT_NEAR(t0.reverse[0], t1.reverse[0], 1e-12);
}

TEST(CompTable, LookupIsLinearBetweenEntriesAndHoldsTheEnds) {
  const CompTable t = parse_comp_table("0 0.000 0.010\n10 0.020 0.030\n20 -0.020 0.000\n", CompFileType::Trims, "t");
  EXPECT_DOUBLE_EQ(t.forward_at(-100), 0.0) << "held below the first entry";
  EXPECT_DOUBLE_EQ(t.reverse_at(-1), 0.010);
  EXPECT_DOUBLE_EQ(t.forward_at(5), 0.010);
  EXPECT_DOUBLE_EQ(t.reverse_at(15), 0.015);
  EXPECT_DOUBLE_EQ(t.forward_at(10), 0.020) << "exactly on an entry";
  EXPECT_DOUBLE_EQ(t.forward_at(20), -0.020);
  EXPECT_DOUBLE_EQ(t.forward_at(1e6), -0.020) << "held above the last entry";
  EXPECT_DOUBLE_EQ(t.at(5, 1), 0.010);
  EXPECT_DOUBLE_EQ(t.at(5, -1), 0.020);
  EXPECT_DOUBLE_EQ(t.at(5, 0), 0.015) << "no direction yet: the mean of both";
  EXPECT_DOUBLE_EQ(t.forward_at(std::nan("")), 0.0) << "NaN reads the first entry, never out of bounds";
}

TEST(CompTable, HasNoTwoHundredFiftySixEntryLimit) {
  std::string text;
  for (int i = 0; i < 20000; ++i) text += std::to_string(i * 0.015) + " " + std::to_string(1e-6 * i) + " -0.001\n";
  const CompTable t = parse_comp_table(text, CompFileType::Trims, "big");
  ASSERT_EQ(t.size(), 20000u);
  EXPECT_NEAR(t.forward_at(19999 * 0.015), 1e-6 * 19999, 1e-9);
  EXPECT_NEAR(t.forward_at(150.0075), 1e-6 * 10000.5, 1e-9);
}

TEST(CompTable, EntriesMayCarryACommentAndNotesFollowTheTable) {
  const std::string text =
      "0 0 0   ; start\r\n"
      "100 0.001 -0.001 # end\n"
      "\n"
      "# Measured with a laser; values in mm.\n"  // LinuxCNC stops reading at the blank line
      "; Operator: someone\n";
  const CompTable t = parse_comp_table(text, CompFileType::Trims, "notes");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_DOUBLE_EQ(t.reverse[1], -0.001);
}

// LinuxCNC 2.9's loader (usrmotLoadComp) stops at the first line that is
// not three numbers: a comment or blank line before the table would leave
// the joint without compensation there, and a comment inside it would cut
// it short. Such files are refused, so that a file accepted here gives the
// same table in LinuxCNC.
TEST(CompTable, ACommentOrBlankLineBeforeTheTableIsRefusedAsLinuxCncWouldReadNothing) {
  EXPECT_NE(error_of("# X axis, measured 2024\n0 0 0\n100 0.001 -0.001\n")
                .find("x.comp:1: the table must start on the first line: LinuxCNC stops reading a COMP_FILE at the "
                      "first line that is not three numbers, so this comment would leave the joint without "
                      "compensation there"),
            std::string::npos);
  EXPECT_NE(error_of("\n0 0 0\n").find("x.comp:1: the table must start on the first line"), std::string::npos);
  EXPECT_NE(error_of("0 0 0\n# half way\n100 0.001 -0.001\n")
                .find("x.comp:3: an entry after the end of the table: line 2 is a comment or blank"),
            std::string::npos);
}

TEST(CompTable, ABadLineAfterTheFirstEntryIsAnErrorNotAShorterTable) {
  // A typo in the last line, or a run of lines that are not entries, used
  // to end the table there without a word.
  EXPECT_NE(error_of("0 0 0\n10 0.001 0.002\n20 0.001 0,002\n")
                .find("x.comp:3: expected three numbers 'nominal forward-trim reverse-trim' (COMP_FILE_TYPE 1), "
                      "found '20 0.001 0,002'; a line that is not an entry ends the table"),
            std::string::npos);
  EXPECT_NE(error_of("0 0 0\n10 0.001 0.002\n20,0.001,0.002\n30,0.001,0.002\n").find("x.comp:3: expected three"),
            std::string::npos);
  EXPECT_NE(error_of("0 0 0\n\nOperator: someone\n").find("x.comp:3: expected three"), std::string::npos)
      << "notes after the table are comments";
}

TEST(CompTable, ErrorsNameTheFileAndTheLine) {
  EXPECT_EQ(error_of("0 0 0\n10 0 0\n10 0.001 0\n"),
            "x.comp:3: nominal 10 is not greater than the previous one (10, line 2): entries must be in ascending order");
  EXPECT_EQ(error_of("0 0 0\n10 0 0\n5 0 0\n").substr(0, 9), "x.comp:3:");
  EXPECT_NE(error_of("X 0 0 0\n").find("x.comp:1: expected three numbers 'nominal forward-trim reverse-trim'"),
            std::string::npos);
  EXPECT_NE(error_of("0 0 0 0\n").find("x.comp:1: expected three numbers"), std::string::npos) << "four numbers";
  EXPECT_NE(error_of("0 0 0\nend\n20 0 0\n").find("x.comp:2: expected three numbers"), std::string::npos);
  EXPECT_EQ(error_of(""),
            "x.comp: no entries (expected lines of three numbers 'nominal forward-trim reverse-trim' (COMP_FILE_TYPE 1))");
  EXPECT_NE(error_of("0 0 nan\n").find("x.comp:1:"), std::string::npos) << "NaN is not a number here";
  EXPECT_NE(error_of("0 0 0\n1 1e308 0\n").find("x.comp:2: correction"), std::string::npos);
  EXPECT_NE(error_of("1e308 -1e308 1e308\n", CompFileType::Positions).find("x.comp:1: correction"),
            std::string::npos)
      << "an infinite trim from a type 0 conversion";
  // A type 1 file read as type 0 gives trims as large as the positions.
  EXPECT_NE(error_of("0 0.001 -0.001\n100 0.002 0.000\n", CompFileType::Positions)
                .find("x.comp:2: correction 99.998 at nominal 100 is larger than 1 machine units; is COMP_FILE_TYPE right?"),
            std::string::npos);
}

TEST(CompTable, MissingFileSaysSo) {
  try {
    load_comp_file("/nonexistent/x.comp", CompFileType::Trims);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/x.comp");
    EXPECT_NE(std::string(e.what()).find("cannot read the compensation file"), std::string::npos) << e.what();
  }
}

TEST(CompTable, WrittenFilesReadBackInBothTypes) {
  CompTable t;
  for (int i = 0; i < 50; ++i) {
    t.nominal.push_back(-10 + i * 6.25);
    t.forward.push_back(1e-3 * std::sin(i * 0.3));
    t.reverse.push_back(1e-3 * std::cos(i * 0.3) - 0.004);
  }
  for (const CompFileType type : {CompFileType::Positions, CompFileType::Trims}) {
    const std::string text = format_comp_table(t, type, {"a note", "another"});
    const CompTable back = parse_comp_table(text, type, "rt");
    ASSERT_EQ(back.size(), t.size());
    for (std::size_t i = 0; i < t.size(); ++i) {
      EXPECT_NEAR(back.nominal[i], t.nominal[i], 1e-9);
      EXPECT_NEAR(back.forward[i], t.forward[i], 1e-9);
      EXPECT_NEAR(back.reverse[i], t.reverse[i], 1e-9);
    }
    EXPECT_NE(text.find("# a note\n# another\n"), std::string::npos);
    EXPECT_EQ(text.find('#'), text.rfind("# a note")) << "notes come after the table, where LinuxCNC no longer reads";
  }
  EXPECT_NEAR(t.max_abs_trim(), 0.005, 1e-3);
  EXPECT_GT(t.max_abs_slope(), 0);
}

// Found by fuzzing (tests/comp/fuzz/corpus/comp_table/large-nominal-cut-line):
// a 128-byte line buffer cut a large nominal's line short, and the file
// written did not read back.
TEST(CompTable, WrittenLinesAreNeverCutShort) {
  CompTable t;
  t.nominal = {0, 1e308};
  t.forward = {0.001, 0.001};
  t.reverse = {-0.5, -0.5};
  const CompTable back = parse_comp_table(format_comp_table(t, CompFileType::Trims), CompFileType::Trims, "big");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_DOUBLE_EQ(back.nominal[1], 1e308);
  EXPECT_DOUBLE_EQ(back.reverse[1], -0.5);
}

// Found by fuzzing (corpus/comp_table/nominals-closer-than-written): two
// nominals less than 1e-6 apart were both written 0.000000, and the file
// did not read back.
TEST(CompTable, NominalsCloserThanAMicrometreAreWrittenApart) {
  CompTable t;
  t.nominal = {0, 1.6e-319, 2.5e-7, 1};
  t.forward = t.reverse = {0, 0, 0, 0};
  const std::string text = format_comp_table(t, CompFileType::Trims);
  const CompTable back = parse_comp_table(text, CompFileType::Trims, "close");
  ASSERT_EQ(back.size(), 4u) << text;
  EXPECT_EQ(back.nominal[1], 1.6e-319);
  EXPECT_NE(text.find("\n1.000000 "), std::string::npos) << "the usual six decimals where they suffice: " << text;
  // -1e-7 is written -0.000000, which reads as equal to the 0 after it:
  // both get their digits.
  t.nominal = {-1e-7, 0, 1};
  t.forward = t.reverse = {0, 0, 0};
  const std::string around_zero = format_comp_table(t, CompFileType::Trims);
  const CompTable back2 = parse_comp_table(around_zero, CompFileType::Trims, "zero");
  ASSERT_EQ(back2.size(), 3u) << around_zero;
  EXPECT_EQ(back2.nominal[0], -1e-7);
  EXPECT_NE(around_zero.find("\n1.000000 "), std::string::npos) << around_zero;
}
